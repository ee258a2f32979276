import json

import pytest

import servo_drive as sd


def test_a_fresh_drive_runs_the_compiled_weights(drive):
    s = drive.observer_status()
    assert s["source"] == "compiled"
    assert (s["inputs"], s["hidden"], s["words"]) == (4, 8, 75)
    assert len(s["words_crc"]) == 8


def test_a_file_that_is_not_a_model_is_refused_naming_it(drive, tmp_path):
    bad = tmp_path / "model.json"
    bad.write_text(json.dumps({"weights": [float("inf")]}))
    with pytest.raises(sd.ObserverRejected) as e:
        drive.upload_observer(bad)
    assert "model.json" in str(e.value) and "not a trainer model.json" in str(e.value)
    with pytest.raises(sd.ObserverRejected):
        drive.upload_observer(tmp_path / "missing.json")
    assert drive.observer_status()["source"] == "compiled"  # nothing changed
