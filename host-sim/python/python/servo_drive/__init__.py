"""servo_drive: the servo cylinder drive from Python.

Connect to a board (serial) or the simulated drive (TCP), read ``info()`` and
``status()``, get and set parameters by dotted path, run commands, stream setpoints
from numpy arrays, capture into numpy, run step and chirp tests, iterate telemetry.
The protocol code is the Rust host tool's, built into this package from the same
definition the firmware uses; the schema hashes are checked at connect.

    import numpy as np, servo_drive as sd
    with sd.SimulatedDrive() as sim, sim.connect() as drive:
        drive.enable()
        t = np.arange(0, 1, 1e-3); x = 0.25 + 0.01 * np.sin(2 * np.pi * t)
        v = 0.01 * 2 * np.pi * np.cos(2 * np.pi * t)
        print(drive.stream(t, x, v, paced=False).tracking_rms_um)
"""

from .errors import (CommandRefused, ConnectError, ConnectionLost, DriveError, DriveTimeout, InputError,
                     ObserverRejected, ParameterRejected, Refused, SchemaMismatch, SimulatorError, StreamRejected, UnknownParameter)
from .types import Capture, Frf, Info, Mode, Parameter, Status, StreamReport, TestResult
from .drive import (CAPTURE_SIGNALS, PARAM_PATHS, PARAMS_SCHEMA_HASH, SCHEMA_HASH, TELEMETRY_FIELDS, Drive, Telemetry,
                    connect, paper_reference, unit_of)
from .sim import SimulatedDrive, find_host_sim

__version__ = "0.1.0"

__all__ = [
    "CAPTURE_SIGNALS", "PARAM_PATHS", "PARAMS_SCHEMA_HASH", "SCHEMA_HASH", "TELEMETRY_FIELDS",
    "Capture", "CommandRefused", "ConnectError", "ConnectionLost", "Drive", "DriveError", "DriveTimeout", "Frf",
    "Info", "InputError", "Mode", "ObserverRejected", "Parameter", "ParameterRejected", "Refused", "SchemaMismatch", "SimulatedDrive",
    "SimulatorError", "Status", "StreamRejected", "StreamReport", "Telemetry", "TestResult", "UnknownParameter",
    "connect", "find_host_sim", "paper_reference", "unit_of",
]
