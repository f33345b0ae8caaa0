"""The Kinco FD3's serial front ends (Kinco FD/CD manual extract spec/kinco-fd-cd.md §2.1-2.3,
kept beside the project) through
the real binary: `drivetwin run --rs232 PATH / --rs485 PATH` make PATH a link to a pty of the
twin, opened here the way public Kinco programs open a serial port (pyserial, 38400 8N1,
exclusive, 80 ms read timeout, one 10-byte telegram then a 10-byte read) and by pymodbus's
serial client (RTU framer). What one front end writes, the others read: CANopen over
socketcand sees the same objects."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from conftest import CHANNEL, HOST, wait_until

serial = pytest.importorskip("serial")


def checksum(b: bytes) -> int:
    """KINCO-232-01: CHKS = (-sum of bytes 0..8) mod 256."""
    return (-sum(b)) & 0xFF


def telegram(station: int, cmd: int, index: int, sub: int, value: int = 0) -> bytes:
    body = bytes([station, cmd, index & 0xFF, index >> 8, sub]) + (value & 0xFFFFFFFF).to_bytes(4, "little")
    return body + bytes([checksum(body)])


class KincoPort:
    """An RS232 client as public Kinco drivers write it: write 10 bytes, read 10 bytes."""

    def __init__(self, path: Path, station: int = 1, baud: int = 38400):
        self.station = station
        self.s = serial.Serial(str(path), baud, bytesize=8, parity="N", stopbits=1, timeout=0.08,
                               exclusive=True)

    def exchange(self, raw: bytes) -> bytes:
        self.s.reset_input_buffer()
        self.s.write(raw)
        return self.s.read(10)

    def read(self, index: int, sub: int = 0) -> tuple[int, int]:
        a = self.exchange(telegram(self.station, 0x40, index, sub))
        assert len(a) == 10 and sum(a) & 0xFF == 0, a.hex(" ")
        size = {0x43: 4, 0x4B: 2, 0x4F: 1, 0x80: 4}[a[1]]
        return a[1], int.from_bytes(a[5:5 + size], "little")

    def write(self, index: int, sub: int, value: int, size: int) -> bytes:
        cmd = {4: 0x23, 2: 0x2B, 1: 0x2F}[size]
        return self.exchange(telegram(self.station, cmd, index, sub, value))

    def close(self):
        self.s.close()


def _line(twin, kind: str, path: Path):
    wait_until(lambda: any(l.startswith(f"{kind} line on {path}") for l in twin.stdout_lines), 5.0,
               what=f"the {kind} line")
    assert path.is_symlink() and str(path.resolve()).startswith("/dev/pts/"), path


def test_rs232_like_a_public_kinco_driver(launch, node_of, tmp_path):
    """KINCO-232-01, KINCO-232-03, KINCO-232-04, KINCO-232-06, KINCO-232-05, KINCO-232-07, KINCO-232-08 and KINCO-232-11 through pyserial; the value written over
    RS232 is read back over CANopen, and one written over CANopen over RS232."""
    path = tmp_path / "ttyKINCO"
    twin = launch("kinco-fd3", 1, extra=("--rs232", str(path)))
    _line(twin, "RS232", path)
    node = node_of(twin)
    # Factory DIN1 = Enable and DIN3 = Operation Mode Sel own 6040h / 6060h (manual L1287): a
    # master frees them first, as on the real drive.
    node.sdo[0x2010][3].raw = 0
    node.sdo[0x2010][5].raw = 0
    port = KincoPort(path)
    try:
        # KINCO-232-04 and KINCO-232-06: the statusword, 16 bit.
        code, sw = port.read(0x6041)
        assert code == 0x4B
        assert sw == node.sdo[0x6041].raw
        # KINCO-232-01 and KINCO-232-05: controlword := 2Fh, answered 60h.
        a = port.exchange(bytes.fromhex("01 2B 40 60 00 2F 00 00 00 05"))
        assert a[:5] == bytes.fromhex("01 60 40 60 00") and sum(a) & 0xFF == 0, a.hex(" ")
        assert node.sdo[0x6040].raw == 0x2F, "CANopen reads what RS232 wrote"
        # KINCO-232-03: target position 50000 written, read back over RS232 and CANopen.
        a = port.exchange(bytes.fromhex("01 23 7A 60 00 50 C3 00 00 EF"))
        assert a[1] == 0x60, a.hex(" ")
        assert port.read(0x607A) == (0x43, 50000)
        assert node.sdo[0x607A].raw == 50000
        node.sdo[0x607A].raw = -1234
        assert port.read(0x607A) == (0x43, (-1234) & 0xFFFFFFFF), "RS232 reads what CANopen wrote"
        # KINCO-232-07: a wrong checksum, no answer.
        assert port.exchange(bytes.fromhex("01 2B 40 60 00 2F 00 00 00 06")) == b""
        # KINCO-232-08: another station's telegram, no answer, nothing written.
        node.sdo[0x6040].raw = 0x06
        assert port.exchange(bytes.fromhex("02 2B 40 60 00 2F 00 00 00 04")) == b""
        assert node.sdo[0x6040].raw == 0x06
        # KINCO-232-11: an object the drive does not have, 80h with 0602 0000h.
        a = port.exchange(bytes.fromhex("01 2B 00 99 00 01 00 00 00 3A"))
        assert a[:5] == bytes.fromhex("01 80 00 99 00") and a[5:9] == bytes.fromhex("00 00 02 06")
        # Short telegrams and noise: dropped; the next telegram is answered.
        port.s.write(b"\x01\x40\x41")
        time.sleep(0.05)
        port.s.write(bytes(range(7, 250, 3)))
        time.sleep(0.05)
        assert port.read(0x6041)[0] == 0x4B
    finally:
        port.close()
    twin.stop()
    assert not path.exists() and not path.is_symlink(), "the link goes with the twin"


def test_rs232_round_trip_takes_the_wire_time(launch, tmp_path):
    """10 bytes at 38400 bit/s take 2.6 ms; a telegram and its answer 5.2 ms, and
    the twin adds little to it."""
    path = tmp_path / "ttyKINCO"
    twin = launch("kinco-fd3", 1, extra=("--rs232", str(path)))
    _line(twin, "RS232", path)
    port = KincoPort(path)
    try:
        times = []
        for _ in range(40):
            t = time.perf_counter()
            assert port.read(0x6041)[0] == 0x4B
            times.append(time.perf_counter() - t)
        times.sort()
        wire = 20 * 10 / 38400
        assert times[0] >= wire * 0.98, f"faster than the wire: {times[0] * 1e3:.2f} ms"
        # Loaded 2-core CI machines: the median within 3 ms of the wire time.
        assert times[len(times) // 2] < wire + 0.003, f"median {times[len(times) // 2] * 1e3:.2f} ms"
    finally:
        port.close()


def test_host_that_never_reads_does_not_stall_the_line(launch, node_of, tmp_path):
    """Bad input: a host that writes and never reads. The answers fill the pty, then are
    dropped (counted, said once); CANopen goes on, and the line answers the next host. At
    115200 bit/s (RS232_Baudrate 2FE0h = 90, KINCO-232-10) to fill the pty's buffer sooner."""
    path = tmp_path / "ttyKINCO"
    cell = tmp_path / "cell.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
        "[[drive]]", 'device = "kinco-fd3"', "node = 1", f'rs232 = "{path}"',
        "[drive.objects]", '"2FE0:00" = 90', "",
    ]))
    twin = launch(config=cell, device="kinco-fd3")
    _line(twin, "RS232", path)
    node = node_of(twin)
    greedy = serial.Serial(str(path), 115200, timeout=0)
    read_sw = telegram(1, 0x40, 0x6041, 0)
    deadline = time.monotonic() + 30
    while "does not read" not in twin.stderr():
        assert time.monotonic() < deadline, "no warning after 30 s of flooding"
        greedy.write(read_sw * 100)
        time.sleep(0.09)
    assert node.sdo[0x6041].raw >= 0, "CANopen answers while the line is flooded"
    for _ in range(10):
        greedy.write(read_sw * 100)
        time.sleep(0.09)
    assert twin.stderr().count("does not read") == 1, "said once"
    greedy.close()
    port = KincoPort(path, baud=115200)
    try:
        # Answers of the flood still waiting in the twin come first: read until a clean one.
        def answered():
            a = port.exchange(telegram(1, 0x40, 0x6041, 0))
            return a[:2] == bytes([1, 0x4B]) and sum(a) & 0xFF == 0
        wait_until(answered, 10.0, what="an answer after the flood")
    finally:
        port.close()


