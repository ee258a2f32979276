"""Starting the simulated drive (``host-sim drive serve``) from Python.

The ``host-sim`` binary is looked for, in order:

1. the ``host_sim`` argument of :class:`SimulatedDrive`;
2. the ``SERVO_DRIVE_HOST_SIM`` environment variable (a path to the binary);
3. the target folder this package was built in (``host-sim/target/<triple>/release/host-sim``
   or ``host-sim/target/release/host-sim`` of the clone it was installed from:
   ``cd host-sim && cargo build --release`` puts it there);
4. ``host-sim`` on ``PATH``.
"""

from __future__ import annotations

import collections
import os
import shutil
import subprocess
import threading
import time
from pathlib import Path
from typing import Deque, List, Optional, Union

from . import _native
from .errors import SimulatorError

ENV_VAR = "SERVO_DRIVE_HOST_SIM"


def find_host_sim(path: Union[str, os.PathLike, None] = None) -> Path:
    """The ``host-sim`` binary (see the module's docstring for the order); raises
    :class:`SimulatorError` naming every place looked at."""
    looked: List[str] = []
    if path is not None:
        p = Path(path)
        if p.is_file() and os.access(p, os.X_OK):
            return p
        raise SimulatorError(f"host-sim binary {p} does not exist or is not executable", field="host_sim")
    env = os.environ.get(ENV_VAR)
    if env:
        p = Path(env)
        if p.is_file() and os.access(p, os.X_OK):
            return p
        raise SimulatorError(f"{ENV_VAR}={env}: no executable there", field=ENV_VAR)
    target = Path(_native.HOST_SIM_TARGET_DIR)
    candidates = sorted(target.glob("*/release/host-sim")) + [target / "release" / "host-sim"]
    found = [c for c in candidates if c.is_file() and os.access(c, os.X_OK)]
    if found:
        return max(found, key=lambda c: c.stat().st_mtime)
    looked += [str(c) for c in candidates]
    which = shutil.which("host-sim")
    if which:
        return Path(which)
    looked.append("host-sim on PATH")
    raise SimulatorError(
        "no host-sim binary found (looked at: " + ", ".join(looked) + "); build it with "
        "`cd host-sim && cargo build --release`, or name it with "
        f"SimulatedDrive(host_sim=...) or the {ENV_VAR} environment variable",
        field="host_sim",
    )


class SimulatedDrive:
    """A simulated drive served by ``host-sim drive serve`` on a free local port, for as
    long as the ``with`` block (or until :meth:`stop`).

    >>> with SimulatedDrive() as sim:
    ...     drive = sim.connect()
    ...     drive.status().mode
    <Mode.RUNNING: 'Running'>

    ``pace``: ``"fast"`` (simulated time advances per stream frame and as fast as the
    machine can otherwise) or ``"realtime"``. ``commissioned``: start calibrated,
    commutated and homed (else ``startup()`` first, like a fresh board). ``params``:
    a rig file; ``store``: the parameter store file (the board's flash);
    ``extra_args``: more ``drive serve`` options.
    """

    def __init__(self, *, pace: str = "fast", commissioned: bool = True,
                 initial_position_m: Optional[float] = None, params: Union[str, os.PathLike, None] = None,
                 store: Union[str, os.PathLike, None] = None, host_sim: Union[str, os.PathLike, None] = None,
                 extra_args: Optional[List[str]] = None, start_timeout_s: float = 30.0) -> None:
        self.binary = find_host_sim(host_sim)
        args = [str(self.binary), "drive", "serve", "--listen", "127.0.0.1:0", "--pace", pace]
        if commissioned:
            args.append("--commissioned")
        if initial_position_m is not None:
            args += ["--initial-position-m", repr(float(initial_position_m))]
        if params is not None:
            args += ["--params", str(params)]
        if store is not None:
            args += ["--store", str(store)]
        args += list(extra_args or [])
        self.args = args
        self.start_timeout_s = start_timeout_s
        self.address: Optional[str] = None
        self.log: Deque[str] = collections.deque(maxlen=500)
        self._proc: Optional[subprocess.Popen] = None
        self._ready = threading.Event()

    def start(self) -> "SimulatedDrive":
        """Starts the server and waits until it listens; ``address`` is then ``host:port``."""
        self._proc = subprocess.Popen(self.args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.PIPE, text=True, errors="replace")
        threading.Thread(target=self._read_log, daemon=True).start()
        t0 = time.monotonic()
        while not self._ready.wait(0.05):
            if self._proc.poll() is not None or time.monotonic() - t0 > self.start_timeout_s:
                self.stop()
                raise SimulatorError(
                    f"`{' '.join(self.args)}` did not start serving (exit code {self._proc.returncode}):\n"
                    + "\n".join(self.log))
        return self

    def _read_log(self) -> None:
        assert self._proc is not None and self._proc.stderr is not None
        for line in self._proc.stderr:
            line = line.rstrip("\n")
            self.log.append(line)
            if self.address is None and line.startswith("drive: serving on "):
                self.address = line[len("drive: serving on "):].split()[0]
                self._ready.set()

    def connect(self, timeout_s: float = 5.0) -> "Drive":
        """A :class:`~servo_drive.Drive` connected to this simulated drive."""
        from .drive import Drive
        if self.address is None:
            raise SimulatorError("the simulated drive is not running: start() first")
        return Drive.tcp(self.address, timeout_s=timeout_s)

    def stop(self) -> None:
        """Stops the server (SIGTERM, then SIGKILL after 5 s)."""
        p = self._proc
        if p is not None and p.poll() is None:
            p.terminate()
            try:
                p.wait(5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        self.address = None

    @property
    def running(self) -> bool:
        """The server process is alive."""
        return self._proc is not None and self._proc.poll() is None

    def __enter__(self) -> "SimulatedDrive":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def __del__(self) -> None:
        try:
            self.stop()
        except Exception:
            pass



