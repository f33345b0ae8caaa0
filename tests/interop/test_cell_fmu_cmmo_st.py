"""A CMMO-ST (FHPP over Modbus, no CANopen) in a cell FMU (`drivetwin fmu`,
docs/cosimulation.md), met by fmpy: its variables are named by its place among the cell
file's drives (`driveK`: it has no CANopen node), and are the CANopen drives' with FHPP's
status bytes in place of the statusword (`driveK.scon`, `driveK.spos`, UInt8, CMMO-ST manual
§5.4.2 Tab. 5.21 / 5.22) and its reference switch in place of the 16 digital inputs; the timeline's
Modbus request enables it (SCON.ENABLED and OPEN), and a load torque set by the importer turns
its shaft while the output stage is off."""

from __future__ import annotations

import subprocess

import pytest

from conftest import DRIVETWIN_BIN, HOST, REPO_ROOT, free_port

fmpy = pytest.importorskip("fmpy")
from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

PREFIX = "drive0."  # the cell file's first [[drive]]
SCON_ENABLED, SCON_OPEN, SCON_VLOAD = 0x01, 0x02, 0x10  # Tab. 5.21
SPOS_HALT = 0x01  # Tab. 5.22

CELL = """\
[[bus]]
socketcand = ""

[[drive]]
device = "cmmo-st"
modbus = "{modbus}"
"""

# FC 10h to start address 0, 4 registers: CCON = 03h (ENABLE, STOP), CPOS = 01h (HALT not
# active), the rest 0 (§4.3, Tab. 5.11).
TIMELINE = """\
name = "cmmo-st enabled at 300 ms"
cell = "cell.toml"

[[step]]
at = "300ms"
modbus_request = "0001 0000 000F 01 10 0000 0004 08 03 01 00 00 00 00 00 00"
"""


@pytest.fixture(scope="module")
def cell_fmu(tmp_path_factory, cell_library):
    d = tmp_path_factory.mktemp("cell_fmu_cmmo_st")
    # Its Modbus TCP server opens with the FMU: a free port, not the default 1502.
    (d / "cell.toml").write_text(CELL.format(modbus=f"{HOST}:{free_port()}"))
    (d / "start.toml").write_text(TIMELINE)
    out = d / "cell.fmu"
    subprocess.run(
        [str(DRIVETWIN_BIN), "fmu", "--config", str(d / "cell.toml"), "--scenario",
         str(d / "start.toml"), "--output", str(out), "--library", str(cell_library)],
        check=True, cwd=REPO_ROOT, timeout=60,
    )
    return str(out)


def test_the_cmmo_st_has_its_status_bytes_and_reference_switch(cell_fmu):
    assert validate_fmu(cell_fmu) == []
    md = read_model_description(cell_fmu)
    v = {x.name: x for x in md.modelVariables}
    p = PREFIX
    assert (v[p + "load_torque"].causality, v[p + "load_torque"].type) == ("input", "Float64")
    assert (v[p + "reference_switch"].causality, v[p + "reference_switch"].type) == ("input", "Boolean")
    for name, kind in [("position", "Float64"), ("velocity", "Float64"), ("current", "Float64"),
                       ("scon", "UInt8"), ("spos", "UInt8"), ("position_actual", "Int32"),
                       ("display", "String")]:
        assert (v[p + name].causality, v[p + name].type) == ("output", kind), name
    assert p + "statusword" not in v and p + "din0" not in v
    outputs = {u.variable.name for u in md.outputs}
    assert {p + "scon", p + "spos", p + "position"} <= outputs


