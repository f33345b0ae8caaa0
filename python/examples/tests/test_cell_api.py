"""The cell as a context manager and its REST client, without the fixtures."""

import canopen
import pytest

import drivetwin


def test_a_cell_file_as_text_runs_on_free_ports():
    config = """
[[bus]]
channel = "line-a"
socketcand = "127.0.0.1:29536"   # moved to a free port by drivetwin.Cell

[[drive]]
device = "nanotec-smci47s"
node = 34
"""
    with drivetwin.Cell(config=config) as cell:
        assert cell.bus.channel == "line-a" and cell.bus.port != 29536
        net = canopen.Network()
        net.connect(**cell.bus.can_kwargs())
        try:
            node = net.add_node(34)
            vendor = node.sdo.upload(0x1018, 1)  # over the bus, by SDO
        finally:
            net.disconnect()
        assert vendor == cell.api.read(0, 0x1018, 1).bytes  # the same entry over REST
        drive = cell.api.drive(0)
        assert (drive.device, drive.node) == ("nanotec-smci47s", 34)


def test_errors_carry_the_api_message_and_the_abort_code(drivetwin_cell):
    with pytest.raises(drivetwin.NotFound) as e:
        drivetwin_cell.api.read(0, 0x1234, 0)
    assert e.value.abort_code == "0x06020000"
    written = drivetwin_cell.api.write(0, 0x6081, 0, 1500)
    assert written.number == 1500


def test_wire_faults_and_traces(drivetwin_cell):
    api = drivetwin_cell.api
    fault = api.add_fault("drop", node=1, frames=3)
    assert [f.id for f in api.faults()] == [fault.id]
    assert api.clear_faults() == []
    trace = api.start_trace(0, name=f"example-{drivetwin_cell.pid}.pcap")
    api.stop_trace(0)
    with open(trace.path, "rb") as f:
        assert f.read(4) == bytes.fromhex("d4c3b2a1")  # pcap, little-endian


def test_a_scenario_on_the_live_cell(drivetwin_cell):
    report = drivetwin_cell.api.run_scenario("""
name = "heartbeat"
[[step]]
at = "0s"
name = "node 1 beats"
expect_frame = "701"
within = "1500ms"
""")
    assert report.passed, report
    assert [o.name for o in report.expectations] == ["node 1 beats"]


def test_a_dead_cell_says_why(tmp_path):
    cell = drivetwin.Cell(devices=["no-such-device"])
    with pytest.raises(drivetwin.CellStartError) as e:
        cell.__enter__()
    assert "no-such-device" in str(e.value)
