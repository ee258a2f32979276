"""The README's ten-line example: a simulated drive, a 2 Hz sine streamed from numpy."""
import numpy as np
import servo_drive as sd

with sd.SimulatedDrive() as sim, sim.connect() as drive:
    print(drive.status().mode, drive.get("speed_pi.kp"))
    drive.enable()
    t = np.arange(0, 1, 1e-3)                                  # 1 kHz, 1 s
    x = 0.25 + 0.005 * (1 - np.cos(2 * np.pi * 2 * t))          # m, from where the rod is
    v = 0.005 * 2 * np.pi * 2 * np.sin(2 * np.pi * 2 * t)       # m/s
    print(drive.stream(t, x, v, paced=False))
