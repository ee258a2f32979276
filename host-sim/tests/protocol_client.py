#!/usr/bin/env python3
"""An independent client of the drive protocol, written from docs/protocol-wire.md
alone (standard library only, no project code): it starts the simulated
drive, reads Info and Status, sets a parameter, streams 100 points and
decodes a refusal. The parameter index and the reason names come from the
document's own tables, so a document that disagrees with the drive fails.

    python3 host-sim/tests/protocol_client.py [--drive PATH_TO_host-sim]

Exit status 0 when every check passes.
"""

import os
import re
import socket
import struct
import subprocess
import sys
import time
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DOC = os.path.join(ROOT, "docs", "protocol-wire.md")


# ---- the document's tables -------------------------------------------------

def doc_tables():
    text = open(DOC, encoding="utf-8").read()
    params = {m.group(2): (int(m.group(1)), m.group(3)) for m in re.finditer(r"^\| (\d+) \| `(control\.[a-z0-9_.]+)` \| (\w+) \|$", text, re.M)}
    reasons = {}
    sec = text[text.index("## Reason codes"):]
    for m in re.finditer(r"^\| (\d+) \| ([A-Za-z0-9]+) \| (.*) \|$", sec, re.M):
        reasons.setdefault(int(m.group(1)), m.group(2))
    faults = {}
    sec = text[text.index("## Fault bits"):]
    for m in re.finditer(r"^\| (\d+) \| `([a-z_]+)` \|$", sec, re.M):
        faults[int(m.group(1))] = m.group(2)
    return params, reasons, faults


# ---- postcard ----------------------------------------------------------------

def varint(n):
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        if n:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


def f32(x):
    return struct.pack("<f", x)


class Reader:
    def __init__(self, b):
        self.b, self.i = b, 0

    def varint(self):
        n, shift = 0, 0
        while True:
            c = self.b[self.i]
            self.i += 1
            n |= (c & 0x7F) << shift
            shift += 7
            if not c & 0x80:
                return n

    def f32(self):
        (x,) = struct.unpack_from("<f", self.b, self.i)
        self.i += 4
        return x

    def u8(self):
        self.i += 1
        return self.b[self.i - 1]

    def raw(self, n):
        self.i += n
        return self.b[self.i - n:self.i]

    def text(self):
        return self.raw(self.varint()).decode()


# ---- framing: postcard ‖ CRC-32 (LE), COBS, 0 -------------------------------

def cobs_encode(data):
    out, block = bytearray(), bytearray()
    for c in data:
        if c == 0:
            out += bytes([len(block) + 1]) + block
            block = bytearray()
        else:
            block.append(c)
            if len(block) == 254:
                out += bytes([255]) + block
                block = bytearray()
    out += bytes([len(block) + 1]) + block
    return bytes(out)


def cobs_decode(data):
    out, i = bytearray(), 0
    while i < len(data):
        code = data[i]
        out += data[i + 1:i + code]
        i += code
        if code < 255 and i < len(data):
            out.append(0)
    return bytes(out)


def frame(body):
    return cobs_encode(body + struct.pack("<I", zlib.crc32(body))) + b"\x00"


def unframe(raw):
    b = cobs_decode(raw)
    body, crc = b[:-4], struct.unpack("<I", b[-4:])[0]
    assert zlib.crc32(body) == crc, "CRC mismatch"
    return body


# ---- messages (variant orders from the document) ---------------------------

REQ_INFO, REQ_STATUS, REQ_PARAM_COUNT, REQ_PARAM_GET, REQ_PARAM_SET = 0, 1, 2, 3, 4
REQ_COMMAND, REQ_STREAM = 8, 9
CMD_ENABLE = 0
VALUE_F32 = 0
REPLY_INFO, REPLY_STATUS, REPLY_OK, REPLY_COMMAND, REPLY_PARAM_COUNT, REPLY_PARAM, REPLY_ERROR = 0, 1, 2, 3, 4, 5, 9
ERR_INVALID_PARAM, ERR_STREAM = 3, 9
MODES = ["Disabled", "Calibrating", "Aligning", "Homing", "Running", "Stopping", "Fault", "Braking", "Preloading"]


class Drive:
    def __init__(self, addr):
        self.s = socket.create_connection(addr, timeout=5)
        self.s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.seq = 0
        self.buf = b""
        self.s.sendall(b"\x00")

    def send(self, body_after_seq):
        self.seq = self.seq % 65535 + 1
        self.s.sendall(frame(varint(self.seq) + body_after_seq))
        return self.seq

    def frames(self, timeout=5.0):
        end = time.time() + timeout
        while time.time() < end:
            while b"\x00" in self.buf:
                raw, self.buf = self.buf.split(b"\x00", 1)
                if raw:
                    yield unframe(raw)
            self.s.settimeout(max(0.01, end - time.time()))
            try:
                chunk = self.s.recv(65536)
            except socket.timeout:
                continue
            if not chunk:
                raise ConnectionError("drive closed the link")
            self.buf += chunk

    def reply(self, seq, timeout=5.0):
        """The reply with this seq: (variant, Reader); telemetry skipped."""
        for body in self.frames(timeout):
            r = Reader(body)
            kind = r.varint()
            if kind != 0:  # DriveFrame::Telemetry
                continue
            s = r.varint()
            if s == seq:
                return r.varint(), r
        raise TimeoutError("no reply to seq %d" % seq)

    def ask(self, body):
        return self.reply(self.send(body))


