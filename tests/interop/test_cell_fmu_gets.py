"""A get call of many value references on the cell FMU (crates/cell-fmu/src/sys.rs: the
outputs' getters read all of a call's value references under one lock of the cell,
docs/performance.md "The displays on demand, one lock per get call"), met by fmpy's low-level
FMI 3 API: one call of every Float64, UInt16 and Int32 variable of the ten-drive cell gives
what a call per value gives, a call longer than the FMU's batch of 64 as well, `time` (value
reference 0) among them is the FMU's time, and a value reference of another type fails the
call."""

from __future__ import annotations

import subprocess

import pytest

from conftest import CELL_LIBRARY, DRIVETWIN_BIN, REPO_ROOT

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi3 import FMU3Slave  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402

CELL = REPO_ROOT / "examples" / "cell_fmu" / "ten_drives.toml"
STEP = 1e-3


@pytest.fixture(scope="module")
def stepped(tmp_path_factory, cell_library):
    """The ten-drive cell's FMU stepped 20 times, node1's load torque set, and its
    description."""
    out = tmp_path_factory.mktemp("cell_fmu_gets") / "cell.fmu"
    subprocess.run(
        [str(DRIVETWIN_BIN), "fmu", "--config", str(CELL), "--output", str(out),
         "--library", str(CELL_LIBRARY)],
        check=True, cwd=REPO_ROOT, timeout=60,
    )
    md = fmpy.read_model_description(str(out))
    slave = FMU3Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(out)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cell")
    slave.instantiate()
    slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    names = {v.name: v.valueReference for v in md.modelVariables}
    slave.setFloat64([names["node1.load_torque"]], [0.3])
    for k in range(20):
        slave.doStep(currentCommunicationPoint=k * STEP, communicationStepSize=STEP)
    yield slave, md
    slave.terminate()
    slave.freeInstance()


def of_type(md, kind: str) -> list[int]:
    return [v.valueReference for v in md.modelVariables if v.type == kind]


def test_one_call_of_every_value_gives_what_a_call_per_value_gives(stepped):
    slave, md = stepped
    floats = of_type(md, "Float64")
    # Outputs, the load torques (inputs) and the motors' parameters.
    assert len(floats) > 40
    one = [slave.getFloat64([vr])[0] for vr in floats]
    assert slave.getFloat64(floats) == one
    names = {v.name: v.valueReference for v in md.modelVariables}
    assert one[floats.index(names["node1.load_torque"])] == 0.3
    assert len(set(one)) > 3, one
    # Longer than one batch: each batch reads its own value references, in the call's order.
    many = list(reversed(floats)) * 3
    assert len(many) > 64 * 2
    assert slave.getFloat64(many) == list(reversed(one)) * 3
    for get, kind in ((slave.getUInt16, "UInt16"), (slave.getInt32, "Int32")):
        vrs = of_type(md, kind)
        assert len(vrs) == 10
        assert get(vrs) == [get([vr])[0] for vr in vrs]


def test_time_among_the_value_references_is_the_fmus_time(stepped):
    slave, md = stepped
    floats = [v.valueReference for v in md.modelVariables
              if v.type == "Float64" and v.causality == "output"]
    values = slave.getFloat64([0, *floats])
    assert values[0] == pytest.approx(20 * STEP, abs=1e-12)
    assert values[1:] == slave.getFloat64(floats)


def test_a_value_reference_of_another_type_fails_the_call(stepped):
    slave, md = stepped
    position = next(v.valueReference for v in md.modelVariables if v.name == "node1.position")
    statusword = next(v.valueReference for v in md.modelVariables
                      if v.name == "node1.statusword")
    with pytest.raises(FMICallException):
        slave.getFloat64([position, statusword])
    with pytest.raises(FMICallException):
        slave.getUInt16([statusword, position])
