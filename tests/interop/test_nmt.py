"""5. NMT state changes as the heartbeat shows them, boot-up after resets, and SDO silence in
STOPPED."""

import threading
import time

import can
import canopen
import pytest

from conftest import HeartbeatLog, recv_id

BOOTUP, STOPPED, OPERATIONAL, PRE_OPERATIONAL = 0x00, 0x04, 0x05, 0x7F


def _fast_heartbeat(node, period_ms=100):
    node.sdo[0x1017].raw = period_ms
    assert node.sdo[0x1017].raw == period_ms


def _expect_state(hb: HeartbeatLog, state: int, since: int):
    """The node reports `state` within a second, and keeps reporting it."""
    pos = hb.wait_for(state, since, timeout=1.5)
    assert hb.next_states(pos, 3, timeout=1.5) == [state] * 3


def test_first_heartbeat_is_pre_operational(cmmp, node_of):
    node = node_of(cmmp)
    # 1017h = 1000 ms is commissioned for a single drive: a heartbeat comes within ~1 s
    t0 = time.monotonic()
    assert node.nmt.wait_for_heartbeat(timeout=3) == "PRE-OPERATIONAL"
    assert time.monotonic() - t0 < 2.5


def test_heartbeat_period_follows_1017(cmmp, raw_bus, node_of):
    node = node_of(cmmp)
    _fast_heartbeat(node, 100)
    bus = raw_bus(cmmp)
    first = recv_id(bus, 0x701, 1.0)
    assert first is not None and bytes(first.data) == b"\x7f"
    stamps = []
    for _ in range(6):
        msg = recv_id(bus, 0x701, 1.0)
        assert msg is not None, "heartbeat missing"
        assert bytes(msg.data) == b"\x7f", "heartbeat is one byte, state 7Fh"
        stamps.append(time.monotonic())
    mean = (stamps[-1] - stamps[0]) / (len(stamps) - 1)
    assert 0.07 < mean < 0.15, f"mean heartbeat period {mean * 1000:.0f} ms, want 100 ms"
    # 0 switches the producer off
    node.sdo[0x1017].raw = 0
    recv_id(bus, 0x701, 0.2)  # one may have been in flight
    assert recv_id(bus, 0x701, 0.5) is None, "heartbeat still sent with 1017h = 0"


def test_nmt_state_changes_in_heartbeat(cmmp, node_of):
    node = node_of(cmmp)
    hb = HeartbeatLog(node)
    assert node.nmt.wait_for_heartbeat(timeout=3) == "PRE-OPERATIONAL"
    _fast_heartbeat(node)

    for command, state in [("OPERATIONAL", OPERATIONAL), ("STOPPED", STOPPED),
                           ("PRE-OPERATIONAL", PRE_OPERATIONAL), ("OPERATIONAL", OPERATIONAL),
                           ("PRE-OPERATIONAL", PRE_OPERATIONAL)]:
        mark = hb.mark()
        node.nmt.state = command
        _expect_state(hb, state, mark)
        assert node.nmt.wait_for_heartbeat(timeout=1) == command


def test_sdo_silent_in_stopped(cmmp, node_of):
    node = node_of(cmmp)
    hb = HeartbeatLog(node)
    _fast_heartbeat(node)
    node.nmt.state = "STOPPED"
    _expect_state(hb, STOPPED, hb.mark())
    node.sdo.RESPONSE_TIMEOUT = 0.3
    with pytest.raises(canopen.SdoCommunicationError):
        node.sdo[0x1018][1].raw
    # NMT still works in STOPPED and SDO comes back in PRE-OPERATIONAL
    mark = hb.mark()
    node.nmt.state = "PRE-OPERATIONAL"
    _expect_state(hb, PRE_OPERATIONAL, mark)
    assert node.sdo[0x1018][1].raw == 0x1D
    assert node.sdo[0x1017].raw == 100


def _reset_and_wait_bootup(node, command: str):
    """Send `command` a moment after wait_for_bootup() starts listening."""
    timer = threading.Timer(0.2, lambda: setattr(node.nmt, "state", command))
    timer.start()
    try:
        node.nmt.wait_for_bootup(timeout=3)
    finally:
        timer.join()


@pytest.mark.parametrize("command", ["RESET COMMUNICATION", "RESET"])
def test_reset_gives_bootup_then_pre_operational(cmmp, node_of, raw_bus, command):
    node = node_of(cmmp)
    hb = HeartbeatLog(node)
    _fast_heartbeat(node)
    node.nmt.state = "OPERATIONAL"
    _expect_state(hb, OPERATIONAL, hb.mark())

    bus = raw_bus(cmmp)
    mark = hb.mark()
    _reset_and_wait_bootup(node, command)
    # the boot-up message on the wire: 701h, one byte 00 (after the OPERATIONAL heartbeats
    # the raw bus had buffered)
    seen = []
    while True:
        msg = recv_id(bus, 0x701, 1.0)
        assert msg is not None, f"no boot-up frame among {seen}"
        seen.append(bytes(msg.data).hex())
        if bytes(msg.data) == b"\x00":
            break
    assert set(seen[:-1]) <= {"05"}, seen
    pos = hb.wait_for(BOOTUP, mark, timeout=1)
    assert OPERATIONAL not in [s for _, s in hb.states[pos:]]
    # the reset brought the communication parameters back to their power-on values:
    # 1017h = 1000 ms as commissioned, and the node is pre-operational
    assert node.sdo[0x1017].raw == 1000
    pos = hb.wait_for(PRE_OPERATIONAL, pos, timeout=2.5)
    assert hb.states[pos - 1][1] == PRE_OPERATIONAL


def test_reset_node_restores_application_values(bench, node_of):
    node = node_of(bench)
    node.sdo[0x2003].raw = 55
    node.sdo[0x2001].raw = "changed"
    _reset_and_wait_bootup(node, "RESET")
    assert node.sdo[0x2003].raw == 0
    assert node.sdo[0x2001].raw == "drivetwin"


def test_nmt_broadcast_and_other_node_ids(cmmp, raw_bus, node_of):
    node = node_of(cmmp)
    hb = HeartbeatLog(node)
    _fast_heartbeat(node)
    bus = raw_bus(cmmp)
    # a command for another node is ignored
    mark = hb.mark()
    bus.send(can.Message(arbitration_id=0x000, data=b"\x01\x02", is_extended_id=False))
    assert hb.next_states(mark, 3, timeout=1.5) == [PRE_OPERATIONAL] * 3
    # node 0 = all nodes
    mark = hb.mark()
    bus.send(can.Message(arbitration_id=0x000, data=b"\x01\x00", is_extended_id=False))
    _expect_state(hb, OPERATIONAL, mark)


def test_reset_communication_keeps_application_values(bench, node_of):
    node = node_of(bench)
    node.sdo[0x2003].raw = 55
    node.sdo[0x1017].raw = 300
    _reset_and_wait_bootup(node, "RESET COMMUNICATION")
    assert node.sdo[0x2003].raw == 55, "reset communication leaves the application area alone"
    assert node.sdo[0x1017].raw == 1000, "... and reloads the communication area"
