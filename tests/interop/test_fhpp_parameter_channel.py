"""The CMMO-ST parameter channel (EFPC, manual App. C) over Modbus TCP, driven by pymodbus.

FC 0x17 with 8 registers carries "FHPP Standard + FPC": registers 0-3 the FHPP telegram,
register 4 = FPCC/FPCS (high byte) and subindex or packet ID (low byte), register 5 the PNU,
registers 6-7 the PWE, all big-endian (the FHPP manual's extract kept beside the project,
spec/cmmo-st-fhpp.md §2.5, §2.9). A job is answered at the drive's next cycle, so the master
polls until FPCS changes.
"""

from __future__ import annotations

import contextlib
import struct
import time

import pytest

from test_fhpp_modbus import CCON_RECORD_ENABLED, CPOS_HALT, cmmo, telegram  # noqa: F401

NO_TASK = bytes([0x10, 0, 0, 0, 0, 0, 0, 0])
NO_TASK_FILE = bytes([0x40, 0, 0, 0, 0, 0, 0, 0])
IDLE = telegram(0, 0)

# Tab. C.7
ILLEGAL_PNU, CANNOT_CHANGE, LIMIT, WRONG_SUB = 0x00, 0x01, 0x02, 0x03
NOT_IN_STATE, REQ_NOT_SUPPORTED, WRITE_ONLY = 0x11, 0x65, 0x66


def regs(fhpp_regs, fpc: bytes) -> list[int]:
    return list(fhpp_regs) + list(struct.unpack(">4H", fpc))


def exchange(client, fpc: bytes, fhpp_regs=IDLE) -> bytes:
    """One FC 0x17 with 8 registers: returns the 8 FPC input bytes."""
    rr = client.readwrite_registers(read_address=0, read_count=8, write_address=0,
                                    values=regs(fhpp_regs, fpc))
    assert not rr.isError(), rr
    assert len(rr.registers) == 8
    return struct.pack(">4H", *rr.registers[4:])


def poll(client, fpc: bytes, done, fhpp_regs=IDLE, timeout=2.0) -> bytes:
    """Sends `fpc` until the answer satisfies `done`."""
    deadline = time.monotonic() + timeout
    while True:
        r = exchange(client, fpc, fhpp_regs)
        if done(r):
            return r
        if time.monotonic() > deadline:
            pytest.fail(f"no answer to {fpc.hex()}: {r.hex()}")
        time.sleep(0.001)


def job(client, fpc: bytes, fhpp_regs=IDLE) -> bytes:
    """C.3.2: "no task" until response ID 0, then the job until a response comes."""
    poll(client, NO_TASK, lambda r: r[0] == 0x10, fhpp_regs)
    return poll(client, fpc, lambda r: r[0] & 0x0F != 0, fhpp_regs)


def read_req(pnu: int, sub: int) -> bytes:
    return struct.pack(">BBHI", 0x16, sub, pnu, 0)


def write_req(pnu: int, sub: int, value: int) -> bytes:
    return struct.pack(">BBHI", 0x18, sub, pnu, value & 0xFFFFFFFF)


def answer(r: bytes):
    fpcs, sub, pnu, pwe = struct.unpack(">BBHI", r)
    return fpcs, sub, pnu, pwe


def read(client, pnu, sub, fhpp_regs=IDLE):
    fpcs, s, p, pwe = answer(job(client, read_req(pnu, sub), fhpp_regs))
    assert (s, p) == (sub, pnu)
    assert fpcs in (0x15, 0x17), hex(fpcs)
    return ("ok" if fpcs == 0x15 else "error", pwe)


def write(client, pnu, sub, value, fhpp_regs=IDLE):
    fpcs, s, p, pwe = answer(job(client, write_req(pnu, sub, value), fhpp_regs))
    assert (s, p) == (sub, pnu)
    assert fpcs in (0x15, 0x17), hex(fpcs)
    return ("ok" if fpcs == 0x15 else "error", pwe)


