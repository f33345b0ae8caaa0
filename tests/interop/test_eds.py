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
