"""Typed results: what the drive reports, as Python objects."""

from __future__ import annotations

import enum
import json
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from . import _native


class Mode(str, enum.Enum):
    """The drive's mode (``servo_core::Mode``)."""

    DISABLED = "Disabled"
    CALIBRATING = "Calibrating"
    ALIGNING = "Aligning"
    HOMING = "Homing"
    RUNNING = "Running"
    STOPPING = "Stopping"
    FAULT = "Fault"
    BRAKING = "Braking"

    @classmethod
    def parse(cls, name: str) -> "Mode | str":
        try:
            return cls(name)
        except ValueError:  # a mode newer than this package: kept by name
            return name


@dataclass(frozen=True)
class Info:
    """Who the drive is and which schema it speaks."""

    board: str
    firmware_version: str
    git_hash: str
    schema_hash: str
    params_schema_hash: str
    protocol_version: int
    mode: Mode
    faults: Tuple[str, ...]
    pwm_frequency_hz: float
    boot_record: str
    #: The stream period the drive expects (s); None: any interval up to
    #: ``control.stream.period_max_s``.
    stream_period_s: Optional[float]

    @classmethod
    def from_dict(cls, d: Dict[str, Any]) -> "Info":
        return cls(board=d["board"], firmware_version=d["firmware_version"], git_hash=d["git_hash"],
                   schema_hash=d["schema_hash"], params_schema_hash=d["params_schema_hash"],
                   protocol_version=int(d["protocol_version"]), mode=Mode.parse(d["mode"]),
                   faults=tuple(d["faults"]), pwm_frequency_hz=float(d["pwm_frequency_hz"]),
                   boot_record=d["boot_record"], stream_period_s=d["stream_period_s"])


@dataclass(frozen=True)
class Status:
    """Mode, faults by name, readiness, readouts and the next command to try."""

    mode: Mode
    #: Latched faults, by name (``servo_core::FaultSet``); empty: none.
    faults: Tuple[str, ...]
    #: Start-up steps done: ``calibrated``, ``commutated``, ``homed``.
    readiness: Tuple[str, ...]
    position_m: float
    speed_rad_s: float
    current_d_a: float
    current_q_a: float
    bus_voltage_v: float
    winding_thermal_level: Optional[float]
    power_stage_temperature_c: Optional[float]
    boot_record: str
    test_running: bool
    time_s: float
    #: The next command for a drive in this state, in words.
    next: str

    @property
    def homed(self) -> bool:
        return "homed" in self.readiness

    @property
    def running(self) -> bool:
        return self.mode == Mode.RUNNING

    @classmethod
    def from_dict(cls, d: Dict[str, Any]) -> "Status":
        return cls(mode=Mode.parse(d["mode"]), faults=tuple(d["faults"]), readiness=tuple(d["readiness"]),
                   position_m=d["position_m"], speed_rad_s=d["speed_rad_s"], current_d_a=d["current_d_a"],
                   current_q_a=d["current_q_a"], bus_voltage_v=d["bus_voltage_v"],
                   winding_thermal_level=d["winding_thermal_level"],
                   power_stage_temperature_c=d["power_stage_temperature_c"], boot_record=d["boot_record"],
                   test_running=d["test_running"], time_s=d["time_s"], next=d["next"])


@dataclass(frozen=True)
class Parameter:
    """One parameter: its dotted path, value, type, unit and lower bound where the core
    bounds it on its own (others are checked against each other by the drive)."""

    path: str
    value: Any
    kind: str
    unit: Optional[str]
    default: Any = None
    min: Optional[float] = None
    min_exclusive: bool = False
    #: The core's physical range: the largest size (absolute value) the leaf may have,
    #: from its unit and the default set's ratings; None where the core bounds it otherwise.
    max_abs: Optional[float] = None

    @property
    def range_text(self) -> str:
        parts = []
        if self.min is not None:
            parts.append(f"{'>' if self.min_exclusive else '>='} {self.min:g}")
        if self.max_abs is not None:
            parts.append(f"|x| <= {self.max_abs:g}")
        return ", ".join(parts)


