"""11. Several drives on one bus, described by a cell file (--config)."""

import can
import pytest

from conftest import add_node, HeartbeatLog, wait_until, write_cell


@pytest.fixture
def two_drives(launch, tmp_path):
    cfg = write_cell(tmp_path / "cell.toml", [("cmmp-as", 1, {"1017:00": 1000}),
                                              ("testbench", 2, {"1017:00": 1000})])
    twin = launch(config=cfg)
    assert any("cmmp-as" in line and "node 1" in line for line in twin.stdout_lines), twin.stdout_lines
    assert any("testbench" in line and "node 2" in line for line in twin.stdout_lines), twin.stdout_lines
    return twin


def test_cell_both_drives_answer_sdo(two_drives, connect, eds_files):
    net = connect(two_drives)
    cmmp = add_node(net, 1, eds_files["cmmp-as"])
    bench = add_node(net, 2, eds_files["testbench"])
    assert cmmp.sdo[0x1018][1].raw == 0x1D
    assert bench.sdo[0x1018][1].raw == 0x0
    assert bench.sdo[0x2005].raw == 42
    assert cmmp.sdo[0x1017].raw == 1000 and bench.sdo[0x1017].raw == 1000, "commissioned"
    # each drive has its own dictionary
    bench.sdo[0x2001].raw = "node two"
    assert bench.sdo[0x2001].raw == "node two"
    import canopen
    with pytest.raises(canopen.SdoAbortedError) as e:
        cmmp.sdo.upload(0x2001, 0)
    assert e.value.code in (0x06020000, 0x06090011, 0x06010001)
    # a node that is not in the cell does not answer
    ghost = add_node(net, 3, eds_files["testbench"])
    ghost.sdo.RESPONSE_TIMEOUT = 0.2
    with pytest.raises(canopen.SdoCommunicationError):
        ghost.sdo[0x1018][1].raw


def test_cell_nmt_broadcast_starts_both(two_drives, connect, eds_files, raw_bus):
    net = connect(two_drives)
    nodes = [add_node(net, 1, eds_files["cmmp-as"]), add_node(net, 2, eds_files["testbench"])]
    logs = [HeartbeatLog(n) for n in nodes]
    for n in nodes:
        n.sdo[0x1017].raw = 100
    for log in logs:
        assert set(log.next_states(log.mark(), 2, timeout=1.5)) == {0x7F}
    bus = raw_bus(two_drives)
    marks = [log.mark() for log in logs]
    bus.send(can.Message(arbitration_id=0x000, data=b"\x01\x00", is_extended_id=False))
    for log, mark in zip(logs, marks):
        pos = log.wait_for(0x05, mark, timeout=1.5)
        assert log.next_states(pos, 2, timeout=1.5) == [0x05, 0x05]
    # a node-specific stop reaches node 2 only
    marks = [log.mark() for log in logs]
    bus.send(can.Message(arbitration_id=0x000, data=b"\x02\x02", is_extended_id=False))
    pos = logs[1].wait_for(0x04, marks[1], timeout=1.5)
    assert logs[0].next_states(marks[0], 3, timeout=1.5) == [0x05] * 3
    # NMT master's broadcast helper: pre-operational for all
    marks = [log.mark() for log in logs]
    net.nmt.state = "PRE-OPERATIONAL"
    for log, mark in zip(logs, marks):
        log.wait_for(0x7F, mark, timeout=1.5)


def test_cell_heartbeat_consumer_sees_a_silent_producer(launch, tmp_path, connect, eds_files):
    """Node 2 (testbench) watches node 1's heartbeat (1016h:01 = node 1, 300 ms). When node 1 falls
    silent, node 2 flags a communication error in 1001h (its 8130h EMCY is not sent: the test
    bench has no 1014h); when node 1 beats again, the error goes away."""
    cfg = write_cell(tmp_path / "cell.toml", [("cmmp-as", 1, {"1017:00": 100}),
                                              ("testbench", 2, {"1017:00": 1000,
                                                                "1016:01": 0x0001012C})])
    twin = launch(config=cfg)
    net = connect(twin)
    node1 = add_node(net, 1, eds_files["cmmp-as"])
    node2 = add_node(net, 2, eds_files["testbench"])
    assert node2.sdo[0x1016][1].raw == 0x0001012C
    hb1 = HeartbeatLog(node1)
    hb1.next_states(0, 2, timeout=1.5)  # node 1 is beating, node 2 is watching
    assert node2.sdo[0x1001].raw == 0, "no error while node 1 beats"
    node1.sdo[0x1017].raw = 0
    wait_until(lambda: node2.sdo[0x1001].raw & 0x10, timeout=2.0,
               what="communication error bit in node 2's 1001h")
    node1.sdo[0x1017].raw = 100
    wait_until(lambda: node2.sdo[0x1001].raw == 0, timeout=2.0,
               what="node 2's 1001h to clear after node 1 resumed")
