"""1. EDS export: read by python-canopen's importer and linted by Lely's dcfchk."""

import shutil
import subprocess

import canopen
import pytest
from canopen.objectdictionary import datatypes

from conftest import run_cli


def test_eds_cmmp_as_imports_into_python_canopen(eds_files):
    od = canopen.import_od(str(eds_files["cmmp-as"]), node_id=1)
    assert od[0x1018][1].default == 0x1D, "vendor-ID of Festo"
    assert od[0x1800][1].default == 0xC0000181, "TPDO1 COB-ID $NODEID+0xC0000180 for node 1"
    assert od[0x1017].data_type == datatypes.UNSIGNED16
    assert od[0x6041].access_type == "ro"
    assert len(od) > 100, f"only {len(od)} objects"
    # $NODEID is resolved with the node-ID the importer is given
    od5 = canopen.import_od(str(eds_files["cmmp-as"]), node_id=5)
    assert od5[0x1800][1].default == 0xC0000185


def test_eds_testbench_imports_into_python_canopen(eds_files):
    od = canopen.import_od(str(eds_files["testbench"]), node_id=1)
    assert od[0x2000].data_type == datatypes.DOMAIN
    assert od[0x2001].data_type == datatypes.VISIBLE_STRING
    assert od[0x2001].default == "drivetwin"
    assert od[0x2002].access_type == "wo"
    assert od[0x2003].min == -100 and od[0x2003].max == 100
    assert od[0x2005].access_type == "ro" and od[0x2005].default == 42
    assert len(od[0x2004]) >= 12
    assert len(od[0x1016]) >= 4


@pytest.mark.parametrize("device", ["nanotec-smci47s", "nanotec-pd4n"])
def test_eds_nanotec_imports_into_python_canopen(device, eds_files):
    """The Nanotec files as the manual lists them (its text kept beside the project,
    seeds/003_ef071fe40f10c01c.txt)."""
    od = canopen.import_od(str(eds_files[device]), node_id=34)
    assert od[0x1000].default == 0x00000008, "1000h: stepper motor (§9.6)"
    assert od[0x1800][1].default == 0x180 + 34, "TPDO1 follows $NODEID"
    assert od[0x1800][3].default == 1000, "100 ms inhibit time (§9.18)"
    assert od[0x1A00][1].default == 0x60410010, "statusword in TPDO1"
    assert od[0x1600][1].default == 0x60400010, "controlword in RPDO1"
    assert od[0x6502].default == 0x6B, "PP, VL, TQ, HM, IP (§9.43)"
    assert od[0x6098].data_type == datatypes.INTEGER8
    # Nanotec's string layout (§11.20): sub 0 the length, one character per sub-index.
    text = "".join(chr(od[0x100A][i].default) for i in range(1, od[0x100A][0].default + 1))
    assert text == "24-10-2011"
    # Dummies 0002h-0007h from [DummyUsage]; 0001h is not mappable, so not announced.
    assert all(i in od for i in range(0x0002, 0x0008)) and 0x0001 not in od
    assert 0x1008 not in od, "the manual lists no 1008h"
    has_brake = 0x2007 in od
    assert has_brake == (device == "nanotec-smci47s")
    assert (0x6401 in od) == has_brake, "analog input on the SMCI47-S only"
    assert (0x200E in od) != has_brake, "DSPdrive current controller on the PD4-N only"


@pytest.mark.parametrize("device", ["kinco-fd3", "kinco-cd3"])
def test_eds_kinco_imports_into_python_canopen(device, eds_files):
    """The Kinco files as the manual's parameter tables list them (its text kept beside the
    project, seeds/001_da459f46c7138f7b.txt)."""
    od = canopen.import_od(str(eds_files[device]), node_id=3)
    assert od[0x1000].default == 0x00020192, "CiA 402 servo drive (CHOSEN)"
    assert od[0x100B].default == 1, "ID_Com d5.01"
    assert od[0x6040].data_type == datatypes.UNSIGNED16
    assert od[0x6060].data_type == datatypes.INTEGER8
    assert od[0x607A].data_type == datatypes.INTEGER32
    assert od[0x6041].access_type == "ro"
    assert od[0x2010][3].default == 0x0001, "DIN1 = Enable (d3.01)"
    assert od[0x2010][0x0F].default == 0x0001, "OUT1 = Ready (d3.09)"
    assert od[0x2020][0x0D].default == -4 and od[0x2020][0x0E].default == -3, "Din_Mode0/1"
    assert od[0x2020][0x0F].default == 0x2F, "Din_Controlword (KINCO-CW-06)"
    assert od[0x2FF0][0x0E].default == 5242 and od[0x6065].default == 524200, "KINCO-SC-09"
    assert od[0x60F9][0x03].default == 45 and od[0x60F9][0x03].max == 127, "Notch_N (KINCO-SC-06)"
    assert od[0x3040][0x0B].min == 10 and od[0x3040][0x0B].max == 500, "Inertia_Ratio"
    assert od[0x2FE0].default == 270 and od[0x2FE2].default == 540, "baud codes (KINCO-232-10)"
    assert len(od[0x2509]) >= 15, "gear sets 1-7"
    has_can = 0x1400 in od
    assert has_can == (device == "kinco-fd3"), "CANopen on the FD3 only"
    assert (0x2F81 in od) == has_can and (0x2F80 in od) == has_can
    if has_can:
        assert od[0x1800][1].default == 0x180 + 3, "TPDO1 follows $NODEID (KINCO-CAN-05)"
        assert od[0x1014].default == 0x80 + 3
        assert od[0x1A00][1].default == 0x60410010 and od[0x1600][1].default == 0x60400010
        assert od[0x2F81].default == 50, "500 kbit/s (KINCO-CAN-06)"


def test_eds_output_option_writes_same_text(tmp_path, eds_files):
    out = tmp_path / "cmmp.eds"
    r = run_cli("eds", "--device", "cmmp-as", "-o", str(out))
    assert r.returncode == 0, r.stderr
    assert out.read_text() == eds_files["cmmp-as"].read_text()


@pytest.mark.parametrize(
    "device",
    [
        "cmmp-as",
        "testbench",
        "nanotec-smci47s",
        "nanotec-pd4n",
        "kinco-fd3",
        "kinco-cd3",
    ],
)
def test_eds_passes_dcfchk(device, eds_files):
    dcfchk = shutil.which("dcfchk")
    if dcfchk is None:
        pytest.skip("dcfchk (pip install dcf-tools) is not on PATH")
    r = subprocess.run([dcfchk, "-n", "1", str(eds_files[device])], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, f"dcfchk exit {r.returncode}: {r.stdout}{r.stderr}"
    assert "Warning" not in r.stderr, r.stderr
