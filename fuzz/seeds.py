#!/usr/bin/env python3
"""Seed corpora for the fuzz targets, from the manuals' worked frames (spec/vectors.md and the
manuals' extracts, kept beside the project in ../shared/spec) and from the protocol's everyday
messages. Writes corpus/TARGET/seed-*; libFuzzer grows the corpus from there. Usage: seeds.py
SPEC_DIR"""

import json
import re
import struct
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
FRAME = re.compile(r"\b([0-9A-F]{3})h?: ?((?:\b[0-9A-F]{2}\b ?){0,8})")
CI_LINE = re.compile(r"`([?=][0-9A-F]{6}(?::[0-9A-F]{2,8})?)`")


def write(target, name, data):
    d = HERE / "corpus" / target
    d.mkdir(parents=True, exist_ok=True)
    (d / f"seed-{name}").write_bytes(data)


def can_record(cob, payload):
    """One record of canopen_node's input: n, id lo, id hi, n data bytes."""
    return bytes([len(payload)]) + struct.pack("<H", cob) + bytes(payload)


def pause(ms):
    return b"\xff" + struct.pack("<H", ms)


def frames_of(line):
    """The master's frames in one line of a table (node-relative ids moved to node 1)."""
    out = []
    for cob, data in FRAME.findall(line):
        cob = int(cob, 16)
        payload = [int(b, 16) for b in data.split()]
        fn, node = cob & 0x780, cob & 0x7F
        if cob == 0 or cob == 0x80 or fn in (0x200, 0x300, 0x400, 0x500, 0x600):
            out.append((fn | 1 if node else cob, payload))
        elif cob in (0x7E5,):
            out.append((cob, payload))
    return out


def canopen_seeds(spec):
    start = can_record(0x000, [0x01, 0x01])  # NMT start node 1
    n = 0
    for md in sorted(spec.glob("*.md")):
        for line in md.read_text(encoding="utf-8").splitlines():
            frames = frames_of(line)
            if not frames:
                continue
            body = start + b"".join(can_record(c, p) for c, p in frames) + pause(20)
            write("canopen_node", f"{md.stem}-{n:04}", body)
            n += 1
    return n


def ci_seeds(spec):
    n = 0
    vectors = spec / "vectors.md"
    if not vectors.is_file():
        return 0
    for line in vectors.read_text(encoding="utf-8").splitlines():
        for cmd in CI_LINE.findall(line):
            write("ci_terminal", f"{n:03}", cmd.encode() + b"\r\n")
            n += 1
    return n


def mbap(tid, pdu):
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, 0) + pdu


def modbus_seeds():
    # FHPP: FC 0x17 read 4 / write 4 at address 0 (CMMO-ST), FC 3, FC 16, FC 43/14, a bad one.
    fc17 = bytes([0x17]) + struct.pack(">HHHHB", 0, 4, 0, 4, 8) + bytes([0x03, 0, 0, 0, 0, 0, 0, 0])
    fc3 = bytes([0x03]) + struct.pack(">HH", 0, 8)
    fc16 = bytes([0x10]) + struct.pack(">HHB", 0, 2, 4) + bytes([1, 2, 3, 4])
    fc43 = bytes([0x2B, 0x0E, 0x01, 0x00])
    stream = b"".join(mbap(i, p) for i, p in enumerate([fc17, fc3, fc16, fc43, b"\x07"]))
    for cut in (1, 7, 255):
        write("modbus_tcp_stream", f"cut{cut}", bytes([cut]) + stream)
    for i, p in enumerate([fc17, fc3, fc16, fc43]):
        body = bytes([1]) + p
        crc = 0xFFFF
        for b in body:
            crc ^= b
            for _ in range(8):
                crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        write("modbus_rtu", f"{i}", bytes([1]) + body + struct.pack("<H", crc))
    return 7


