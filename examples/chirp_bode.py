"""Tune the speed loop from a chirp: the measured closed-loop Bode (H1 from the capture)
against the model's (the same chirp on a fresh simulated drive with the drive's
parameters), for the present gains and for a raised speed-loop gain (PNG).

    python examples/chirp_bode.py --out out/python
"""
import argparse
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import servo_drive as sd  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__)
ap.add_argument("--out", default="out/python")
ap.add_argument("--amplitude-rad-s", type=float, default=10.0)
a = ap.parse_args()
os.makedirs(a.out, exist_ok=True)

with sd.SimulatedDrive() as sim, sim.connect() as drive:
    drive.enable()
    kp0 = drive.get("speed_pi.kp")
    fig, (ag, ap_) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for kp in (kp0, 1.5 * kp0):
        drive.set("speed_pi.kp", kp)
        meas = drive.chirp("speed", a.amplitude_rad_s, 5.0, 150.0, 2.0).frf()
        model = drive.chirp("speed", a.amplitude_rad_s, 5.0, 150.0, 2.0, predict=True).frf()
        # Inside the sweep, away from its ends.
        band = (meas.freq_hz >= 8) & (meas.freq_hz <= 120)
        dev = float(np.max(np.abs(meas.gain_db[band] - model.gain_db[band])))
        ag.semilogx(meas.freq_hz[band], meas.gain_db[band], label=f"measured, kp={kp:.3g}")
        ag.semilogx(model.freq_hz[band], model.gain_db[band], "--", label=f"model, kp={kp:.3g}")
        ap_.semilogx(meas.freq_hz[band], meas.phase_deg[band], label=f"measured, kp={kp:.3g}")
        ap_.semilogx(model.freq_hz[band], model.phase_deg[band], "--", label=f"model, kp={kp:.3g}")
        print(f"kp = {kp:.4g}: measured vs model gain, largest difference 8-120 Hz: {dev:.2f} dB")
    drive.set("speed_pi.kp", kp0)
    ag.set_ylabel("|speed / reference| [dB]")
    ag.legend(fontsize=8)
    ap_.set_ylabel("phase [deg]")
    ap_.set_xlabel("frequency [Hz]")
    ag.set_title("speed loop, closed-loop response from a chirp")
    path = os.path.join(a.out, "chirp_bode.png")
    fig.savefig(path, dpi=100)
    print(path)
