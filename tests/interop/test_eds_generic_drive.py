"""A CiA 402 drive nobody here wrote, from its EDS: `drivetwin run --eds FILE --node N` (and
`eds = "…"` on a `[[drive]]` of a cell file) driven by python-canopen's BaseNode402 with the same
EDS, as its documentation sets up a drive: the PDOs the file maps read from the drive, the
TPDOs made synchronous with a 10 ms SYNC (BaseNode402 waits for a TPDO after each command),
NMT Operational, the state machine to OPERATION ENABLED, a Profile Position move, a Profile
Velocity run and homing method 35 (CiA 402 §8.4: the actual position is the home position).

The files in data/eds/ are written after other vendors' public object lists, each naming whose
drive it follows in its header: `epos4_like.eds` after the maxon EPOS4 Firmware Specification,
`lexium32_like.eds` after the Schneider Lexium 32 fieldbus manual. A damaged file is refused
with its file, line, section and key."""

from __future__ import annotations

from pathlib import Path

import pytest
from canopen.profiles.p402 import BaseNode402

from conftest import CHANNEL, SDO_TIMEOUT, run_cli, wait_until

EDS_DIR = Path(__file__).parent / "data" / "eds"
REV = 65536  # the default servo motor's encoder increments per revolution
SYNC_PERIOD = 0.01

# (file, node-ID, whose drive it follows)
DRIVES = [
    ("epos4_like.eds", 3, "maxon EPOS4"),
    ("lexium32_like.eds", 5, "Schneider Lexium 32"),
]


@pytest.fixture(params=DRIVES, ids=[d[2] for d in DRIVES])
def drive(request, launch, connect):
    eds, node_id, _ = request.param
    path = EDS_DIR / eds
    twin = launch(node=node_id, extra=("--eds", str(path)))
    assert any(l.startswith(f"drive {path.stem.replace('_', '-')} node {node_id}")
               for l in twin.stdout_lines), twin.stdout_lines
    net = connect(twin)
    node = BaseNode402(node_id, str(path))
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    node.nmt.wait_for_heartbeat(3)
    node.setup_402_state_machine()
    # The file's TPDOs (statusword, mode, position, velocity) sent on every SYNC.
    for pdo in node.tpdo.values():
        if pdo.enabled:
            pdo.trans_type = 1
            pdo.save()
    net.sync.start(SYNC_PERIOD)
    node.nmt.state = "OPERATIONAL"
    yield node
    net.sync.stop()


def move_to(node, target: int) -> None:
    node.sdo[0x607A].raw = target
    node.controlword = 0x1F  # new set-point
    wait_until(lambda: node.statusword & 0x1000, 1.0, what="set-point acknowledge")
    node.controlword = 0x0F
    window = node.sdo[0x6067].raw
    wait_until(lambda: node.statusword & 0x0400 and abs(node.sdo[0x6064].raw - target) <= window,
               5.0, what=f"target {target} reached")


def test_enable_and_disable(drive):
    drive.state = "OPERATION ENABLED"
    assert drive.state == "OPERATION ENABLED"
    assert drive.sdo[0x6041].raw & 0x6F == 0x27
    drive.state = "SWITCH ON DISABLED"
    assert drive.sdo[0x6041].raw & 0x4F == 0x40


def test_profile_position_move(drive):
    drive.op_mode = "PROFILED POSITION"
    drive.sdo[0x6081].raw = 600
    drive.sdo[0x6083].raw = 6000
    drive.sdo[0x6084].raw = 6000
    drive.state = "OPERATION ENABLED"
    start = drive.sdo[0x6064].raw
    move_to(drive, start + 2 * REV)
    move_to(drive, start - REV)
    assert drive.op_mode == "PROFILED POSITION"


def test_profile_velocity_run(drive):
    # CiA 402 makes 6080h max_motor_speed optional: a file without it runs uncapped.
    drive.op_mode = "PROFILED VELOCITY"
    drive.sdo[0x6083].raw = 6000
    drive.sdo[0x6084].raw = 6000
    drive.state = "OPERATION ENABLED"
    drive.sdo[0x60FF].raw = 300
    wait_until(lambda: abs(drive.sdo[0x606C].raw - 300) <= 15, 3.0, what="300 min⁻¹")
    assert drive.statusword & 0x1000 == 0, "speed is not 0"
    drive.sdo[0x60FF].raw = 0
    wait_until(lambda: abs(drive.sdo[0x606C].raw) <= 5, 3.0, what="standstill")
    drive.state = "SWITCH ON DISABLED"


def test_homing_method_35(drive):
    # Somewhere else first, so that homing has a position to change.
    drive.op_mode = "PROFILED POSITION"
    drive.sdo[0x6081].raw = 600
    drive.state = "OPERATION ENABLED"
    move_to(drive, drive.sdo[0x6064].raw + REV)
    offset = 0
    if 0x607C in drive.object_dictionary:
        offset = 1000
        drive.sdo[0x607C].raw = offset
    drive.sdo[0x6098].raw = 35
    assert drive.homing(timeout=5), "method 35"
    sw = drive.sdo[0x6041].raw
    assert sw & 0x3400 == 0x1400, f"homing attained, target reached, no error: {sw:04X}"
    assert abs(drive.sdo[0x6064].raw - offset) <= 2


