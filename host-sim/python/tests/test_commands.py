import pytest

import servo_drive as sd


def test_enable_move_jog_stop_disable(drive):
    drive.enable()
    assert drive.status().mode is sd.Mode.RUNNING
    r = drive.move(0.27, wait=True)
    assert r["outcome"] == "accepted"
    assert drive.status().position_m == pytest.approx(0.27, abs=20e-6)
    drive.jog(-0.01)
    drive._wait(lambda s: abs(s.position_m - 0.26) < 20e-6 and abs(s.speed_rad_s) < 1, 30, "jog")
    drive.stop()
    drive.disable()
    drive._wait(lambda s: s.mode is sd.Mode.DISABLED, 10, "disable")


def test_move_beyond_stroke_is_clamped_and_said(running):
    stroke_max = running.get("limits.stroke_max_m")
    r = running.move(stroke_max + 0.1)
    assert r["outcome"] == "clamped_to_stroke" and r["position_m"] <= stroke_max
    running.stop()


def test_move_while_disabled_is_refused_with_reason(drive):
    with pytest.raises(sd.CommandRefused) as e:
        drive.move(0.26)
    assert e.value.reason == "NotRunning"


def test_nan_move_is_refused_before_sending(running):
    with pytest.raises(sd.InputError):
        running.move(float("nan"))


def test_startup_on_a_fresh_drive_homes_it():
    with sd.SimulatedDrive(commissioned=False) as sim, sim.connect() as d:
        assert not d.status().homed
        with pytest.raises(sd.CommandRefused):
            d.enable()
        d.startup(timeout_s=120)
        assert d.status().homed


def test_set_home_and_clear_faults(drive):
    drive.set_home(0.2)
    assert drive.status().position_m == pytest.approx(0.2, abs=1e-4)
    drive.clear_faults()
    assert drive.status().faults == ()