def _rtu_client(path: Path, baud: int = 19200):
    from pymodbus.client import ModbusSerialClient

    c = ModbusSerialClient(port=str(path), baudrate=baud, bytesize=8, parity="N", stopbits=1,
                           timeout=0.3, retries=0)
    assert c.connect()
    return c


def test_rs485_modbus_rtu_with_pymodbus(launch, node_of, tmp_path):
    """KINCO-MB-01, KINCO-MB-02 and KINCO-MB-03 through pymodbus's serial client; a bad CRC and another station get
    no answer; the registers are the CANopen objects."""
    from pymodbus.exceptions import ModbusIOException

    path = tmp_path / "ttyRS485"
    twin = launch("kinco-fd3", 1, extra=("--rs485", str(path)))
    _line(twin, "RS485", path)
    node = node_of(twin)
    # Factory DIN1 = Enable and DIN3 = Operation Mode Sel own 6040h / 6060h (manual L1287): a
    # master frees them first, as on the real drive.
    node.sdo[0x2010][3].raw = 0
    node.sdo[0x2010][5].raw = 0
    c = _rtu_client(path)
    try:
        # KINCO-MB-01: two registers from the statusword: its value, low word first.
        r = c.read_holding_registers(0x3200, count=2, device_id=1)
        assert not r.isError(), r
        assert r.registers == [node.sdo[0x6041].raw, 0]
        # KINCO-MB-02: controlword 000Fh, echoed.
        r = c.write_register(0x3100, 0x000F, device_id=1)
        assert not r.isError() and r.registers == [0x000F], r
        assert node.sdo[0x6040].raw == 0x000F
        # KINCO-MB-03: target velocity 0008 5555h, low word first.
        r = c.write_registers(0x6F00, [0x5555, 0x0008], device_id=1)
        assert not r.isError(), r
        assert node.sdo[0x60FF].raw == 0x00085555
        node.sdo[0x60FF].raw = -2
        r = c.read_holding_registers(0x6F00, count=2, device_id=1)
        assert r.registers == [0xFFFE, 0xFFFF]
        # Another station: no answer.
        with pytest.raises(ModbusIOException):
            c.read_holding_registers(0x3200, count=2, device_id=5)
    finally:
        c.close()
    # A bad CRC: no answer (raw bytes over pyserial).
    s = serial.Serial(str(path), 19200, timeout=0.2)
    try:
        s.write(bytes.fromhex("01 03 32 00 00 02 CA B4"))
        assert s.read(16) == b""
        s.write(bytes.fromhex("01 03 32 00 00 02 CA B3"))
        a = s.read(9)
        assert a[:3] == bytes.fromhex("01 03 04"), a.hex(" ")
    finally:
        s.close()


