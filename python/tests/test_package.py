"""The package's own tests (cell files, addresses, the client's errors); scripts/wheel runs
them in the fresh venv beside the example suite."""

import os
import sysconfig
from pathlib import Path

import pytest

import drivetwin
from drivetwin import cellfile


def test_cell_files_written_read_back_equal():
    doc = {
        "bus": [{"name": "line-a", "socketcand": "127.0.0.1:0", "bitrate": "instant",
                 "disturb": [{"at_ms": 1500, "node": 3, "frames": 32}]}],
        "drive": [{"device": "cmmp-as", "node": 1, "interfaces": ["canopen", "ci-terminal"],
                   "objects": {"1017:00": 1000, "6510:F0": 0x80},
                   "axis": {"end_stops": [-3.0, 47.0], "index_pulse": "none"},
                   "travel": {"negative_limit": -1310720}, "allow_unreal_interfaces": False,
                   "note": 'a "quoted"\tline\n'}],
    }
    assert cellfile.loads(cellfile.dumps(doc)) == doc


def test_devices_get_nodes_heartbeats_and_free_ports(tmp_path):
    doc = cellfile.from_devices(["cmmp-as", {"device": "kinco-fd3", "rs232": True}, "cmmo-st",
                                 {"device": "nanotec-pd4n", "node": 2}],
                                bitrate=None, channel="vcan0", serial_dir=tmp_path)
    cmmp, kinco, cmmo, nanotec = doc["drive"]
    assert (cmmp["node"], kinco["node"], nanotec["node"]) == (1, 3, 2)
    assert cmmp["objects"] == {"1017:00": 1000, "6510:F0": 0x80}
    assert kinco["objects"] == {"1017:00": 1000}
    assert kinco["rs232"] == str(tmp_path / "drive2-rs232")
    assert cmmo == {"device": "cmmo-st", "modbus": "127.0.0.1:0"}
    assert doc["bus"] == [{"socketcand": "127.0.0.1:0", "channel": "vcan0"}]


def test_a_users_cell_file_moves_to_free_ports(tmp_path):
    doc = cellfile.loads("""
[bus]
socketcand = "127.0.0.1:29536"
[[drive]]
device = "cmmp-as"
eds = "my.eds"
ci_terminal = "127.0.0.1:29540"
[[drive]]
device = "cmmo-st"
modbus = "127.0.0.1:1502"
""")
    out = cellfile.to_free_ports(doc, tmp_path / "serial", base_dir=tmp_path)
    assert out["bus"] == [{"socketcand": "127.0.0.1:0"}]
    assert out["drive"][0]["ci_terminal"] == "127.0.0.1:0"
    assert out["drive"][0]["eds"] == str((tmp_path / "my.eds").resolve())
    assert out["drive"][1]["modbus"] == "127.0.0.1:0"


def test_the_wheels_binary_is_found_and_names_its_device_files():
    if "DRIVETWIN_BIN" not in os.environ:  # the wheel's, beside this interpreter
        assert drivetwin.find_binary().parent == Path(sysconfig.get_path("scripts"))
    text = drivetwin.binary_version()
    assert text.startswith("drivetwin ")
    assert "cmmp-as" in text and "cmmo-st" in text and "kinco-fd3" in text


def test_a_cell_gives_every_address(tmp_path):
    devices = ["cmmp-as", {"device": "kinco-fd3", "rs232": True, "ci_terminal": False},
               "cmmo-st", {"device": "cmmp-as", "ci_terminal": True}]
    with drivetwin.Cell(devices=devices, bitrate="instant") as cell:
        assert len(cell.buses) == 1 and cell.bus.channel == "vcan0"
        assert len(cell.modbus) == 1 and cell.modbus[0].port > 0
        assert [s.kind for s in cell.serial] == ["rs232"]
        assert Path(cell.serial[0].path).resolve() == Path(cell.serial[0].pty)
        assert list(cell.ci_terminals) == [4]
        assert cell.http.startswith("http://127.0.0.1:")
        assert [d.device for d in cell.api.drives()] == ["cmmp-as", "kinco-fd3", "cmmp-as",
                                                         "cmmo-st"]


def test_a_cell_without_console():
    with drivetwin.Cell(http=False) as cell:
        assert cell.http is None
        with pytest.raises(LookupError):
            cell.api


def test_a_cell_that_dies_is_reported():
    cell = drivetwin.Cell()
    cell.start()
    os.kill(cell.pid, 9)
    with pytest.raises(drivetwin.CellDied) as e:
        cell.stop()
    assert e.value.returncode == -9
    cell.close()


def test_refusals_are_conflicts_with_the_abort_code(drivetwin_cell):
    with pytest.raises(drivetwin.ApiError) as e:
        drivetwin_cell.api.write(0, 0x1018, 1, 5)  # vendor-ID: read only
    assert e.value.status in (400, 409) and e.value.abort_code is not None


def test_a_cell_stopped_as_soon_as_it_runs_stops_cleanly():
    # SIGTERM right after "running; Ctrl-C stops": the binary listens before it says so.
    for _ in range(10):
        with drivetwin.Cell(http=False) as cell:
            assert cell.running
