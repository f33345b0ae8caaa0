"""A confirmed write has been taken (DESIGN "never faster, never stricter than the device"):
controlwords and FHPP telegrams written back to back, each after its answer and with no pause,
all take effect, on the default cell of each device and over each of its interfaces. Each run
disables the drive and enables it again; 20 runs of 20 must end in OPERATION ENABLED (or, on
the CMMO-ST, at the target of a move started by a START pulse within the burst).

The drive is polled only to learn the outcome, as field code waits for a statusword."""

from __future__ import annotations

import pytest

from conftest import wait_until
from test_fhpp_modbus import CCON_DIRECT_ENABLED, CPOS_HALT, CPOS_START, SPOS_MC, cmmo, decode, \
    enable_and_home, telegram  # noqa: F401 (cmmo is a fixture)
from test_kinco_serial import KincoPort, _line, _rtu_client

RUNS = 20
ENABLE = (0x00, 0x06, 0x07, 0x0F)


def operation_enabled(sw: int) -> bool:
    return sw & 0x6F == 0x27


@pytest.mark.parametrize("device,node", [("cmmp-as", 1), ("nanotec-smci47s", 34), ("kinco-fd3", 1)])
def test_sdo_controlwords_back_to_back(launch, node_of, device, node):
    twin = launch(device, node)
    n = node_of(twin)
    if device.startswith("kinco"):
        # Factory DIN1 = Enable and DIN3 = Operation Mode Sel own 6040h / 6060h (Kinco L1287).
        n.sdo[0x2010][3].raw = 0
        n.sdo[0x2010][5].raw = 0
    # The Nanotec demo's sequence starts with a fault-reset edge.
    words = (0x00, 0x80, 0x06, 0x07, 0x0F) if device.startswith("nanotec") else ENABLE
    enabled = 0
    for _ in range(RUNS):
        for cw in words:
            n.sdo[0x6040].raw = cw
        wait_until(lambda: operation_enabled(n.sdo[0x6041].raw), 1.0, what="OPERATION ENABLED")
        enabled += 1
    assert enabled == RUNS


def test_kinco_rs232_controlwords_back_to_back(launch, node_of, tmp_path):
    path = tmp_path / "ttyKINCO"
    twin = launch("kinco-fd3", 1, extra=("--rs232", str(path)))
    _line(twin, "RS232", path)
    port = KincoPort(path)
    try:
        for index, sub in ((0x2010, 3), (0x2010, 5)):
            assert port.write(index, sub, 0, 2)[1] == 0x60
        for _ in range(RUNS):
            for cw in ENABLE:
                answer = port.write(0x6040, 0, cw, 2)
                assert answer[1] == 0x60, answer.hex(" ")
            wait_until(lambda: operation_enabled(port.read(0x6041)[1]), 1.0,
                       what="OPERATION ENABLED over RS232")
    finally:
        port.close()


def test_kinco_modbus_rtu_controlwords_back_to_back(launch, node_of, tmp_path):
    path = tmp_path / "ttyRS485"
    twin = launch("kinco-fd3", 1, extra=("--rs485", str(path)))
    _line(twin, "RS485", path)
    # Din3_Function has no Modbus register: the DIN functions are freed over CANopen.
    n = node_of(twin)
    n.sdo[0x2010][3].raw = 0
    n.sdo[0x2010][5].raw = 0
    c = _rtu_client(path)
    try:
        for _ in range(RUNS):
            for cw in ENABLE:
                r = c.write_register(0x3100, cw, device_id=1)
                assert not r.isError(), r
            wait_until(lambda: operation_enabled(
                c.read_holding_registers(0x3200, count=1, device_id=1).registers[0]), 1.0,
                what="OPERATION ENABLED over Modbus RTU")
    finally:
        c.close()


def test_fhpp_telegrams_back_to_back(cmmo):
    """A PLC that disables, enables and pulses START (set, then taken away) with one Modbus
    write each, no pause: every run moves to its target."""
    twin = cmmo()
    c = twin.client()
    try:
        enable_and_home(c)
        for run in range(RUNS):
            target = 9000 * (1 + run % 2)
            for regs in (telegram(0, 0),
                         telegram(CCON_DIRECT_ENABLED, CPOS_HALT, 0, 50, target),
                         telegram(CCON_DIRECT_ENABLED, CPOS_HALT | CPOS_START, 0, 50, target),
                         telegram(CCON_DIRECT_ENABLED, CPOS_HALT, 0, 50, target)):
                assert not c.write_registers(0, regs).isError()

            def at_target():
                s = decode(c.read_holding_registers(0, count=4).registers)
                return s["spos"] & SPOS_MC and abs(s["actual"] - target) <= 180 and s
            wait_until(at_target, 5.0, what=f"run {run}: at {target} SINC")
    finally:
        c.close()
