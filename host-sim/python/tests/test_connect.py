import socket
import threading

import pytest

import servo_drive as sd
from servo_drive import _native


def test_info_and_status_are_typed(drive):
    i = drive.info()
    assert i.schema_hash == sd.SCHEMA_HASH and i.params_schema_hash == sd.PARAMS_SCHEMA_HASH
    assert i.pwm_frequency_hz == 20000.0
    assert i.mode is sd.Mode.DISABLED
    s = drive.status()
    assert s.mode is sd.Mode.DISABLED and s.faults == ()
    # Commissioned: calibrated, commutated and homed; at the default start position.
    assert set(s.readiness) == {"calibrated", "commutated", "homed"}
    assert s.position_m == pytest.approx(0.25, abs=1e-4)
    assert 40 < s.bus_voltage_v < 60


def _fake_drive(schema_hash: bytes, params_hash: bytes):
    """A TCP server answering the first request with an Info of the given hashes."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)

    def serve():
        conn, _ = srv.accept()
        buf = b""
        while buf.count(b"\0") < 2:  # the lone delimiter, then the Info request
            chunk = conn.recv(256)
            if not chunk:
                return
            buf += chunk
        conn.sendall(bytes(_native.encode_info_reply(1, list(schema_hash), list(params_hash))))
        conn.recv(16)
        conn.close()

    threading.Thread(target=serve, daemon=True).start()
    return srv, "127.0.0.1:%d" % srv.getsockname()[1]


def test_wrong_schema_hash_is_refused_naming_both():
    other = bytes(range(8))
    srv, addr = _fake_drive(other, bytes.fromhex(sd.PARAMS_SCHEMA_HASH))
    with pytest.raises(sd.SchemaMismatch) as e:
        sd.connect(addr)
    srv.close()
    assert e.value.drive_hash == other.hex() and e.value.package_hash == sd.SCHEMA_HASH
    assert other.hex() in str(e.value) and sd.SCHEMA_HASH in str(e.value)


def test_wrong_parameter_schema_hash_is_refused():
    other = bytes([9] * 8)
    srv, addr = _fake_drive(bytes.fromhex(sd.SCHEMA_HASH), other)
    with pytest.raises(sd.SchemaMismatch) as e:
        sd.connect(addr)
    srv.close()
    assert e.value.drive_hash == other.hex() and e.value.package_hash == sd.PARAMS_SCHEMA_HASH


def test_nobody_listening_is_a_connect_error():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    with pytest.raises(sd.ConnectError):
        sd.connect(f"127.0.0.1:{port}")


def test_closed_drive_raises_connection_lost(drive):
    drive.close()
    with pytest.raises(sd.ConnectionLost):
        drive.status()


def test_missing_host_sim_binary_is_named(monkeypatch, tmp_path):
    monkeypatch.setenv("SERVO_DRIVE_HOST_SIM", str(tmp_path / "nothing"))
    with pytest.raises(sd.SimulatorError) as e:
        sd.SimulatedDrive()
    assert "SERVO_DRIVE_HOST_SIM" in str(e.value)


def test_simulated_drive_stops_its_process():
    with sd.SimulatedDrive() as s:
        assert s.running
    assert not s.running