def main():
    params, reasons, faults = doc_tables()
    assert len(params) > 100, "the document's parameter table is missing"
    assert reasons and faults, "the document's reason or fault table is missing"
    exe = None
    if "--drive" in sys.argv:
        exe = sys.argv[sys.argv.index("--drive") + 1]
    else:
        for cand in ("target/x86_64-unknown-linux-gnu/release/host-sim", "target/release/host-sim"):
            p = os.path.join(ROOT, "host-sim", cand)
            if os.path.exists(p):
                exe = p
                break
    assert exe, "build host-sim first (cd host-sim && cargo build --release)"
    drive = subprocess.Popen([exe, "drive", "serve", "--listen", "127.0.0.1:0", "--pace", "fast", "--commissioned"],
                             stderr=subprocess.PIPE, text=True)
    try:
        addr = None
        for line in drive.stderr:
            m = re.search(r"serving on ([0-9.]+):(\d+)", line)
            if m:
                addr = (m.group(1), int(m.group(2)))
                break
        assert addr, "the drive did not say where it serves"
        d = Drive(addr)

        # Info: firmware_version, git_hash (text), schema_hash [u8; 8], ...
        kind, r = d.ask(varint(REQ_INFO))
        assert kind == REPLY_INFO, kind
        version, git = r.text(), r.text()
        schema, pschema, board = r.raw(8).hex(), r.raw(8).hex(), r.text()
        mode, fault_bits, pwm = r.varint(), r.varint(), r.f32()
        print("info: %s %s %s schema %s mode %s pwm %.0f Hz" % (board, version, git, schema, MODES[mode], pwm))
        assert pwm > 0

        # Status: mode, faults, readiness (u8), time_s, test_running, readouts.
        kind, r = d.ask(varint(REQ_STATUS))
        assert kind == REPLY_STATUS, kind
        mode, fault_bits, ready, t = r.varint(), r.varint(), r.u8(), r.f32()
        test_running, pos = r.u8(), r.f32()
        print("status: %s faults %s readiness %d t %.3f s position %.4f m" % (MODES[mode], [faults[b] for b in faults if fault_bits >> b & 1], ready, t, pos))
        assert ready & 4, "commissioned drive should be homed"

        # Set a parameter by the document's index.
        index, typ = params["control.speed_pi.kp"]
        assert typ == "F32"
        kind, r = d.ask(varint(REQ_PARAM_GET) + varint(index))
        assert kind == REPLY_PARAM, kind
        assert r.varint() == index and r.varint() == VALUE_F32
        kp = r.f32()
        kind, r = d.ask(varint(REQ_PARAM_SET) + varint(index) + varint(VALUE_F32) + f32(kp * 0.9))
        assert kind == REPLY_PARAM, kind
        assert r.varint() == index and r.varint() == VALUE_F32
        applied = r.f32()
        assert abs(applied - kp * 0.9) < 1e-6, applied
        print("param set: control.speed_pi.kp %.4f -> %.4f" % (kp, applied))

        # A refusal decoded: NaN for the same leaf.
        kind, r = d.ask(varint(REQ_PARAM_SET) + varint(index) + varint(VALUE_F32) + f32(float("nan")))
        assert kind == REPLY_ERROR, kind
        err = r.varint()
        assert err == ERR_INVALID_PARAM, err
        leaf, reason = r.varint(), r.varint()
        print("refusal: InvalidParam leaf %d reason %d (%s)" % (leaf, reason, reasons[reason]))
        assert leaf == index and reasons[reason] == "MustBeFinite"

        # Enable, then stream 100 points at 1 kHz (fast pacing: lock-step).
        kind, r = d.ask(varint(REQ_COMMAND) + varint(CMD_ENABLE))
        assert kind == REPLY_COMMAND, kind
        for _ in range(200):
            kind, r = d.ask(varint(REQ_STATUS))
            if MODES[r.varint()] == "Running":
                break
            time.sleep(0.01)
        else:
            raise AssertionError("the drive did not reach Running")
        x0, v = pos, 0.01
        seqs = []
        for k in range(100):
            x = x0 + v * (k + 1) * 1e-3
            # StreamPoint: position f32, velocity f32, force Option<f32> (0: None).
            seqs.append(d.send(varint(REQ_STREAM) + f32(x) + f32(v) + b"\x00"))
        # A point beyond the stroke: refused with its seq.
        bad = d.send(varint(REQ_STREAM) + f32(5.0) + f32(0.0) + b"\x00")
        kind, r = d.reply(bad)
        assert kind == REPLY_ERROR and r.varint() == ERR_STREAM, kind
        reason = r.varint()
        print("stream: 100 points sent; the 101st (5 m) refused: %s" % reasons[reason])
        assert reasons[reason] == "BeyondStrokeMax", reasons[reason]
        kind, r = d.ask(varint(REQ_STATUS))
        assert kind == REPLY_STATUS
        mode, fault_bits, ready, t = r.varint(), r.varint(), r.u8(), r.f32()
        r.u8()
        moved = r.f32() - x0
        print("after the stream: %s, moved %.2f mm" % (MODES[mode], moved * 1e3))
        assert fault_bits == 0, [faults[b] for b in faults if fault_bits >> b & 1]
        assert 0.0005 < moved < 0.0015, moved
        print("protocol_client: all checks passed")
    finally:
        drive.terminate()
        drive.wait(timeout=5)


if __name__ == "__main__":
    main()