@dataclass
class StreamReport:
    """What became of a stream."""

    rows: int
    sent: int
    duration_s: float
    wall_s: float
    #: (row, reason) for each point the drive refused or bounded (row: 0-based
    #: index into the arrays; None for the closing Stop).
    refusals: List[Tuple[Optional[int], str]]
    #: The drive stopped taking points (faulted, disabled); sending ended at this row.
    aborted_at_row: Optional[int]
    #: Following error (position reference − motor position) over the telemetry
    #: received while streaming, µm.
    tracking_rms_um: Optional[float]
    tracking_max_um: Optional[float]
    telemetry_records: int
    #: Faults latched at the end, by name.
    faults: List[str]
    #: The telemetry behind the tracking figures, shape (records, 3): drive time (s),
    #: position reference (m), motor position (m). Empty without ``track``.
    tracking_trace: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self) -> None:
        self.tracking_trace = np.asarray(self.tracking_trace, dtype=np.float64).reshape(-1, 3)

    def grouped_refusals(self) -> List[str]:
        """Refusals with consecutive rows of one reason merged: ``rows 4–80: ...``."""
        out: List[List[Any]] = []
        for row, why in self.refusals:
            if out and out[-1][2] == why and row is not None and out[-1][1] is not None and out[-1][1] + 1 == row:
                out[-1][1] = row
            else:
                out.append([row, row, why])
        return [f"row {a}: {w}" if a == b else f"rows {a}–{b}: {w}" for a, b, w in out]

    def __repr__(self) -> str:
        g = self.grouped_refusals()
        shown = "; ".join(g[:3]) + (f"; ... {len(g) - 3} more groups" if len(g) > 3 else "")
        fig = lambda x: "n/a" if x is None else f"{x:.2f}"
        return (f"StreamReport({self.sent}/{self.rows} sent in {self.wall_s:.3f} s wall for {self.duration_s:.3f} s, "
                f"{len(self.refusals)} refused [{shown}], aborted_at_row={self.aborted_at_row}, "
                f"tracking RMS {fig(self.tracking_rms_um)} µm, max {fig(self.tracking_max_um)} µm "
                f"({self.telemetry_records} records), faults={self.faults})")

    @property
    def setpoints_per_s(self) -> float:
        """Points sent per second of wall time."""
        return self.sent / self.wall_s if self.wall_s > 0 else float("nan")

    @property
    def ok(self) -> bool:
        """Every row sent, none refused, no fault."""
        return self.sent == self.rows and not self.refusals and not self.faults and self.aborted_at_row is None


@dataclass
class Capture:
    """An uploaded capture: ``values[i]`` is signal ``names[i]``; ``t`` is zero at the trigger."""

    names: List[str]
    dt_s: float
    trigger_index: int
    values: np.ndarray  # shape (signals, samples), float64
    t: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        n = self.values.shape[1] if self.values.ndim == 2 else 0
        self.t = (np.arange(n, dtype=np.float64) - self.trigger_index) * self.dt_s

    def __getitem__(self, name: str) -> np.ndarray:
        """The samples of signal ``name``."""
        try:
            return self.values[self.names.index(name)]
        except ValueError:
            raise KeyError(f"no signal {name!r} in this capture; it has {', '.join(self.names)}") from None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def to_pandas(self):  # pandas is optional
        """A ``pandas.DataFrame`` indexed by ``t_s`` (needs pandas)."""
        import pandas as pd
        return pd.DataFrame(dict(zip(self.names, self.values)), index=pd.Index(self.t, name="t_s"))


@dataclass
class TestResult:
    """A step or chirp test generated in the core: the capture around it and figures.

    ``reference`` and ``response`` are the loop's reference and measured signal.
    For a step: ``rise_time_s``, ``overshoot``, ``steady_state``; for a chirp: the
    measured closed-loop frequency response ``frf`` (H1 estimate).
    """

    kind: str
    target: str
    capture: Capture

    @property
    def reference(self) -> np.ndarray:
        return self.capture.values[0]

    @property
    def response(self) -> np.ndarray:
        return self.capture.values[1]

    def frf(self, nfft: int = 1024) -> "Frf":
        """The measured closed-loop frequency response, response / reference from the
        test's start (H1 estimate: Welch, Hann, 50 % overlap; ``nfft`` a power of two)."""
        k0 = self.capture.trigger_index
        return Frf(*map(np.asarray, _native.frf_h1(self.reference[k0:].tolist(), self.response[k0:].tolist(),
                                                 self.capture.dt_s, nfft)))

    def step_figures(self, amplitude: float = float("nan")) -> Dict[str, Optional[float]]:
        """Rise time (10–90 %, s), overshoot (% of the change), settling time (±2 %, s),
        initial and final value of the response."""
        c = self.capture
        return json.loads(_native.step_figures(self.response.tolist(), c.dt_s, c.trigger_index * c.dt_s, amplitude))


@dataclass
class Frf:
    """A frequency response: gain (dB) and phase (deg) per frequency, with coherence."""

    freq_hz: np.ndarray
    gain_db: np.ndarray
    phase_deg: np.ndarray
    coherence: np.ndarray