def signed(v: int) -> int:
    return struct.unpack(">i", struct.pack(">I", v))[0]


def test_read_and_write_pnus_through_fc_0x17(cmmo):
    c = cmmo().client()
    try:
        # FHPP-MB-04 / FHPP-FPC-01 (fhpp §8.2 c): read PNU 1041:1 (actual position) over
        # FC 0x17 with 8 registers -> 15 01 04 11 <int32 BE>.
        r = job(c, bytes.fromhex("1601041100000000"))
        assert r[:4] == bytes.fromhex("15010411"), r.hex()
        # uint16 array, read-only: firmware version 1.5.2.0 (PNU 101:1-4).
        assert [read(c, 101, s) for s in range(1, 5)] == [("ok", v) for v in (1, 5, 2, 0)]
        # uint8 array: the user device name, one character per subindex (PNU 121, rw1).
        for i, ch in enumerate(b"FPC", start=1):
            assert write(c, 121, i, ch) == ("ok", ch)
        assert [read(c, 121, i)[1] for i in range(1, 4)] == list(b"FPC")
        # English manual Fig. C.1: write PNU 440:2 = 4660, the answer echoes the bytes.
        r = job(c, bytes.fromhex("180201B800001234"))
        assert r == bytes.fromhex("150201B800001234"), r.hex()
        assert read(c, 440, 2) == ("ok", 4660)
        # int32 record array, sign-extended both ways (PNU 404:3 target of record 3).
        assert write(c, 404, 3, -100_000) == ("ok", 0xFFFE7960)
        status, v = read(c, 404, 3)
        assert (status, signed(v)) == ("ok", -100_000)
        # int8 (PNU 600 = -2) reads sign-extended.
        assert read(c, 600, 1) == ("ok", 0xFFFFFFFE)
    finally:
        c.close()


def test_error_responses(cmmo):
    c = cmmo().client()
    try:
        assert read(c, 99, 1) == ("error", ILLEGAL_PNU)
        r = job(c, bytes.fromhex("160103E700000000"))  # FHPP-FPC-04
        assert r == bytes.fromhex("170103E700000000"), r.hex()
        r = job(c, bytes.fromhex("1602041100000000"))  # FHPP-FPC-05
        assert r == bytes.fromhex("1702041100000003"), r.hex()
        assert write(c, 100, 1, 0) == ("error", CANNOT_CHANGE)  # read-only
        assert write(c, 127, 2, 2) == ("error", LIMIT)  # PNU 127:2 takes only 1
        assert write(c, 418, 1, 1001) == ("error", LIMIT)  # int16 0...1000
        assert write(c, 600, 1, 0xFD) == ("error", LIMIT)  # int8 not sign-extended
        assert read(c, 101, 9) == ("error", WRONG_SUB)
        assert read(c, 101, 0) == ("error", WRONG_SUB)
        assert read(c, 204, 3) == ("error", WRITE_ONLY)  # delete diagnostic memory
        # ReqID 4 (upload) is a file-mode request: 65h in parameter mode.
        r = job(c, bytes.fromhex("1401006500000000"))
        assert r == bytes.fromhex("1701006500000065"), r.hex()
        # rw2 (PNU 1023) with the output stage on: 11h; rw1 (PNU 121) is fine.
        enabled = telegram(CCON_RECORD_ENABLED, CPOS_HALT)
        deadline = time.monotonic() + 2
        while True:
            rr = c.readwrite_registers(read_address=0, read_count=8, write_address=0,
                                       values=regs(enabled, NO_TASK))
            assert not rr.isError()
            if rr.registers[0] >> 8 == 0x13:  # SCON: enabled, operation enabled
                break
            assert time.monotonic() < deadline, hex(rr.registers[0])
        assert write(c, 1023, 1, 20, enabled) == ("error", NOT_IN_STATE)
        assert write(c, 121, 1, 0x41, enabled) == ("ok", 0x41)
        assert write(c, 1023, 1, 20) == ("ok", 20)  # disabled again
    finally:
        c.close()


