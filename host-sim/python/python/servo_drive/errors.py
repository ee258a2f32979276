"""The package's exception types.

Every error the package raises is a :class:`DriveError`. Each carries the
drive's ``reason`` code where the drive gave one, the ``field`` (parameter
path, array name, argument) and the ``row`` (0-based index into the arrays
you passed) where one is at fault.
"""

from __future__ import annotations

import difflib
import json
from typing import Any, List, Optional, Sequence, Tuple


class DriveError(Exception):
    """Base of every error of this package."""

    def __init__(self, message: str, *, reason: Optional[str] = None, field: Optional[str] = None,
                 row: Optional[int] = None) -> None:
        super().__init__(message)
        self.message = message
        #: The drive's reason code (e.g. ``"MustBePositive"``, ``"NotRunning"``), if it gave one.
        self.reason = reason
        #: The parameter path, array or argument at fault.
        self.field = field
        #: The 0-based row of the arrays at fault.
        self.row = row


class ConnectError(DriveError):
    """The drive could not be reached, or did not answer ``Info`` properly."""


class SchemaMismatch(ConnectError):
    """The drive speaks another protocol or parameter schema than this package."""

    def __init__(self, message: str, *, drive_hash: str, package_hash: str, **kw: Any) -> None:
        super().__init__(message, **kw)
        #: The drive's schema hash (hex).
        self.drive_hash = drive_hash
        #: This package's schema hash (hex).
        self.package_hash = package_hash


class ConnectionLost(DriveError):
    """The link dropped (the drive closed it, the cable went) or is closed."""


class DriveTimeout(DriveError):
    """The drive did not answer within the client's timeout."""


class Refused(DriveError):
    """The drive refused a request; ``reason`` is its code. Nothing of it was applied."""


class CommandRefused(Refused):
    """The drive refused a command (not running, faults latched, not homed...)."""


class ParameterRejected(Refused, ValueError):
    """A parameter value the drive (or its type) does not take: out of range, wrong type,
    or changeable only with the bridge off. ``field`` is the parameter's path."""


class ObserverRejected(Refused, ValueError):
    """Observer weights the drive (or this side, reading the file) refused: wrong shape,
    NaN or infinite words, another structure hash, a normalisation that does not match,
    a prediction beyond the shift bound. The message names the part; the running
    weights are unchanged."""


class UnknownParameter(DriveError, KeyError):
    """No parameter at this path; ``suggestions`` are the closest paths."""

    def __init__(self, message: str, *, suggestions: Sequence[str] = (), **kw: Any) -> None:
        if suggestions:
            message = f"{message}; did you mean {', '.join(suggestions)}?"
        super().__init__(message, **kw)
        #: The closest existing paths.
        self.suggestions = list(suggestions)

    def __str__(self) -> str:  # KeyError would quote the message
        return self.message


class InputError(DriveError, ValueError):
    """Bad input on this side, before anything was sent: NaN, wrong length or dtype,
    unknown names. ``field`` names the array or argument, ``row`` the row."""


class StreamRejected(InputError):
    """Rows the drive would not take (stroke, speed, force, rate, velocity against the
    position steps); nothing was sent. ``problems`` lists (row, field, message)."""

    def __init__(self, message: str, *, problems: Sequence[Tuple[int, str, str]] = (), **kw: Any) -> None:
        super().__init__(message, **kw)
        self.problems: List[Tuple[int, str, str]] = list(problems)


class SimulatorError(DriveError):
    """The simulated drive could not be started (binary not found, exited early)."""


_KINDS = {
    "DriveError": DriveError,
    "ConnectError": ConnectError,
    "ConnectionLost": ConnectionLost,
    "DriveTimeout": DriveTimeout,
    "Refused": Refused,
    "CommandRefused": CommandRefused,
    "ParameterRejected": ParameterRejected,
    "ObserverRejected": ObserverRejected,
    "UnknownParameter": UnknownParameter,
    "ValueError": InputError,
}


def closest_paths(path: str, paths: Sequence[str], n: int = 3) -> List[str]:
    """The ``n`` parameter paths closest to ``path`` (with or without ``control.``)."""
    full = path if path.startswith("control.") else f"control.{path}"
    near = difflib.get_close_matches(full, paths, n=n, cutoff=0.5)
    if not near:
        leaf = full.rsplit(".", 1)[-1]
        near = [p for p in paths if p.rsplit(".", 1)[-1] == leaf][:n]
    return near


def from_native(e: BaseException, paths: Sequence[str] = ()) -> DriveError:
    """The package exception for a ``_native.NativeError`` (its argument is JSON)."""
    try:
        d = json.loads(str(e.args[0]))
    except (ValueError, IndexError, TypeError):
        return DriveError(str(e))
    kind = d.get("kind", "DriveError")
    kw = dict(reason=d.get("reason"), field=d.get("field"), row=d.get("row"))
    msg = d.get("message", "")
    if kind == "SchemaMismatch":
        return SchemaMismatch(msg, drive_hash=d.get("drive_hash", ""), package_hash=d.get("package_hash", ""), **kw)
    if kind == "UnknownParameter":
        return UnknownParameter(msg, suggestions=closest_paths(kw["field"] or "", paths), **kw)
    return _KINDS.get(kind, DriveError)(msg, **kw)
