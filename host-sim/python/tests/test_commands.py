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


def test_move_beyond_stroke_is_refused_before_sending(running):
    # The drive would clamp it and run to the end stop; the package refuses it.
    stroke_max = running.get("limits.stroke_max_m")
    with pytest.raises(sd.InputError) as e:
        running.move(stroke_max + 0.1)
    assert e.value.field == "position_m" and "outside the stroke" in str(e.value)
    assert running.status().speed_rad_s == pytest.approx(0, abs=1.0)


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


def test_bad_numbers_and_a_move_in_millimetres_are_refused_before_sending(running):
    # A target typed in millimetres: refused with the unit named, the rod stays.
    before = running.status().position_m
    with pytest.raises(sd.InputError) as e:
        running.move(250)
    assert e.value.field == "position_m" and "millimetres? positions are in metres: 0.25 m" in str(e.value)
    assert running.status().position_m == pytest.approx(before, abs=20e-6)
    # Times that are not finite or not above zero: named, never a panic.
    for bad in (float("nan"), float("inf"), -1, 0):
        with pytest.raises(sd.InputError) as e:
            running.timeout_s = bad
        assert e.value.field == "timeout_s"
        with pytest.raises(sd.InputError) as e:
            running.capture(["speed"], 10, wait_s=bad)
        assert e.value.field == "wait_s"
    assert running.timeout_s == pytest.approx(5.0)
    # A refusal names the request as the user would type it, not Rust debug text.
    with pytest.raises(sd.DriveError) as e:
        running.set("speed_pi.kp", 1e30)
    assert "param set control.speed_pi.kp" in str(e.value) and "ParamSet {" not in str(e.value)