def test_a_new_job_needs_the_zero_request(cmmo):
    """FHPP-FPC-02."""
    c = cmmo().client()
    try:
        first = job(c, write_req(121, 1, 0x31))
        assert first[0] == 0x15
        # A different job without "no task": the old answer stays, nothing is written.
        for _ in range(20):
            assert exchange(c, write_req(121, 2, 0x32)) == first
            time.sleep(0.002)
        # "No task" -> response ID 0; now the job is taken.
        assert poll(c, NO_TASK, lambda r: r == NO_TASK) == NO_TASK
        assert read(c, 121, 2) == ("ok", 0), "the ignored job was not carried out later"
        assert write(c, 121, 2, 0x32) == ("ok", 0x32)
    finally:
        c.close()


def test_writes_are_volatile_until_pnu_127_2(cmmo):
    c = cmmo().client()
    try:
        assert write(c, 121, 1, ord("S")) == ("ok", ord("S"))
        # FHPP-FPC-03 (fhpp §8.2 d): save with `18 02 00 7F 00 00 00 01` -> FPCS 15h.
        assert job(c, bytes.fromhex("1802007F00000001"))[0] == 0x15
        assert write(c, 121, 1, ord("X")) == ("ok", ord("X"))
        # PNU 127:4 = 10h loads the saved values.
        assert write(c, 127, 4, 0x10) == ("ok", 0x10)
        assert read(c, 121, 1) == ("ok", ord("S"))
    finally:
        c.close()