def test_a_load_torque_turns_the_free_shaft_and_the_timeline_enables_the_drive(cell_fmu):
    md = read_model_description(cell_fmu)
    vr = {x.name: x.valueReference for x in md.modelVariables}
    p = PREFIX
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=extract(cell_fmu),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cmmo")
    fmu.instantiate()
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()

    def status():
        return fmu.getUInt8([vr[p + "scon"], vr[p + "spos"]])

    scon, _ = status()
    assert scon & SCON_VLOAD and not scon & SCON_ENABLED, hex(scon)
    t, h = 0.0, 1e-3
    # The load's torque acts towards negative rotation; 20 ms of it, 20 ms against it.
    fmu.setFloat64([vr[p + "load_torque"]], [0.1])
    for _ in range(20):
        fmu.doStep(t, h)
        t += h
    angle, speed = fmu.getFloat64([vr[p + "position"], vr[p + "velocity"]])
    assert angle < -0.05 and speed < 0.0, (angle, speed)
    fmu.setFloat64([vr[p + "load_torque"]], [-0.1])
    for _ in range(20):
        fmu.doStep(t, h)
        t += h
    fmu.setFloat64([vr[p + "load_torque"]], [0.0])
    for _ in range(300):
        fmu.doStep(t, h)
        t += h
    scon, spos = status()
    assert scon & SCON_ENABLED and scon & SCON_OPEN, hex(scon)
    assert spos & SPOS_HALT, hex(spos)
    # The display's text is the FMU's own until its next fmi3GetString (FMI 3.0 §2.2.6.2):
    # fmpy decodes it after the call returns, and reads the same text twice.
    shown = fmu.getString([vr[p + "display"]])
    assert len(shown) == 1 and isinstance(shown[0], str), shown
    assert fmu.getString([vr[p + "display"]]) == shown
    fmu.terminate()
    fmu.freeInstance()


def pack(tmp_path, library, name: str, stepper: str = "") -> str:
    """A cell FMU of one CMMO-ST (no timeline) with `stepper` as its `[drive.stepper]` keys."""
    cell = tmp_path / f"{name}.toml"
    cell.write_text(CELL.format(modbus=f"{HOST}:{free_port()}")
                    + (f"[drive.stepper]\n{stepper}" if stepper else ""))
    out = tmp_path / f"{name}.fmu"
    subprocess.run(
        [str(DRIVETWIN_BIN), "fmu", "--config", str(cell), "--output", str(out),
         "--library", str(library)],
        check=True, cwd=REPO_ROOT, timeout=60,
    )
    return str(out)


def free_turn(fmu_path: str, start: dict[str, float]) -> list[tuple[float, float]]:
    """The shaft's angle and speed at every 1 ms step of 60 ms, the free shaft turned by a
    load torque of 0.1 N·m, with the parameters `start` set before initialisation."""
    md = read_model_description(fmu_path)
    vr = {x.name: x.valueReference for x in md.modelVariables}
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=extract(fmu_path),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="stepper")
    fmu.instantiate()
    for name, value in start.items():
        fmu.setFloat64([vr[name]], [value])
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    fmu.setFloat64([vr[PREFIX + "load_torque"]], [0.1])
    seen = []
    for k in range(60):
        fmu.doStep(k * 1e-3, 1e-3)
        seen.append(tuple(fmu.getFloat64([vr[PREFIX + "position"], vr[PREFIX + "velocity"]])))
    fmu.terminate()
    fmu.freeInstance()
    return seen


def test_a_stepper_parameter_set_before_initialisation_is_the_cell_files_key(tmp_path, cell_library):
    """`drive0.stepper.load_inertia` (kg·m², fixed, its start the built cell's value) set by
    fmpy before the FMU initialises gives the trajectory of the cell file with that
    `[drive.stepper] load_inertia`, within 1e-9 relative at every step; the default's differs."""
    plain = pack(tmp_path, cell_library, "plain")
    md = read_model_description(plain)
    v = {x.name: x for x in md.modelVariables}
    p = v[PREFIX + "stepper.load_inertia"]
    assert (p.causality, p.variability, p.type) == ("parameter", "fixed", "Float64")
    assert float(p.start) == pytest.approx(1.4e-5)  # the CMMO-ST's default load (StepperData)
    assert p.unit == "kg.m2" and "kg.m2" in {u.name for u in md.unitDefinitions}, p.unit
    for key, unit in [("viscous_friction", "N.m.s/rad"), ("coulomb_friction", "N.m"),
                      ("holding_torque", "N.m")]:
        q = v[PREFIX + "stepper." + key]
        assert (q.causality, q.unit) == ("parameter", unit), key
    assert validate_fmu(plain) == []
    heavy = 1.0e-4
    keyed = pack(tmp_path, cell_library, "keyed", f"load_inertia = {heavy}\n")
    tuned = free_turn(plain, {PREFIX + "stepper.load_inertia": heavy})
    native = free_turn(keyed, {})
    default = free_turn(plain, {})
    for (a, w), (a_n, w_n) in zip(tuned, native):
        assert a == pytest.approx(a_n, rel=1e-9, abs=0) and w == pytest.approx(w_n, rel=1e-9, abs=0)
    # The heavier load turns slower under the same torque.
    assert abs(tuned[-1][0]) < abs(default[-1][0]) and tuned[-1][0] < -0.01, (tuned[-1], default[-1])
