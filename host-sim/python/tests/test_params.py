import pytest

import servo_drive as sd


def test_get_set_by_dotted_path(drive):
    kp = drive.get("speed_pi.kp")
    assert drive.get("control.speed_pi.kp") == kp
    applied = drive.set("speed_pi.kp", kp * 1.5)
    assert applied == pytest.approx(kp * 1.5, rel=1e-6)
    assert drive.get("speed_pi.kp") == pytest.approx(kp * 1.5, rel=1e-6)


def test_out_of_range_value_names_field_and_reason(drive):
    kp = drive.get("speed_pi.kp")
    with pytest.raises(sd.ParameterRejected) as e:
        drive.set("speed_pi.kp", -1.0)
    assert e.value.field == "control.speed_pi.kp" and e.value.reason == "MustBePositive"
    assert drive.get("speed_pi.kp") == kp  # nothing changed


def test_nan_value_is_refused_before_sending(drive):
    with pytest.raises(sd.InputError) as e:
        drive.set("speed_pi.kp", float("nan"))
    assert e.value.field == "control.speed_pi.kp"


def test_unknown_path_suggests_closest(drive):
    with pytest.raises(sd.UnknownParameter) as e:
        drive.get("speed_pi.kpp")
    assert e.value.suggestions[0] == "control.speed_pi.kp"
    with pytest.raises(sd.UnknownParameter) as e:
        drive.set("limits.stroke_max", 0.3)
    assert "control.limits.stroke_max_m" in e.value.suggestions


def test_list_has_units_defaults_and_bounds(drive):
    ps = {p.path: p for p in drive.parameters()}
    assert len(ps) == len(sd.PARAM_PATHS)
    r = ps["control.motor.phase_resistance_ohm"]
    assert r.unit == "Ω" and r.min == 0.0 and r.min_exclusive and r.value == r.default
    assert ps["control.limits.stroke_max_m"].unit == "m"
    assert ps["control.motor.pole_pairs"].kind == "uint" and ps["control.motor.pole_pairs"].min == 1


def test_export_import_roundtrip(drive, tmp_path):
    kp = drive.get("speed_pi.kp")
    f = tmp_path / "params.toml"
    n = drive.export_params(f)
    assert n == len(sd.PARAM_PATHS) and "[control" in f.read_text()
    drive.set("speed_pi.kp", kp * 2)
    drive.import_params(f)
    assert drive.get("speed_pi.kp") == pytest.approx(kp, rel=1e-6)


def test_import_of_bad_file_changes_nothing(drive, tmp_path):
    kp = drive.get("speed_pi.kp")
    f = tmp_path / "bad.toml"
    f.write_text("[control.speed_pi]\nkp = -3.0\n")
    with pytest.raises(sd.ParameterRejected):
        drive.import_params(f)
    assert drive.get("speed_pi.kp") == kp


def test_save_and_load_through_the_store(tmp_path):
    store = tmp_path / "store.bin"
    with sd.SimulatedDrive(store=store) as sim, sim.connect() as d:
        kp = d.get("speed_pi.kp")
        d.set("speed_pi.kp", kp * 1.25)
        d.save()
        d.defaults()
        assert d.get("speed_pi.kp") == pytest.approx(kp, rel=1e-6)
        d.load()
        assert d.get("speed_pi.kp") == pytest.approx(kp * 1.25, rel=1e-6)


def test_save_refused_with_bridge_on(running):
    with pytest.raises(sd.Refused):
        running.save()


def test_core_range_is_listed_and_enforced(drive):
    ps = {p.path: p for p in drive.parameters()}
    bounded = [p for p in ps.values() if p.max_abs is not None and p.kind == "float" and p.min is not None]
    assert bounded, "the core states physical ranges"
    p = bounded[0]
    with pytest.raises(sd.ParameterRejected) as e:
        drive.set(p.path, p.max_abs * 10)
    assert e.value.field == p.path
    assert drive.get(p.path) == pytest.approx(p.value)
