"""The CMMO-ST twin over Modbus TCP, driven by pymodbus (a client nobody here wrote).

`drivetwin run --device cmmo-st --modbus 127.0.0.1:PORT` serves the FHPP telegrams on registers
0…3 (the FHPP manual's extract kept beside the project, spec/cmmo-st-fhpp.md §2.5): writes are
the output telegram (CCON, CPOS, byte 3, byte 4, setpoint int32 big-endian), reads the input
telegram (SCON, SPOS, …).
"""

from __future__ import annotations

import signal
import socket
import struct
import subprocess
import threading
import time

import pytest
from pymodbus.client import ModbusTcpClient

from conftest import DRIVETWIN_BIN, HOST, START_TIMEOUT, STOP_TIMEOUT, free_port

# SCON / SPOS bits (Tab. 5.13).
SCON_ENABLED, SCON_OPEN, SCON_FAULT = 0x01, 0x02, 0x08
SPOS_HALT, SPOS_ACK, SPOS_MC, SPOS_MOV, SPOS_FOLERR, SPOS_REF = 0x01, 0x02, 0x04, 0x10, 0x20, 0x80
# CCON / CPOS.
CCON_RECORD_ENABLED = 0x03  # ENABLE + STOP
CCON_DIRECT_ENABLED = 0x43  # OPM1 + STOP + ENABLE
CPOS_HALT, CPOS_START, CPOS_HOM = 0x01, 0x02, 0x04


class CmmoSt:
    """One `drivetwin run --device cmmo-st` process with its Modbus TCP server."""

    def __init__(self, log_dir, extra=()):
        self.port = free_port()
        self.lines: list[str] = []
        self.stderr_path = log_dir / f"cmmo-st-{self.port}.stderr"
        with open(self.stderr_path, "wb") as err:
            self.proc = subprocess.Popen(
                [str(DRIVETWIN_BIN), "run", "--device", "cmmo-st", "--modbus",
                 f"{HOST}:{self.port}", *extra],
                stdout=subprocess.PIPE, stderr=err, text=True, bufsize=1)
        self._ready = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self._ready.wait(START_TIMEOUT)
        if not any(l.startswith("modbus server on") for l in self.lines):
            self.proc.kill()
            pytest.fail(f"no 'modbus server on' line: {self.lines} {self.stderr()}")
        assert f"modbus server on {HOST}:{self.port}" in self.lines, self.lines
        assert "running; Ctrl-C stops" in self.lines or self._wait_line("running; Ctrl-C stops")

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))
            if line.startswith("modbus server on"):
                self._ready.set()
        self._ready.set()

    def _wait_line(self, text, timeout=2.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.lines:
                return True
            time.sleep(0.01)
        return False

    def stderr(self) -> str:
        try:
            return self.stderr_path.read_text(errors="replace")
        except OSError:
            return ""

    def client(self) -> ModbusTcpClient:
        c = ModbusTcpClient(HOST, port=self.port, timeout=2, retries=0)
        assert c.connect(), "connect failed"
        return c

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                pytest.fail("drivetwin ignored SIGTERM")
        self._reader.join(2)
        assert self.proc.returncode == 0, self.stderr()
        assert "stopped" in self.lines, self.lines


@pytest.fixture
def cmmo(tmp_path):
    """Factory: cmmo(*extra_args) starts a CMMO-ST twin; stopped (and checked) at teardown."""
    twins = []

    def _start(*extra):
        t = CmmoSt(tmp_path, extra)
        twins.append(t)
        return t

    yield _start
    for t in twins:
        t.stop()


# Both ways the twin serves its connection: the cycle thread itself (default) or a tokio task.
IO = ["thread", "async"]


def telegram(ccon, cpos, byte3=0, byte4=0, setpoint=0):
    """The 8 output bytes as 4 big-endian registers."""
    raw = struct.pack(">BBBBi", ccon, cpos, byte3, byte4, setpoint)
    return list(struct.unpack(">4H", raw))


def decode(registers):
    scon, spos, b3, b4, actual = struct.unpack(">BBBBi", struct.pack(">4H", *registers))
    return {"scon": scon, "spos": spos, "byte3": b3, "byte4": b4, "actual": actual}


def exchange(client, regs):
    """One FC 0x17 cycle: write the output telegram, read the input telegram."""
    rr = client.readwrite_registers(read_address=0, read_count=4, write_address=0, values=regs)
    assert not rr.isError(), rr
    return decode(rr.registers)


def cycle_until(client, regs, pred, timeout=10.0, what="condition"):
    deadline = time.monotonic() + timeout
    while True:
        s = exchange(client, regs)
        if pred(s):
            return s
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what}: {s}")
        time.sleep(0.005)


def enable_and_home(client):
    s = exchange(client, telegram(0, 0))
    assert (s["scon"], s["spos"]) == (0x10, 0x04), s  # power-on (Example 1)
    s = cycle_until(client, telegram(CCON_RECORD_ENABLED, CPOS_HALT),
                    lambda s: (s["scon"], s["spos"]) == (0x13, 0x05), what="enabled 13h/05h")
    # Homing (method -35, current position) by CPOS.HOM, then take HOM away.
    cycle_until(client, telegram(CCON_RECORD_ENABLED, CPOS_HALT | CPOS_HOM),
                lambda s: s["spos"] & SPOS_REF and s["spos"] & SPOS_MC, what="referenced")
    cycle_until(client, telegram(CCON_RECORD_ENABLED, CPOS_HALT),
                lambda s: not s["spos"] & SPOS_ACK, what="ACK falls")


