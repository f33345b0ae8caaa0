"""The default cell's CMMP-AS driven by python-canopen's BaseNode402 over socketcand: the
CiA 402 state machine, mode changes, a profile-position move ending in the position window,
a velocity ramp, a torque step, quick stop, and fault reset after a following error."""

from __future__ import annotations

import time

import pytest
from canopen.profiles.p402 import BaseNode402

from conftest import map_pdo, wait_until


@pytest.fixture
def drive(cmmp, connect, eds_files):
    net = connect(cmmp)
    node = BaseNode402(1, str(eds_files["cmmp-as"]))
    net.add_node(node)
    node.nmt.wait_for_heartbeat(3)
    node.setup_402_state_machine()
    return node


def test_state_machine_to_operation_enabled_and_back(drive):
    # BaseNode402 raises if a single transition is not confirmed within 0.4 s.
    assert drive.state == "SWITCH ON DISABLED"
    drive.state = "OPERATION ENABLED"
    assert drive.statusword & 0x6F == 0x27
    drive.state = "SWITCHED ON"
    assert drive.statusword & 0x6F == 0x23
    drive.state = "SWITCH ON DISABLED"
    assert drive.statusword & 0x4F == 0x40


def test_op_mode_changes_are_confirmed(drive):
    for mode in ("PROFILED POSITION", "PROFILED VELOCITY", "PROFILED TORQUE", "HOMING"):
        drive.op_mode = mode
        assert drive.op_mode == mode
    assert drive.sdo[0x6502].raw == 0x6D


def test_profile_position_move_ends_in_the_window_with_target_reached(drive):
    drive.op_mode = "PROFILED POSITION"
    drive.state = "OPERATION ENABLED"
    revs = 4
    drive.sdo[0x607A].raw = revs * 65536
    drive.sdo[0x6081].raw = 1200  # rpm
    drive.sdo[0x6083].raw = 12000  # rpm/s
    drive.sdo[0x6084].raw = 12000
    drive.controlword = 0x1F  # new set-point
    t0 = time.monotonic()
    wait_until(lambda: drive.statusword & 0x1000, 0.4, what="set-point acknowledge")
    drive.controlword = 0x0F
    wait_until(lambda: drive.statusword & 0x0400, 3.0, interval=0.005, what="target reached")
    took = time.monotonic() - t0
    # Trapezoid: 0.1 s ramps each side, 4 rev at 20 rev/s cruise → 0.3 s in all.
    assert 0.25 < took < 0.8, took
    pos = drive.sdo[0x6064].raw
    assert abs(pos - revs * 65536) <= drive.sdo[0x6067].raw, pos
    assert drive.statusword & 0x2000 == 0, "no following error"


def test_velocity_ramp_and_torque_step(drive):
    drive.op_mode = "PROFILED VELOCITY"
    drive.state = "OPERATION ENABLED"
    # Statusword and actual velocity in one synchronous TPDO, one snapshot of the drive as a
    # master reads its process data: two SDO reads lie milliseconds apart on the bus, and the
    # velocity moves meanwhile.
    drive.tpdo.read()
    snapshot = map_pdo(drive.tpdo[3], [0x6041, 0x606C], trans_type=1)
    drive.nmt.state = "OPERATIONAL"
    window = drive.sdo[0x606D].raw
    drive.sdo[0x60FF].raw = 2000

    def reached():
        drive.network.sync.transmit()
        snapshot.wait_for_reception(0.5)
        return snapshot[0x6041].raw & 0x0400 and snapshot[0x606C].raw

    velocity = wait_until(reached, 2.0, what="velocity reached")
    assert abs(velocity - 2000) <= window, velocity
    drive.sdo[0x60FF].raw = 0
    wait_until(lambda: drive.statusword & 0x1000, 2.0, what="speed 0")
    drive.op_mode = "PROFILED TORQUE"
    drive.sdo[0x6087].raw = 100000  # ‰/s
    drive.sdo[0x6071].raw = 300
    wait_until(lambda: abs(drive.sdo[0x6077].raw - 300) < 40, 1.0, what="torque actual")
    wait_until(lambda: drive.sdo[0x606C].raw > 200, 1.0, what="the motor accelerates")


def test_quick_stop_then_switch_on_disabled(drive):
    drive.op_mode = "PROFILED VELOCITY"
    drive.state = "OPERATION ENABLED"
    drive.sdo[0x60FF].raw = 1500
    wait_until(lambda: drive.statusword & 0x0400, 2.0, what="at speed")
    drive.controlword = 0x02
    wait_until(lambda: drive.statusword & 0x4F == 0x40, 1.0, what="switch on disabled after the ramp")
    assert abs(drive.sdo[0x606C].raw) < 50


def test_fault_reset_after_a_following_error(drive):
    drive.op_mode = "PROFILED POSITION"
    drive.state = "OPERATION ENABLED"
    # A hard following-error limit of 20 increments trips on a real move (error 17-0): the
    # well-tuned axis lags ~90 increments while accelerating.
    drive.sdo[0x6510][0x22].raw = 20
    drive.sdo[0x607A].raw = 10 * 65536
    drive.controlword = 0x1F
    wait_until(lambda: drive.is_faulted(), 1.0, what="FAULT")
    wait_until(lambda: any(e.code == 0x8611 for e in drive.emcy.log), 1.0, what="EMCY 8611h")
    assert [e.code for e in drive.emcy.active] == [0x8611]
    drive.sdo[0x6510][0x22].raw = 0
    drive.reset_from_fault()
    assert drive.state == "OPERATION ENABLED"
    # The error-free EMCY (0000h) empties python-canopen's list of active errors.
    wait_until(lambda: drive.emcy.log[-1].code == 0x0000, 1.0, what="EMCY 0000h")
    assert drive.emcy.active == []
