import subprocess

import numpy as np
import pytest

import servo_drive as sd


def sine(x0=0.25, amp=0.005, f=2.0, dur=1.0, dt=1e-3):
    t = np.arange(0, dur, dt)
    w = 2 * np.pi * f
    # Starts at rest at x0: a 1 - cos profile.
    return t, x0 + amp * (1 - np.cos(w * t)), amp * w * np.sin(w * t)


def test_stream_tracks_and_ends_where_the_setpoints_end(running):
    t, x, v = sine()
    r = running.stream(t, x, v, paced=False)
    assert r.ok, r
    assert r.sent == len(t) and r.telemetry_records > 100
    assert r.tracking_rms_um < 5 and r.tracking_max_um < 50
    # Motion happened: the following error is not the zero of a drive that stood still.
    assert r.tracking_max_um > 0.01
    running._wait(lambda s: abs(s.speed_rad_s) < 1, 10, "settle")
    assert running.status().position_m == pytest.approx(x[-1], abs=20e-6)


def test_refusals_are_reported_by_row(running):
    # The first point is 5 mm from the rod: a jump the drive refuses, row by row,
    # until the setpoints come within reach... they never do here. Sent without
    # the check, which would refuse it first (below).
    t, x, v = sine(x0=0.255, dur=0.05)
    r = running.stream(t, x, v, paced=False, check=False)
    assert r.refusals and r.refusals[0][0] == 0
    assert all(isinstance(row, int) for row, _ in r.refusals)
    assert "jump" in r.refusals[0][1]


def test_a_start_away_from_the_rod_or_moving_is_refused_before_sending(running):
    # The drive starts a stream from rest where its reference is: a first point
    # 1 mm away, or already at 0.079 m/s, would lurch; nothing is sent.
    t, x, v = sine(x0=0.251, dur=0.05)
    with pytest.raises(sd.StreamRejected) as e:
        running.stream(t, x, v, paced=False)
    assert e.value.row == 0 and e.value.field == "position_m" and "move" in str(e.value)
    t, x, v = sine(dur=0.05)
    v = v + 0.079
    x = x + 0.079 * t
    with pytest.raises(sd.StreamRejected) as e:
        running.stream(t, x, v, paced=False)
    assert (0, "velocity_m_s") in [(r, f) for r, f, _ in e.value.problems], e.value.problems
    assert running.status().position_m == pytest.approx(0.25, abs=20e-6)


def test_nan_names_array_and_row(running):
    t, x, v = sine()
    x[17] = np.nan
    with pytest.raises(sd.InputError) as e:
        running.stream(t, x, v)
    assert e.value.field == "position_m" and e.value.row == 17


def test_wrong_length_and_dtype(running):
    t, x, v = sine()
    with pytest.raises(sd.InputError) as e:
        running.stream(t, x[:-1], v)
    assert e.value.field == "position_m"
    with pytest.raises(sd.InputError) as e:
        running.stream(t, x, v.astype(np.complex128))
    assert e.value.field == "velocity_m_s" and "complex" in str(e.value)
    with pytest.raises(sd.InputError):
        running.stream(t, x.astype(str), v)
    with pytest.raises(sd.InputError):
        running.stream(t, np.vstack([x, x]), v)


def test_rows_beyond_limits_are_rejected_before_sending(running):
    t, x, v = sine()
    stroke_max = running.get("limits.stroke_max_m")
    x = x.copy()
    x[300] = stroke_max + 0.01
    with pytest.raises(sd.StreamRejected) as e:
        running.stream(t, x, v)
    rows = {row for row, field, _ in e.value.problems if field == "position_m"}
    assert 300 in rows and e.value.row in rows
    assert running.status().position_m == pytest.approx(0.25, abs=1e-4)  # nothing was sent


def test_dropped_connection_mid_stream(sim):
    d = sim.connect()
    d.enable()
    t, x, v = sine(dur=10.0)
    # Kill the simulated drive 0.5 s into a paced 10 s stream.
    subprocess.Popen(["sh", "-c", f"sleep 0.5; kill -9 {sim._proc.pid}"])
    with pytest.raises(sd.ConnectionLost):
        d.stream(t, x, v, paced=True, check=False)