@pytest.mark.parametrize("io", IO)
def test_enable_and_direct_move_to_a_sinc_position(cmmo, io):
    """FHPP-MB-03, FHPP-CB-14: FC 17h cycles in direct mode: ACK / MC 0 at START, MC at the
    target once START is back to 0."""
    twin = cmmo("--modbus-io", io)
    c = twin.client()
    try:
        enable_and_home(c)
        target = 27_000  # 270 deg with the default 0.01 deg SINC
        idle = telegram(CCON_DIRECT_ENABLED, CPOS_HALT, 0x00, 100, target)
        s = cycle_until(c, idle, lambda s: s["scon"] == 0x53, what="direct mode 53h")
        start = telegram(CCON_DIRECT_ENABLED, CPOS_HALT | CPOS_START, 0x00, 100, target)
        s = cycle_until(c, start, lambda s: s["spos"] & SPOS_ACK, what="ACK")
        assert not s["spos"] & SPOS_MC
        s = cycle_until(c, idle, lambda s: s["spos"] & SPOS_MC, what="MC")
        assert abs(s["actual"] - target) <= 180, s  # PNU 1022 position target window
        assert not s["spos"] & (SPOS_MOV | SPOS_FOLERR), s
        # FC 0x03 reads the same input telegram.
        rr = c.read_holding_registers(0, count=4)
        assert not rr.isError()
        assert decode(rr.registers)["scon"] == 0x53
    finally:
        c.close()


def test_read_device_identification(cmmo):
    """FHPP-MB-06: FC 2Bh / 0Eh basic (objects 00…02) and regular (03, 04, 06; no 05)."""
    twin = cmmo()
    c = twin.client()
    try:
        rr = c.read_device_information(read_code=0x01, object_id=0)
        assert not rr.isError(), rr
        assert rr.information[0] == b"Festo AG & Co. KG"
        assert rr.information[1] == b"1512317"
        assert rr.information[2] == b"1.5.2.0"
        rr = c.read_device_information(read_code=0x02, object_id=0)
        assert not rr.isError(), rr
        assert rr.information[3] == b"http://www.festo.com"
        assert rr.information[4] == b"CMMO-ST-C5-1-LKP"
        assert 5 not in rr.information
    finally:
        c.close()


@pytest.mark.parametrize("io", IO)
def test_wrong_address_and_quantity_get_exceptions(cmmo, io):
    """FHPP-MB-07: start address 1 → exception 02, quantity 5 → 03; FHPP-MB-05: FC 07h
    answers 0 without a fault."""
    twin = cmmo("--modbus-io", io)
    c = twin.client()
    try:
        rr = c.read_holding_registers(1, count=4)
        assert rr.isError() and rr.exception_code == 0x02
        rr = c.read_holding_registers(0, count=5)
        assert rr.isError() and rr.exception_code == 0x03
        rr = c.write_registers(0, [0, 0])
        assert rr.isError() and rr.exception_code == 0x03
        rr = c.readwrite_registers(read_address=2, read_count=4, write_address=0,
                                   values=telegram(0, 0))
        assert rr.isError() and rr.exception_code == 0x02
        # The server keeps serving.
        rr = c.read_holding_registers(0, count=4)
        assert not rr.isError()
        assert decode(rr.registers)["scon"] == 0x10
        rr = c.read_exception_status()
        assert not rr.isError() and rr.status == 0
    finally:
        c.close()


@pytest.mark.parametrize("io", IO)
def test_second_client_is_refused(cmmo, io):
    twin = cmmo("--modbus-io", io)
    c = twin.client()
    try:
        assert not c.read_holding_registers(0, count=4).isError()
        with socket.create_connection((HOST, twin.port), timeout=2) as s2:
            s2.settimeout(2)
            assert s2.recv(16) == b"", "the second connection is closed without a byte"
        # The first one is undisturbed.
        assert not c.read_holding_registers(0, count=4).isError()
    finally:
        c.close()


@pytest.mark.parametrize("io", IO)
def test_watchdog_fires_when_the_client_goes_silent(cmmo, io):
    """FHPP-MB-08, FHPP-DIAG-01: silent for longer than the timeout while Modbus holds control
    → the connection is closed and error 47h raised (FHPP-MB-05: FC 07h answers 47h)."""
    twin = cmmo("--modbus-timeout-ms", "200", "--modbus-io", io)
    c = twin.client()
    try:
        enable_and_home(c)
    finally:
        c.close()  # a silent client would do the same: keep the socket, stop sending
    c = twin.client()
    s = exchange(c, telegram(CCON_RECORD_ENABLED, CPOS_HALT))
    assert s["scon"] & SCON_ENABLED and not s["scon"] & SCON_FAULT  # a close is no timeout
    # Now go silent with the connection open: after 200 ms the server closes it.
    time.sleep(0.6)
    c.close()
    c = twin.client()
    try:
        rr = c.read_exception_status()
        assert not rr.isError()
        assert rr.status == 0x47, hex(rr.status)  # Modbus connection with master control
        s = decode(c.read_holding_registers(0, count=4).registers)
        assert s["scon"] & SCON_FAULT, s
        # Reconnected: the cause is gone, RESET acknowledges it (T10).
        exchange(c, telegram(CCON_RECORD_ENABLED, CPOS_HALT))
        s = cycle_until(c, telegram(CCON_RECORD_ENABLED | 0x08, CPOS_HALT),
                        lambda s: not s["scon"] & SCON_FAULT, timeout=3, what="fault reset")
        assert c.read_exception_status().status == 0
    finally:
        c.close()