def test_two_drives_on_one_rs485_line(launch, node_of, tmp_path):
    """Two FD3s on one RS485 line, each answering its station number (= node-ID)."""
    path = tmp_path / "ttyBUS"
    cell = tmp_path / "cell.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
        "[[drive]]", 'device = "kinco-fd3"', "node = 1", f'rs485 = "{path}"', "",
        "[[drive]]", 'device = "kinco-fd3"', "node = 2", f'rs485 = "{path}"', "",
    ]))
    twin = launch(config=cell, device="kinco-fd3")
    _line(twin, "RS485", path)
    n1 = node_of(twin, 1)
    n2 = node_of(twin, 2)
    c = _rtu_client(path)
    try:
        assert not c.write_registers(0x4000, [1000, 0], device_id=1).isError()
        assert not c.write_registers(0x4000, [2000, 0], device_id=2).isError()
        assert n1.sdo[0x607A].raw == 1000
        assert n2.sdo[0x607A].raw == 2000
        assert c.read_holding_registers(0x4000, count=2, device_id=2).registers == [2000, 0]
        assert c.read_holding_registers(0x4000, count=2, device_id=1).registers == [1000, 0]
    finally:
        c.close()


def test_drivetwin_kinco_master_over_the_pty(launch, node_of, tmp_path):
    """`drivetwin kinco read|write|status --port PATH --id N` against the
    twin's RS232 pty, checked over CANopen."""
    from conftest import run_cli

    path = tmp_path / "ttyKINCO"
    twin = launch("kinco-fd3", 3, extra=("--rs232", str(path)))
    _line(twin, "RS232", path)
    node = node_of(twin)
    port = ("--port", str(path), "--id", "3")
    r = run_cli("kinco", "write", "607A", "0", "-5000", *port)
    assert r.returncode == 0, r.stderr
    assert node.sdo[0x607A].raw == -5000
    r = run_cli("kinco", "read", "0x607A", *port)
    assert r.returncode == 0 and r.stdout.strip() == "-5000", (r.stdout, r.stderr)
    r = run_cli("kinco", "status", *port)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[0].startswith("statusword"), r.stdout
    # Another station: no answer (exit 4); an object the drive lacks: the abort (exit 5).
    r = run_cli("kinco", "read", "6041", "--port", str(path), "--id", "9")
    assert r.returncode == 4 and "no answer" in r.stderr, r.stderr
    r = run_cli("kinco", "read", "9900", *port)
    assert r.returncode == 5 and "06020000" in r.stderr, r.stderr


