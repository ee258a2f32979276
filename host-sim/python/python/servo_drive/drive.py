"""A connected drive: the board over its ST-LINK virtual COM port, or the simulated drive
over TCP. The protocol is the Rust host tool's (``host_sim::tool``), compiled into this
package from the same definition the firmware is built from."""

from __future__ import annotations

import json
import math
import os
import re
import time
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, TypeVar, Union

import numpy as np

from . import _native
from .errors import DriveError, InputError, StreamRejected, UnknownParameter, closest_paths, from_native
from .types import Capture, Info, Parameter, Status, StreamReport, TestResult

T = TypeVar("T")

#: Every parameter path with its type, from this package's copy of the tree (the
#: connect checked it is the drive's).
_PATHS: List[Dict[str, str]] = json.loads(_native.param_paths())
PARAM_PATHS: List[str] = [p["path"] for p in _PATHS]
_KIND = {p["path"]: p["kind"] for p in _PATHS}
_DEFAULTS = {d["path"]: d for d in json.loads(_native.defaults())}
CAPTURE_SIGNALS, TELEMETRY_FIELDS = (list(x) for x in _native.signal_names())
#: This package's (protocol, parameter) schema hashes, hex.
SCHEMA_HASH, PARAMS_SCHEMA_HASH = _native.schema_hashes()

# Units from the SI suffix every core name carries, longest first.
_UNITS = [
    ("_n_m_s_rad", "N·m·s/rad"), ("_kg_m2", "kg·m²"), ("_rad_s2", "rad/s²"), ("_rad_s", "rad/s"),
    ("_m_s2", "m/s²"), ("_m_s3", "m/s³"), ("_m_s", "m/s"), ("_n_m", "N·m"), ("_ohm", "Ω"), ("_wb", "Wb"),
    ("_hz", "Hz"), ("_rad", "rad"), ("_kg", "kg"), ("_m", "m"), ("_s", "s"), ("_a", "A"), ("_v", "V"),
    ("_n", "N"), ("_h", "H"), ("_c", "°C"), ("_w", "W"), ("_pct", "%"),
]


def unit_of(path: str) -> Optional[str]:
    """The SI unit a parameter's name states (``control.speed_pi.kp``: None)."""
    leaf = path.rsplit(".", 1)[-1]
    for suffix, unit in _UNITS:
        if leaf.endswith(suffix):
            return unit
    return None


def full_path(path: str) -> str:
    """``path`` with the ``control.`` prefix the drive's paths carry."""
    return path if path.startswith("control.") else f"control.{path}"


def _check_path(path: str) -> str:
    full = full_path(path)
    if full not in _KIND:
        raise UnknownParameter(f"no parameter `{full}`", field=full, suggestions=closest_paths(full, PARAM_PATHS))
    return full


def _call(f: Callable[..., T], *args: Any, **kw: Any) -> T:
    try:
        return f(*args, **kw)
    except _native.NativeError as e:
        raise from_native(e, PARAM_PATHS) from None


