"""Benchmark of the Python package against the simulated drive; writes summary.json.

- the paper run's motor-side reference streamed at 1 kHz from Python (fast pacing:
  one simulated millisecond per point), its tracking figures from the drive's
  telemetry (as `host-sim drive bench-stream` does), and the rate the points left
  Python at (setpoints per second of wall time);
- a 4 x 1024 capture uploaded into numpy (wall time, median of 5);
- the package's build + install time, when given (`host-sim/python/ci.sh` measures it).

    python examples/bench_python.py --out out/python-bench

Exits non-zero only if the tracking figures miss their bounds (RMS <= 5 um,
max <= 50 um); times are reported, not asserted.
"""
import argparse
import json
import os
import statistics
import time

import servo_drive as sd

ap = argparse.ArgumentParser(description=__doc__)
ap.add_argument("--out", default="out/python-bench")
ap.add_argument("--build-install-s", type=float, default=None)
a = ap.parse_args()
os.makedirs(a.out, exist_ok=True)

t, x, v = sd.paper_reference()
summary = {}
with sd.SimulatedDrive(initial_position_m=float(x[0])) as sim, sim.connect(timeout_s=10) as drive:
    drive.enable()
    r = drive.stream(t, x, v, paced=False)
    summary["paper_stream_1khz"] = {
        "rows": r.rows, "sent": r.sent, "refused": len(r.refusals), "faults": r.faults,
        "duration_s": r.duration_s, "wall_s": r.wall_s,
        "tracking_rms_um": r.tracking_rms_um, "tracking_max_um": r.tracking_max_um,
        "telemetry_records": r.telemetry_records,
        "bound_rms_um": 5.0, "bound_max_um": 50.0,
    }
    summary["stream_throughput_setpoints_per_s"] = r.setpoints_per_s
    summary["stream_throughput_target"] = 10000
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        c = drive.capture(["motor_position", "speed", "current_q", "current_d"], 1024)
        times.append(time.perf_counter() - t0)
        assert c.values.shape == (4, 1024)
    summary["capture_4x1024_s"] = {"median": statistics.median(times), "max": max(times), "runs": len(times), "target": 0.1}
if a.build_install_s is not None:
    summary["package_build_install_s"] = a.build_install_s

path = os.path.join(a.out, "summary.json")
with open(path, "w") as f:
    json.dump(summary, f, indent=2)
print(json.dumps(summary, indent=2))
print(path)
p = summary["paper_stream_1khz"]
ok = (r.ok and p["tracking_rms_um"] is not None and p["tracking_rms_um"] <= 5.0 and p["tracking_max_um"] <= 50.0)
raise SystemExit(0 if ok else 1)