def socketcand_seeds():
    session = (
        b"< open vcan0 >< rawmode >< send 601 8 40 18 10 01 00 00 00 00 >"
        b"< send 000 2 01 01 >< echo >< bcmmode >< add 1 0 123 4 01 02 03 04 >"
        b"< frame 581 1.000000 43 18 10 01 1D 00 00 00 >< error text >"
    )
    for cut in (1, 5, 64, 255):
        write("socketcand_text", f"cut{cut}", bytes([cut]) + session)
    return 4


def coe_seeds():
    # Mailbox header (length, address, channel/priority, type 3 + counter) + CoE SDO request.
    def mbx(counter, payload):
        return struct.pack("<HHBB", len(payload), 0, 0, 0x03 | (counter << 4)) + payload

    upload = bytes([0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])
    download = bytes([0x00, 0x20, 0x2B, 0x40, 0x60, 0x00, 0x06, 0x00, 0, 0])
    info = bytes([0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00])
    session = b"".join(
        struct.pack("<H", 0x80) + mbx(1 + i, p).ljust(0x80, b"\x00")
        for i, p in enumerate([upload, download, info])
    )
    write("coe_mailbox", "cmmp-as", b"\x00" + session)
    write("coe_mailbox", "full", b"\x01" + session)
    return 3


REPO = HERE.parent
TELEGRAM = re.compile(r'"((?:[0-9A-F]{2} ){9}[0-9A-F]{2})"')
JSON_BODY = re.compile(r"json!\((\{.*?\})\)")
# The first key of a body names its route (the byte fuzz/fuzz_targets/http_body.rs reads).
ROUTE_OF_KEY = {
    "node": 0, "frames": 0, "value": 1, "raw": 1, "mask": 2, "levels": 2, "volts": 3,
    "torque_nm": 4, "direction": 5, "velocity": 5, "target": 6, "relative": 6,
    "velocity_percent": 6, "settings": 7, "active": 8, "key": 9, "action": 9, "name": 10,
    "fault": 11,
}


def kinco_seeds():
    """The telegrams of the Kinco RS232 tests (KINCO-232-01...), point to point and in a ring."""
    telegrams = []
    for f in [REPO / "crates/drive/src/vendors/kinco/rs232.rs", *sorted((REPO / "crates/drive/tests").glob("kinco*.rs"))]:
        if f.is_file():
            telegrams += [bytes.fromhex(t) for t in TELEGRAM.findall(f.read_text(encoding="utf-8"))]
    for setup, name in ((0x01, "p2p"), (0x81, "ring")):
        body = bytes([setup])
        for t in telegrams:
            body += bytes([10]) + t + b"\xff\x05"
        # A telegram cut by a pause longer than the gap, then one whole.
        if telegrams:
            body += bytes([4]) + telegrams[0][:4] + b"\xff\x30" + bytes([10]) + telegrams[0]
        write("kinco_rs232", name, body)
    return len(telegrams)


def http_seeds():
    """The JSON bodies of the web API tests, each with the route its first key names."""
    n = 0
    files = sorted((REPO / "crates/drivetwin/tests").glob("*.rs")) + sorted((REPO / "crates/drivetwin/src/web").glob("*.rs"))
    seen = set()
    for f in files:
        for body in JSON_BODY.findall(f.read_text(encoding="utf-8")):
            try:
                obj = json.loads(body)
            except ValueError:
                continue  # a body built from variables
            key = next(iter(obj), "value")
            route = ROUTE_OF_KEY.get(key, 1)
            data = bytes([route, 0x80]) + json.dumps(obj).encode()
            if data not in seen:
                seen.add(data)
                write("http_body", f"{n:03}", data)
                n += 1
    return n


def main():
    spec = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parent.parent / "shared" / "spec"
    if not spec.is_dir():
        print(f"no spec extracts at {spec}: seeds from the protocol messages only")
    counts = {
        "canopen_node": canopen_seeds(spec),
        "ci_terminal": ci_seeds(spec),
        "modbus": modbus_seeds(),
        "socketcand_text": socketcand_seeds(),
        "coe_mailbox": coe_seeds(),
        "kinco_rs232": kinco_seeds(),
        "http_body": http_seeds(),
    }
    for k, v in counts.items():
        print(f"{k}: {v} seeds")


if __name__ == "__main__":
    main()