def _column(name: str, a: Any, n: Optional[int]) -> np.ndarray:
    """``a`` as a 1-D float64 column, refusing what would be silently changed."""
    if isinstance(a, np.ndarray):
        if a.dtype.kind not in "fiu":
            raise InputError(f"`{name}` has dtype {a.dtype}; a real number array (float64, float32 or integer) is needed",
                             field=name)
        if a.ndim != 1:
            raise InputError(f"`{name}` has shape {a.shape}; a 1-D array is needed", field=name)
    else:
        try:
            a = np.asarray(a, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise InputError(f"`{name}` is not a sequence of numbers: {e}", field=name) from None
        if a.ndim != 1:
            raise InputError(f"`{name}` has shape {a.shape}; a 1-D sequence is needed", field=name)
    a = np.ascontiguousarray(a, dtype=np.float64)
    if n is not None and a.shape[0] != n:
        raise InputError(f"`{name}` has {a.shape[0]} rows, `t` has {n}", field=name, row=min(n, a.shape[0]))
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise InputError(f"`{name}` row {int(bad[0])} is {a[bad[0]]} ({bad.size} non-finite rows); every value must be finite",
                         field=name, row=int(bad[0]))
    return a


class Telemetry:
    """An iterator of telemetry records ``(time_s, {field: value})`` from the drive, at the
    rate asked; ends after ``seconds`` (None: never) or :meth:`close`. A context manager
    that stops the drive's telemetry on exit."""

    def __init__(self, drive: "Drive", fields: Sequence[str], rate_hz: int, seconds: Optional[float]) -> None:
        self._drive = drive
        self._buf: List[Tuple[float, Dict[str, float]]] = []
        self._end = None if seconds is None else time.monotonic() + _seconds("seconds", seconds)
        self._open = True
        _call(drive._n.telemetry_start, list(fields), int(rate_hz))

    def __iter__(self) -> "Telemetry":
        return self

    def __next__(self) -> Tuple[float, Dict[str, float]]:
        while not self._buf:
            if not self._open or (self._end is not None and time.monotonic() >= self._end):
                self.close()
                raise StopIteration
            self._buf.extend((float(t), dict(v)) for t, v in _call(self._drive._n.telemetry_poll, 0.005))
        return self._buf.pop(0)

    def close(self) -> None:
        """Stops the drive's telemetry."""
        if self._open:
            self._open = False
            try:
                _call(self._drive._n.telemetry_start, [], 0)
            except DriveError:
                pass

    def __enter__(self) -> "Telemetry":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Drive:
    """A connected drive. Make one with :meth:`tcp` (simulated drive), :meth:`serial`
    (board) or :func:`servo_drive.connect`; the schema hashes are checked at connect
    (:class:`~servo_drive.SchemaMismatch` names both). Use it as a context manager or
    :meth:`close` it. Every refusal raises a :class:`~servo_drive.DriveError` subclass
    carrying the drive's reason and the field or row."""

    def __init__(self, native: Any) -> None:
        self._n = native
        self._info: Optional[Info] = None

    # ---- connection -----------------------------------------------------------------
    @classmethod
    def tcp(cls, address: str, timeout_s: float = 2.0) -> "Drive":
        """Connects to a drive at ``host:port`` (``host-sim drive serve --listen``)."""
        timeout_s = _seconds("timeout_s", timeout_s)
        return cls(_call(_native.NativeDrive, "tcp", address, 115_200, timeout_s))

    @classmethod
    def serial(cls, port: str, baud: int = 115_200, timeout_s: float = 2.0) -> "Drive":
        """Connects to a board on a serial port (e.g. ``/dev/ttyACM0``, the ST-LINK's
        virtual COM port)."""
        timeout_s = _seconds("timeout_s", timeout_s)
        return cls(_call(_native.NativeDrive, "serial", port, int(baud), timeout_s))

    def close(self) -> None:
        """Closes the link; the drive sees the client go (a stream decelerates and holds)."""
        self._n.close()

    def __enter__(self) -> "Drive":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def timeout_s(self) -> float:
        """How long a request waits for its reply (s)."""
        return _call(lambda: self._n.timeout_s)

    @timeout_s.setter
    def timeout_s(self, t: float) -> None:
        _call(setattr, self._n, "timeout_s", _seconds("timeout_s", t))

    # ---- who and how ----------------------------------------------------------------
    def info(self) -> Info:
        """Who the drive is: board, firmware, schema hashes, mode, faults, PWM rate,
        saved-record outcome, stream period."""
        self._info = Info.from_dict(json.loads(_call(self._n.info)))
        return self._info

    def status(self) -> Status:
        """Mode, faults by name, readiness, position, speed, currents, bus voltage,
        temperatures, and the next command to try."""
        return Status.from_dict(json.loads(_call(self._n.status)))

    # ---- parameters -----------------------------------------------------------------
    def get(self, path: str) -> Any:
        """A parameter's value by dotted path (``speed_pi.kp`` or ``control.speed_pi.kp``):
        float, int, bool, or an enum's name."""
        return json.loads(_call(self._n.param_get, _check_path(path)))

    def set(self, path: str, value: Any) -> Any:
        """Sets a parameter; returns the value as applied. The drive validates the whole set:
        a value out of range raises :class:`~servo_drive.ParameterRejected` with the field
        and the drive's reason; nothing is changed then."""
        full = _check_path(path)
        if isinstance(value, bool):
            text = "true" if value else "false"
        elif isinstance(value, (float, np.floating)):
            if not math.isfinite(value):
                raise InputError(f"`{full}`: {value} is not a finite number; nothing was sent", field=full)
            text = repr(float(value))
        else:
            text = str(value)
        return json.loads(_call(self._n.param_set, full, text))

    def parameters(self) -> List[Parameter]:
        """Every parameter with value, type, unit, default and lower bound (where the core
        bounds the leaf by itself)."""
        out = []
        for d in json.loads(_call(self._n.param_list)):
            p = d["path"]
            meta = _DEFAULTS.get(p, {})
            out.append(Parameter(path=p, value=d["value"], kind=_KIND.get(p, "?"), unit=unit_of(p),
                                 default=meta.get("value"), min=meta.get("min"),
                                 min_exclusive=bool(meta.get("min_exclusive")), max_abs=meta.get("max_abs")))
        return out

    def params_dict(self) -> Dict[str, Any]:
        """Every parameter as ``{path: value}``."""
        return {d["path"]: d["value"] for d in json.loads(_call(self._n.param_list))}

    def export_params(self, path: Union[str, os.PathLike]) -> int:
        """Writes every parameter to a TOML file (the rig file's ``[control]`` layout);
        returns how many."""
        return _call(self._n.param_export, os.fspath(path))

    def import_params(self, path: Union[str, os.PathLike]) -> List[str]:
        """Applies a TOML file's parameters, all or none (a refused one rolls the others
        back); returns the paths set."""
        return _call(self._n.param_import, os.fspath(path))

    def save(self) -> None:
        """Writes the present parameters to flash (the simulated drive's store file).
        Refused while the bridge is on."""
        _call(self._n.param_save)

    def load(self) -> Dict[str, Any]:
        """Applies the saved parameters; a bad record is refused and nothing changes."""
        return json.loads(_call(self._n.param_load))

    def defaults(self) -> None:
        """Applies the image's default parameters (flash untouched until :meth:`save`)."""
        _call(self._n.param_defaults)

    # ---- observer weights -----------------------------------------------------------
    def observer_status(self) -> Dict[str, Any]:
        """Which observer weights run: ``source`` ("compiled" or "uploaded"), shape,
        structure hash and the CRC of the running words."""
        return json.loads(_call(self._n.observer_status))

    def upload_observer(self, model_json: "os.PathLike[str] | str") -> Dict[str, Any]:
        """Uploads a trainer's ``model.json`` as the observer's weights: checked by the
        drive, stored in flash with the present parameters, run at once (bridge off),
        and verified by the CRC of the words the drive runs. A refused block raises
        ``ObserverRejected`` naming the part; the running weights are unchanged."""
        return json.loads(_call(self._n.upload_observer, os.fspath(model_json)))

    def use_compiled_observer(self) -> Dict[str, Any]:
        """Back to the observer weights compiled into the image."""
        return json.loads(_call(self._n.use_compiled_observer))

    # ---- commands -------------------------------------------------------------------
    def _command(self, name: str, arg: Optional[float] = None) -> Dict[str, Any]:
        if arg is not None:
            arg = float(arg)
            if not math.isfinite(arg):
                raise InputError(f"`{name}`: {arg} is not a finite number; nothing was sent", field=name)
        return json.loads(_call(self._n.command, name, arg))

    def startup(self, wait: bool = True, timeout_s: float = 60.0) -> None:
        """Every start-up step still missing (calibration, commutation, homing), in order;
        ``wait``: until the drive is homed and back to Disabled or Running."""
        self._command("startup")
        if wait:
            self._wait(lambda s: s.homed and s.mode.value in ("Disabled", "Running"), timeout_s, "start-up")

    def enable(self, wait: bool = True) -> None:
        """Bridge on, position control at the present position; ``wait``: until Running."""
        self._command("enable")
        if wait:
            _call(self._n.wait_running)

    def disable(self) -> None:
        """Controlled stop, then the bridge off (brake closed first if one is fitted)."""
        self._command("disable")

    def move(self, position_m: float, wait: bool = False, timeout_s: float = 30.0,
             tolerance_m: float = 20e-6) -> Dict[str, Any]:
        """Moves to ``position_m`` on the drive's jerk-limited profile. Returns
        ``{"outcome": "accepted" | "clamped_to_stroke", "position_m": ...}``; ``wait``:
        until within ``tolerance_m`` and still."""
        # Refused here rather than clamped by the drive: a target typed in
        # millimetres would otherwise send the rod to the end of the stroke.
        self._within_stroke("position_m", f"move({position_m!r})", float(position_m))
        r = self._command("move", position_m)
        if wait:
            target = r["position_m"] if r["position_m"] is not None else position_m
            self._wait(lambda s: abs(s.position_m - target) <= tolerance_m and abs(s.speed_rad_s) < 1.0,
                       timeout_s, f"the move to {target} m")
        return r

    def _within_stroke(self, field: str, what: str, target_m: float) -> None:
        if not math.isfinite(target_m):
            return  # the command's own check names it
        lo, hi = float(self.get("limits.stroke_min_m")), float(self.get("limits.stroke_max_m"))
        if not lo <= target_m <= hi:
            hint = ""
            if lo <= target_m / 1000 <= hi:
                hint = f" (millimetres? positions are in metres: {target_m / 1000} m)"
            raise InputError(f"{what}: the target {target_m} m is outside the stroke {lo} … {hi} m "
                             f"(control.limits.stroke_min_m, stroke_max_m){hint}; nothing was sent", field=field)

    def jog(self, distance_m: float) -> Dict[str, Any]:
        """Moves by ``distance_m`` from the present position."""
        return self._command("jog", distance_m)

    def set_home(self, position_m: float) -> None:
        """Declares the present position to be ``position_m`` (a rig with a known reference)."""
        self._command("set-home", position_m)

    def home(self) -> None:
        """Homing only (towards the end stop or switch)."""
        self._command("home")

    def stop(self) -> None:
        """A controlled stop of a move or stream; the drive then holds."""
        self._command("stop")

    def clear_faults(self) -> None:
        """Clears latched faults whose cause is gone (then :meth:`enable`)."""
        self._command("clear-faults")

    def set_compensation(self, enabled: bool) -> None:
        """The error observer's setpoint compensation on or off."""
        self._command("compensation-on" if enabled else "compensation-off")

    def _wait(self, done: Callable[[Status], bool], timeout_s: float, what: str) -> Status:
        t0 = time.monotonic()
        while True:
            s = self.status()
            if done(s):
                return s
            if s.faults:
                raise DriveError(f"{what}: faults latched: {', '.join(s.faults)}; {s.next}", reason="Faulted")
            if time.monotonic() - t0 > timeout_s:
                raise DriveError(f"{what} did not finish within {timeout_s} s (mode {s.mode.value})", reason="Timeout")
            time.sleep(0.01)

    # ---- streaming ------------------------------------------------------------------
    def check_stream(self, t: Any, position_m: Any, velocity_m_s: Any, force_n: Any = None) -> List[Tuple[int, str, str]]:
        """The rows the drive would not take, as (row, field, message), without sending
        anything; also raises :class:`~servo_drive.InputError` for NaN, wrong length or
        dtype."""
        cols = self._columns(t, position_m, velocity_m_s, force_n)
        problems = json.loads(_call(self._n.stream_check, *cols))
        return [(int(p["row"]), p["field"], p["message"]) for p in problems]

    @staticmethod
    def _columns(t: Any, position_m: Any, velocity_m_s: Any, force_n: Any) -> Tuple[list, list, list, Optional[list]]:
        tt = _column("t", t, None)
        if tt.shape[0] == 0:
            raise InputError("`t` is empty: nothing to stream", field="t")
        n = tt.shape[0]
        x = _column("position_m", position_m, n)
        v = _column("velocity_m_s", velocity_m_s, n)
        f = None if force_n is None else _column("force_n", force_n, n).tolist()
        return tt.tolist(), x.tolist(), v.tolist(), f

    def stream(self, t: Any, position_m: Any, velocity_m_s: Any, force_n: Any = None, *,
               paced: bool = True, track: bool = True, check: bool = True) -> StreamReport:
        """Streams setpoints from arrays: times (s), positions (m), velocities (m/s) and
        optional forces (N), all 1-D, finite and of one length. ``paced``: sent at the rows'
        times on the wall clock (a board, a real-time simulated drive); else back to back
        (a fast-paced simulated drive takes one stream period per point). Ends with
        ``stop``; the drive then holds.

        ``check`` first checks every row against the drive's limits and raises
        :class:`~servo_drive.StreamRejected` listing (row, field, message) without sending.
        Points the drive refuses while streaming are in the report's ``refusals`` by row;
        a dropped link raises :class:`~servo_drive.ConnectionLost`. ``track``: the
        following-error figures from telemetry (``tracking_rms_um``, ``tracking_max_um``)."""
        cols = self._columns(t, position_m, velocity_m_s, force_n)
        if check:
            problems = json.loads(_call(self._n.stream_check, *cols))
            if problems:
                lines = [f"row {p['row']}: {p['field']}: {p['message']}" for p in problems[:20]]
                more = f"\n... and {len(problems) - 20} more" if len(problems) > 20 else ""
                first = problems[0]
                raise StreamRejected("the drive would not take these rows; nothing was sent:\n" + "\n".join(lines) + more,
                                     problems=[(int(p["row"]), p["field"], p["message"]) for p in problems],
                                     field=first["field"], row=int(first["row"]))
        r = json.loads(_call(self._n.stream, *cols, paced=paced, track=track))
        r["refusals"] = [(row, why) for row, why in r["refusals"]]
        return StreamReport(**r)

    # ---- capture and tests ----------------------------------------------------------
    def capture(self, signals: Sequence[str], samples: int = 1024, *, decimation: int = 1,
                pre_trigger: int = 0, trigger: str = "command", wait_s: float = 10.0) -> Capture:
        """Records ``signals`` (names, :data:`CAPTURE_SIGNALS`) in the drive's PWM interrupt,
        every ``decimation``-th period, ``samples`` each, and uploads them into numpy.
        ``trigger``: ``"command"`` (now, after ``pre_trigger`` samples of history),
        ``"fault"`` or ``"test_start"``."""
        unknown = [s for s in signals if s not in CAPTURE_SIGNALS]
        if unknown:
            raise InputError(f"unknown capture signal {unknown[0]!r}; one of {', '.join(CAPTURE_SIGNALS)}", field=unknown[0])
        for name, v, lo in (("samples", samples, 1), ("decimation", decimation, 1), ("pre_trigger", pre_trigger, 0)):
            if not isinstance(v, (int, np.integer)) or not lo <= v <= 65535:
                raise InputError(f"`{name}` = {v!r}: an integer {lo} … 65535 is needed", field=name)
        names, dt, trig, values = _call(self._n.capture, list(signals), int(samples), int(decimation),
                                        int(pre_trigger), trigger, _seconds("wait_s", wait_s))
        return Capture(names=list(names), dt_s=dt, trigger_index=trig, values=np.array(values, dtype=np.float64))

    def _test(self, kind: str, target: str, amplitude: float, duration_s: float,
              chirp_hz: Optional[Tuple[float, float]], predict: bool, position_m: float) -> TestResult:
        for name, v in (("amplitude", amplitude), ("duration_s", duration_s)) + (
                (("start_hz", chirp_hz[0]), ("end_hz", chirp_hz[1])) if chirp_hz else ()):
            if not math.isfinite(float(v)):
                raise InputError(f"`{name}` = {v}: a finite number is needed", field=name)
        chirp = None if chirp_hz is None else (float(chirp_hz[0]), float(chirp_hz[1]))
        f = self._n.predict if predict else self._n.test
        args: Tuple[Any, ...] = (target, float(amplitude), float(duration_s), chirp)
        if predict:
            args += (float(position_m),)
        names, dt, trig, values = _call(f, *args)
        cap = Capture(names=list(names), dt_s=dt, trigger_index=trig, values=np.array(values, dtype=np.float64))
        return TestResult(kind=kind, target=target, capture=cap)

    def step(self, target: str, amplitude: float, duration_s: float = 0.2, *, predict: bool = False,
             position_m: float = 0.25) -> TestResult:
        """A step generated in the core (exact timing) on the ``current`` (A), ``speed``
        (rad/s) or ``position`` (m) loop, with the capture around it. The drive must be
        running. ``predict``: the same test on a fresh simulated drive with this drive's
        parameters (the model's answer) instead."""
        return self._test("step", target, amplitude, duration_s, None, predict, position_m)

    def chirp(self, target: str, amplitude: float, start_hz: float, end_hz: float, duration_s: float = 1.0, *,
              predict: bool = False, position_m: float = 0.25) -> TestResult:
        """A chirp from ``start_hz`` to ``end_hz`` on a loop, with the capture of reference
        and response; :meth:`TestResult.frf` gives the measured frequency response."""
        return self._test("chirp", target, amplitude, duration_s, (start_hz, end_hz), predict, position_m)

    # ---- telemetry ------------------------------------------------------------------
    def telemetry(self, fields: Sequence[str] = ("position_reference_m", "motor_position_m", "speed_rad_s"),
                  rate_hz: int = 100, seconds: Optional[float] = None) -> Telemetry:
        """An iterator of telemetry records ``(time_s, {field: value})`` at ``rate_hz``
        (fields: :data:`TELEMETRY_FIELDS`)."""
        unknown = [f for f in fields if f not in TELEMETRY_FIELDS]
        if unknown:
            raise InputError(f"unknown telemetry field {unknown[0]!r}; one of {', '.join(TELEMETRY_FIELDS)}", field=unknown[0])
        return Telemetry(self, fields, rate_hz, seconds)


def connect(address: str, *, baud: int = 115_200, timeout_s: float = 2.0) -> Drive:
    """A drive at ``address``: ``host:port`` (TCP, the simulated drive) or a serial port
    (``/dev/ttyACM0``, ``COM3``: the board)."""
    if re.fullmatch(r"[^/\\:]+:\d+", address):
        return Drive.tcp(address, timeout_s=timeout_s)
    return Drive.serial(address, baud=baud, timeout_s=timeout_s)


def paper_reference(rig: Union[str, os.PathLike, None] = None) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper cycle's motor-side reference at 1 kHz (what ``host-sim drive bench-stream``
    streams): (t_s, position_m, velocity_m_s)."""
    t, x, v = _call(_native.paper_reference, None if rig is None else os.fspath(rig))
    return np.array(t), np.array(x), np.array(v)


def _seconds(name: str, value: Any) -> float:
    """A time argument: finite, above zero, at most a day (s)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"`{name}` = {value!r}: a number of seconds is needed", field=name) from None
    if not (math.isfinite(v) and 0 < v <= 86_400):
        raise InputError(f"`{name}` = {value!r}: a time above 0 and at most a day (86400 s) is needed", field=name)
    return v