def crc16_ibm_3740(data: bytes) -> int:
    """CRC-16/IBM-3740 (CCITT-FALSE), written here from its definition."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def file_packet(c, fpcc: int, packet_id: int, data: bytes = bytes(6)) -> bytes:
    """One file packet; waits for the handshake (same packet ID) or an error."""
    req = bytes([fpcc, packet_id]) + data
    return poll(c, req, lambda r: (r[0] == 0x43 and r[1] == packet_id)
                or r[0] == 0x47 or (r[0] == 0x43 and r[1] >> 5 == 0b011))


def test_parameter_file_upload_and_download(cmmo):
    c = cmmo().client()
    try:
        assert write(c, 121, 1, ord("U")) == ("ok", ord("U"))
        assert write(c, 127, 2, 1) == ("ok", 1)
        # Upload (C.4.5): start packet 001 00000, the size comes back little-endian.
        poll(c, NO_TASK_FILE, lambda r: r[0] == 0x40)
        r = file_packet(c, 0x44, 0x20)
        assert r[:2] == bytes([0x43, 0x20]), r.hex()
        size = struct.unpack("<I", r[2:6])[0]
        data = bytearray()
        seq = 0
        while len(data) < size:
            seq = 0 if seq == 31 else seq + 1
            r = file_packet(c, 0x44, seq)
            assert r[:2] == bytes([0x43, seq]), r.hex()
            data += r[2:]
        assert not any(data[size:]), "zero padding"
        f = bytes(data[:size])
        r = file_packet(c, 0x44, 0x40)  # stop
        assert r[:2] == bytes([0x43, 0x40])
        poll(c, NO_TASK_FILE, lambda r: r[0] == 0x40)
        # The documented format: FHPF, 256-byte header, data, CRC-16 LE.
        assert f[:4] == b"FHPF"
        version, header_len, data_len = struct.unpack("<HHI", f[4:12])
        assert (version, header_len, len(f)) == (1, 256, 256 + data_len + 2)
        assert f[20:27] == b"cmmo-st"
        assert struct.unpack("<H", f[-2:])[0] == crc16_ibm_3740(f[:-2])
        # Download the file back after a change; it is activated by PNU 127:4 only.
        assert write(c, 121, 1, ord("Z")) == ("ok", ord("Z"))
        poll(c, NO_TASK_FILE, lambda r: r[0] == 0x40)
        r = file_packet(c, 0x45, 0x20, struct.pack("<IH", len(f), 0))
        assert r[:6] == bytes([0x43, 0x20]) + struct.pack("<I", len(f)), r.hex()
        seq = 0
        for at in range(0, len(f), 6):
            seq = 0 if seq == 31 else seq + 1
            chunk = f[at:at + 6].ljust(6, b"\0")
            r = file_packet(c, 0x45, seq, chunk)
            assert r[:2] == bytes([0x43, seq]), r.hex()
        r = file_packet(c, 0x45, 0x40 | seq)  # stop
        assert r[:2] == bytes([0x43, 0x40 | seq]), r.hex()
        poll(c, NO_TASK_FILE, lambda r: r[0] == 0x40)
        assert read(c, 121, 1) == ("ok", ord("Z")), "stored, not active yet (C.4.4)"
        assert write(c, 127, 4, 0x10) == ("ok", 0x10)
        assert read(c, 121, 1) == ("ok", ord("U"))
        # A second download within 3 s: type-1 error 11h in FPCS (47h), code in byte 3.
        poll(c, NO_TASK_FILE, lambda r: r[0] == 0x40)
        r = file_packet(c, 0x45, 0x20, struct.pack("<IH", len(f), 0))
        assert r[:3] == bytes([0x47, 0x20, NOT_IN_STATE]), r.hex()
    finally:
        c.close()


def test_a_type_2_error_aborts_and_shows_e27(cmmo):
    """FHPP-FPC-15: an aborting error shows E27 (diagnostic 27h, also in FC 0x07)."""
    c = cmmo().client()
    try:
        poll(c, NO_TASK_FILE, lambda r: r[0] == 0x40)
        # Download of an invalid length: error packet 011 00000 with code 05h, E27.
        r = file_packet(c, 0x45, 0x20, struct.pack("<IH", 10, 0))
        assert r[:3] == bytes([0x43, 0x60, 0x05]), r.hex()
        deadline = time.monotonic() + 2
        while True:
            rr = c.read_holding_registers(0, count=8)
            assert not rr.isError()
            if rr.registers[0] >> 8 & 0x08:  # SCON.FAULT
                break
            assert time.monotonic() < deadline
        rr = c.read_exception_status()
        assert not rr.isError() and rr.status == 0x27, rr
    finally:
        c.close()


@contextlib.contextmanager
def powered_on(cmmo, state):
    """One run of a twin with `--state-dir state`: the twin and its client, then stopped."""
    twin = cmmo("--state-dir", str(state))
    c = twin.client()
    try:
        yield twin, c
    finally:
        c.close()
        twin.stop()


def test_the_permanent_memory_survives_a_restart_with_a_state_dir(cmmo, tmp_path):
    """PNU 127:2 writes the permanent memory to --state-dir (atomically); the next start
    powers on from it; PNU 127:1 deletes it; a damaged file gives the factory settings."""
    state = tmp_path / "state"
    eeprom = state / "cmmo-st-node1.eeprom"
    with powered_on(cmmo, state) as (twin, c):
        assert write(c, 121, 1, ord("S")) == ("ok", ord("S"))
        assert not eeprom.exists(), "a write alone is volatile"
        assert job(c, bytes.fromhex("1802007F00000001"))[0] == 0x15  # 127:2 save
        assert eeprom.exists()
    with powered_on(cmmo, state) as (twin, c):
        assert read(c, 121, 1) == ("ok", ord("S")), "powered on from the saved memory"
        assert write(c, 127, 1, 0x10) == ("ok", 0x10)  # 127:1 delete EEPROM
        assert not eeprom.exists()
    with powered_on(cmmo, state) as (twin, c):
        assert read(c, 121, 1) == ("ok", 0), "factory settings after the delete"
    eeprom.write_bytes(b"\x00" * 40)
    with powered_on(cmmo, state) as (twin, c):
        assert read(c, 121, 1) == ("ok", 0)
        assert not c.read_holding_registers(0, count=4).isError(), "and it serves"
    assert "factory settings" in twin.stderr()
