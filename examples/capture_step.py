"""Capture a position step generated in the drive's core and plot it (PNG).

    python examples/capture_step.py --out out/python
"""
import argparse
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import servo_drive as sd  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__)
ap.add_argument("--out", default="out/python")
ap.add_argument("--distance-m", type=float, default=0.002)
a = ap.parse_args()
os.makedirs(a.out, exist_ok=True)

with sd.SimulatedDrive() as sim, sim.connect() as drive:
    drive.enable()
    res = drive.step("position", a.distance_m, 0.3)
    model = drive.step("position", a.distance_m, 0.3, predict=True)
    c = res.capture
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    ax1.plot(c.t * 1e3, c["position_command"] * 1e3, label="position command")
    ax1.plot(c.t * 1e3, c["motor_position"] * 1e3, label="motor position (measured)")
    ax1.plot(model.capture.t * 1e3, model.capture["motor_position"] * 1e3, "--", label="model (fresh simulated drive)")
    ax1.set_ylabel("position [mm]")
    ax1.legend()
    ax2.plot(c.t * 1e3, c["speed"], label="speed")
    ax2.set_ylabel("speed [rad/s]")
    ax2.set_xlabel("time from the step [ms]")
    f = res.step_figures(a.distance_m)
    ax1.set_title(f"position step {a.distance_m * 1e3:g} mm: rise {f['rise_time_s'] * 1e3:.1f} ms, "
                  f"overshoot {f['overshoot_pct']:.1f} %")
    path = os.path.join(a.out, "capture_step.png")
    fig.savefig(path, dpi=100)
    print(f"{path}: {len(c)} samples every {c.dt_s * 1e3:g} ms; {f}")
