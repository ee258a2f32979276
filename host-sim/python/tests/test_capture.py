import math
import time

import numpy as np
import pytest

import servo_drive as sd


def test_capture_shape_and_rate(running):
    t0 = time.perf_counter()
    c = running.capture(["motor_position", "speed", "current_q", "current_d"], 1024, decimation=20)
    assert c.values.shape == (4, 1024) and c.values.dtype == np.float64
    assert c.dt_s == pytest.approx(20 / 20000) and len(c.t) == 1024
    assert np.all(np.isfinite(c.values))
    # Holding still at the start position.
    np.testing.assert_allclose(c["motor_position"], 0.25, atol=1e-4)


def test_position_step_capture_agrees_with_the_screw(running):
    """The rod's speed from the encoder's position is the motor speed through the screw."""
    lead = running.get("drive_train.screw_lead_m")
    res = running.step("position", 0.002, 0.3)
    c = res.capture
    assert c.names[:3] == ["position_command", "motor_position", "speed"]
    x, w = c["motor_position"], c["speed"]
    # Integrated through the screw, the motor speed gives the encoder's travel.
    rod_speed = w * lead / (2 * math.pi)
    travel = np.concatenate([[0.0], np.cumsum(0.5 * (rod_speed[1:] + rod_speed[:-1]) * c.dt_s)])
    assert np.ptp(x) > 0.0015
    # (trapezoid over 1 ms samples of a filtered speed: a few per cent)
    np.testing.assert_allclose(x - x[0], travel, atol=0.05 * np.ptp(x))
    assert travel[-1] == pytest.approx(x[-1] - x[0], rel=0.02)
    f = res.step_figures(0.002)
    assert f["final_value"] - f["initial"] == pytest.approx(0.002, rel=0.02)


def test_capture_bad_arguments(running):
    with pytest.raises(sd.InputError) as e:
        running.capture(["speeed"], 64)
    assert e.value.field == "speeed"
    with pytest.raises(sd.InputError):
        running.capture(["speed"], 0)


def test_pandas_optional(running):
    pd = pytest.importorskip("pandas")
    df = running.capture(["speed"], 64).to_pandas()
    assert list(df.columns) == ["speed"] and df.index.name == "t_s"


def test_speed_step_reaches_its_amplitude_and_matches_the_model(running):
    res = running.step("speed", 20.0, 0.1)
    f = res.step_figures(20.0)
    change = f["final_value"] - f["initial"]
    assert change == pytest.approx(20.0, rel=0.05)
    assert 0 < f["rise_time_s"] < 0.02
    model = running.step("speed", 20.0, 0.1, predict=True)
    g = model.step_figures(20.0)
    assert g["rise_time_s"] == pytest.approx(f["rise_time_s"], rel=0.3, abs=1e-3)


def test_chirp_frf_tracks_at_low_frequency_and_matches_the_model(running):
    res = running.chirp("speed", 10.0, 5.0, 200.0, 1.0)
    frf = res.frf()
    band = (frf.freq_hz >= 5) & (frf.freq_hz <= 20)
    assert band.any()
    # A speed loop follows its reference well below its bandwidth (PI peaking < 3 dB).
    assert np.all(np.abs(frf.gain_db[band]) < 3)
    model = running.chirp("speed", 10.0, 5.0, 200.0, 1.0, predict=True).frf()
    np.testing.assert_allclose(frf.gain_db[band], model.gain_db[band], atol=1.0)


def test_telemetry_iterator(running):
    with running.telemetry(["motor_position_m", "speed_rad_s"], rate_hz=200, seconds=0.3) as tm:
        recs = list(tm)
    assert len(recs) > 10
    times = [t for t, _ in recs]
    assert all(b > a for a, b in zip(times, times[1:]))
    assert set(recs[0][1]) == {"motor_position_m", "speed_rad_s"}
    assert recs[-1][1]["motor_position_m"] == pytest.approx(0.25, abs=1e-4)
    with pytest.raises(sd.InputError):
        running.telemetry(["nope"])
