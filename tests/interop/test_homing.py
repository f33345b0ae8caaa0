"""CMMP-AS homing (CiA 402 mode 6) driven by python-canopen's BaseNode402 over socketcand: method
17 (negative limit switch) and method 34 (index pulse, positive) on the default travel of the
twin, checked by 6064h and the statusword afterwards."""

from __future__ import annotations

import pytest
from canopen.profiles.p402 import BaseNode402

from conftest import wait_until

REV = 65536
HOME_OFFSET = 1000


@pytest.fixture
def drive(cmmp, connect, eds_files):
    net = connect(cmmp)
    node = BaseNode402(1, str(eds_files["cmmp-as"]))
    net.add_node(node)
    node.nmt.wait_for_heartbeat(3)
    node.setup_402_state_machine()
    # Faster than the defaults (100 / 10 min⁻¹): the twin runs in real time and the negative
    # limit switch sits 20 revolutions from the power-on position.
    node.sdo[0x6099][1].raw = 1200
    node.sdo[0x6099][2].raw = 60
    node.sdo[0x609A].raw = 20000
    node.sdo[0x607C].raw = HOME_OFFSET
    return node


def homed(node) -> None:
    sw = node.sdo[0x6041].raw
    assert sw & 0x3000 == 0x1000, f"homing attained, no error: {sw:04X}"
    assert sw & 0x8000, "referenced"


def test_method_17_then_34(drive):
    assert drive.sdo[0x6098].raw == 17, "the default method (CMMP-HM-04)"
    assert drive.homing(timeout=15), "method 17"
    homed(drive)
    # The reference is where the negative limit switch went inactive; the drive brakes from
    # crawl speed just past it.
    pos = drive.sdo[0x6064].raw
    assert HOME_OFFSET <= pos <= HOME_OFFSET + 400, pos
    assert abs(drive.sdo[0x606C].raw) <= 30, "stands (the speed filter settles)"

    # Method 34: crawl positive to the next index pulse, a quarter revolution past the
    # switch edge (the index is at 16384 of every revolution, the edge at −20 revolutions).
    drive.controlword = 0x0F  # bit 4 low first: homing starts on its rising edge
    wait_until(lambda: drive.sdo[0x6041].raw & 0x0400, 1.0, what="still standing")
    drive.sdo[0x6098].raw = 34
    drive.sdo[0x607C].raw = 0
    before = drive.sdo[0x6064].raw
    assert drive.homing(timeout=15), "method 34"
    homed(drive)
    pos = drive.sdo[0x6064].raw
    assert 0 <= pos <= 400, pos
    # In the frame of the first homing the index was at HOME_OFFSET + 16384.
    assert before < HOME_OFFSET + 16384


def test_halt_aborts_homing_with_homing_error(drive):
    # Halt during the search: homing_error (bit 13), the drive stays enabled.
    drive.op_mode = "HOMING"
    drive.state = "OPERATION ENABLED"
    drive.controlword = 0x1F
    wait_until(lambda: drive.sdo[0x606C].raw < -100, 2.0, what="searching negative")
    drive.controlword = 0x11F
    wait_until(lambda: drive.sdo[0x6041].raw & 0x2000, 2.0, what="homing error")
    assert drive.state == "OPERATION ENABLED"
    assert not drive.sdo[0x6041].raw & 0x9000


def test_timeout_is_error_11_3_with_emcy_8a83(drive):
    # CMMP-HM-06 / CMMP-EMCY-04: 2045h exceeded → 11-3, EMCY 8A83h with error register 01h.
    drive.sdo[0x6099][1].raw = 100
    drive.sdo[0x2045].raw = 300
    assert not drive.homing(timeout=3)
    wait_until(lambda: any(e.code == 0x8A83 for e in drive.emcy.log), 1.0, what="EMCY 8A83h")
    emcy = next(e for e in drive.emcy.log if e.code == 0x8A83)
    assert emcy.register == 0x01
    assert drive.sdo[0x6041].raw & 0x2000, "homing error"
    wait_until(lambda: drive.is_faulted(), 1.0, what="FAULT")