def test_two_drives_on_an_rs232_ring(launch, node_of, tmp_path):
    """KINCO-232-09: RS232_Loop_Enable 6510h:0B = 1 on two drives sharing one RS232 path: the
    host reads its own telegram, then the answer of the station it named; to a station no
    drive has, the echo only."""
    path = tmp_path / "ttyRING"
    cell = tmp_path / "cell.toml"
    lines = ["[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', ""]
    for n in (1, 2):
        lines += ["[[drive]]", 'device = "kinco-fd3"', f"node = {n}", f'rs232 = "{path}"',
                  "[drive.objects]", '"6510:0B" = 1', ""]
    cell.write_text("\n".join(lines))
    twin = launch(config=cell, device="kinco-fd3")
    _line(twin, "RS232", path)
    n2 = node_of(twin, 2)
    s = serial.Serial(str(path), 38400, timeout=0.08, exclusive=True)
    try:
        t = telegram(2, 0x23, 0x607A, 0, 777)
        s.write(t)
        got = s.read(20)
        assert got[:10] == t and got[10:12] == bytes([2, 0x60]), got.hex(" ")
        assert n2.sdo[0x607A].raw == 777
        t = telegram(1, 0x40, 0x607A, 0)
        s.write(t)
        got = s.read(20)
        assert got[:10] == t and got[10:12] == bytes([1, 0x43]), got.hex(" ")
        t = telegram(9, 0x40, 0x6041, 0)
        s.write(t)
        assert s.read(20) == t
    finally:
        s.close()


def test_a_real_device_path_is_opened_not_linked(launch, tmp_path):
    """`--rs232 /dev/...` naming a character device opens that device (here the slave of a pty
    this test made, standing in for /dev/ttyUSB0): no link, the twin answers on it."""
    import os
    import select

    master, slave = os.openpty()
    name = os.ttyname(slave)
    os.close(slave)
    try:
        twin = launch("kinco-fd3", 1, extra=("--rs232", name))
        wait_until(lambda: any(l.startswith(f"RS232 line on device {name}") for l in twin.stdout_lines),
                   5.0, what="the device line")
        os.write(master, telegram(1, 0x40, 0x6041, 0))
        got = b""
        deadline = time.monotonic() + 2
        while len(got) < 10 and time.monotonic() < deadline:
            if select.select([master], [], [], 0.1)[0]:
                got += os.read(master, 64)
        assert got[:2] == bytes([1, 0x4B]) and sum(got[:10]) & 0xFF == 0, got.hex(" ")
        twin.stop()
        assert os.path.exists(name), "a device is never removed"
    finally:
        os.close(master)


def test_base_node_402_moves_the_drive_while_rs232_polls_its_position(launch, connect, eds_files,
                                                                     tmp_path):
    """One drive, two masters at once, as a machine with a PLC on CANopen and a
    service PC on RS232 has them. python-canopen's BaseNode402 runs the CiA 402 state machine
    and a profile position move over socketcand while a pyserial client polls 6063h (position
    actual, increments) over RS232 every 10 ms: every poll is answered, the positions it sees
    climb to the target, and both masters read the same end position."""
    import threading

    from canopen.profiles.p402 import BaseNode402

    from conftest import SDO_TIMEOUT

    path = tmp_path / "ttyKINCO"
    twin = launch("kinco-fd3", 1, extra=("--rs232", str(path)))
    _line(twin, "RS232", path)
    net = connect(twin)
    node = BaseNode402(1, str(eds_files["kinco-fd3"]))
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    node.sdo[0x2010][3].raw = 0  # DIN1 and DIN3 give the controlword and the mode to the bus
    node.sdo[0x2010][5].raw = 0
    node.sdo[0x6060].raw = 1
    node.setup_402_state_machine(read_pdos=False)

    port = KincoPort(path)
    seen: list[int] = []
    unanswered = [0]
    stop = threading.Event()

    def poll():
        while not stop.is_set():
            a = port.exchange(telegram(1, 0x40, 0x6063, 0))
            if len(a) != 10 or sum(a) & 0xFF or a[1] != 0x43:
                unanswered[0] += 1
            else:
                seen.append(int.from_bytes(a[5:9], "little", signed=True))
            time.sleep(0.01)

    poller = threading.Thread(target=poll, daemon=True)
    poller.start()
    try:
        node.op_mode = "PROFILED POSITION"
        node.sdo[0x6081].raw = int(600 * 512 * 10_000 / 1875)  # 600 rpm in DEC
        node.sdo[0x6083].raw = int(100 * 65536 * 10_000 / 4_000_000)  # 100 rps² in DEC
        node.sdo[0x6084].raw = int(100 * 65536 * 10_000 / 4_000_000)
        node.state = "OPERATION ENABLED"
        start = node.sdo[0x6063].raw
        target = start + 100_000
        node.sdo[0x607A].raw = target
        node.controlword = 0x1F  # new set-point, absolute
        wait_until(lambda: node.statusword & 0x1000, 1.0, what="set-point acknowledged")
        node.controlword = 0x0F
        wait_until(lambda: node.statusword & 0x0400, 5.0, interval=0.01, what="target reached")
        time.sleep(0.1)  # a few more polls at the target
    finally:
        stop.set()
        poller.join(2)
        port.close()
    end = node.sdo[0x6063].raw
    assert abs(end - target) <= 20, (end, target)
    assert unanswered[0] == 0, f"{unanswered[0]} RS232 polls unanswered of {len(seen)}"
    assert len(seen) >= 30, len(seen)
    moving = [p for p in seen if start + 100 < p < target - 100]
    assert len(moving) >= 5, f"RS232 saw the move: {seen[:5]} … {seen[-5:]}"
    assert all(b >= a - 20 for a, b in zip(seen, seen[1:])), "the position climbs"
    assert abs(seen[-1] - end) <= 20, (seen[-1], end)