def test_modes_the_file_and_the_engine_allow(launch, connect):
    """6060h takes the modes of 6502h the engine runs (the EPOS4's CSV is refused); 6098h
    the homing methods the file and the engine share."""
    import canopen

    path = EDS_DIR / "epos4_like.eds"
    twin = launch(node=3, extra=("--eds", str(path)))
    node = connect(twin).add_node(3, str(path))
    node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    assert node.sdo[0x6502].raw == 0x3A5
    node.sdo[0x6060].raw = 3
    with pytest.raises(canopen.SdoAbortedError) as e:
        node.sdo[0x6060].raw = 9
    assert e.value.code == 0x06090030
    with pytest.raises(canopen.SdoAbortedError):
        node.sdo[0x6098].raw = -4
    assert node.sdo[0x1018][1].raw == 0xFB
    assert node.sdo[0x1800][1].raw == 0x40000183, "$NODEID+0x40000180"


def test_eds_on_a_drive_of_a_cell_file(tmp_path, launch, connect):
    """`eds = "…"` on a `[[drive]]`, relative to the cell file, beside a built-in device."""
    (tmp_path / "drives").mkdir()
    eds = tmp_path / "drives" / "lexium32_like.eds"
    eds.write_bytes((EDS_DIR / "lexium32_like.eds").read_bytes())
    cell = tmp_path / "cell.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
        "[[drive]]", 'eds = "drives/lexium32_like.eds"', "node = 5",
        "[drive.objects]", '"1017:00" = 100', "",
        "[[drive]]", 'device = "cmmp-as"', "node = 1", "",
    ]))
    twin = launch(config=cell)
    net = connect(twin)
    node = net.add_node(5, str(eds))
    node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    assert node.sdo[0x1018][1].raw == 0x0800005A
    assert node.sdo[0x1017].raw == 100
    assert node.sdo[0x60E3][31].raw == 35
    assert net.add_node(1).sdo.upload(0x1018, 1)[:1] == b"\x1d"  # the CMMP-AS beside it: Festo


def _damaged(tmp_path: Path, name: str) -> tuple[Path, int]:
    """epos4_like.eds with 6081h's DataType made an unknown code; the path and that line."""
    lines = (EDS_DIR / "epos4_like.eds").read_text().splitlines()
    at = lines.index("[6081]")
    line = next(i for i in range(at, len(lines)) if lines[i].startswith("DataType=")) + 1
    lines[line - 1] = "DataType=0x0042"
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path, line


def test_a_broken_eds_is_refused_with_its_line(tmp_path):
    path, line = _damaged(tmp_path, "broken.eds")
    r = run_cli("run", "--eds", str(path), "--virtual-seconds", "0.1")
    assert r.returncode != 0, r.stdout
    assert f"{path}:{line}: [6081] DataType: 0x0042 is no CiA 301 data type" in r.stderr, r.stderr
    assert "panicked" not in r.stderr


def test_a_broken_eds_in_a_cell_file_is_refused_with_its_line(tmp_path):
    path, line = _damaged(tmp_path, "broken.eds")
    cell = tmp_path / "cell.toml"
    cell.write_text('[[drive]]\neds = "broken.eds"\nnode = 3\n')
    r = run_cli("run", "--config", str(cell), "--virtual-seconds", "0.1")
    assert r.returncode != 0, r.stdout
    assert f"{path}:{line}: [6081] DataType:" in r.stderr, r.stderr
    # Not a drive: the device type names another profile.
    other = tmp_path / "io.eds"
    text = (EDS_DIR / "epos4_like.eds").read_text()
    other.write_text(text.replace("DefaultValue=0x00020192", "DefaultValue=0x00000191"))
    r = run_cli("run", "--eds", str(other), "--virtual-seconds", "0.1")
    assert r.returncode != 0
    assert "[1000] DefaultValue: the device type 1000h does not name CiA 402" in r.stderr, r.stderr


@pytest.mark.parametrize("eds,node_id", [("epos4_like.eds", 3), ("lexium32_like.eds", 5)],
                         ids=["maxon EPOS4", "Schneider Lexium 32"])
def test_dummy_mapping_follows_dummy_usage(eds, node_id, launch, connect):
    """CiA 306 [DummyUsage]: the EPOS4-like file allows the dummies 0002h-0007h, not 0001h;
    the Lexium-like file none. python-canopen maps an allowed dummy into RPDO1 with its own
    PdoMap (the dummies it read from the same section); a dummy the file does not allow is
    refused with 0604 0041h (CiA 301: object cannot be mapped to the PDO)."""
    import canopen

    path = EDS_DIR / eds
    twin = launch(node=node_id, extra=("--eds", str(path)))
    net = connect(twin)
    node = net.add_node(node_id, str(path))
    node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    node.rpdo.read()
    rpdo = node.rpdo[1]
    allowed = 0x0002 in node.object_dictionary
    assert allowed == (eds == "epos4_like.eds")
    if allowed:
        rpdo.clear()
        rpdo.add_variable(0x0002)  # INTEGER8: one byte skipped
        rpdo.add_variable(0x6040)
        rpdo.save()
        assert node.sdo[0x1600][1].raw == 0x00020008
        assert node.sdo[0x1600][2].raw == 0x60400010
    # Not allowed: 0001h in the EPOS4-like file, every dummy in the Lexium-like one.
    refused = 0x00010008 if allowed else 0x00020008
    node.sdo[0x1400][1].raw = node.sdo[0x1400][1].raw | 0x80000000
    node.sdo[0x1600][0].raw = 0
    with pytest.raises(canopen.SdoAbortedError) as e:
        node.sdo[0x1600][1].raw = refused
    assert e.value.code == 0x06040041
