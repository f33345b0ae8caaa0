"""A drivetwin cell as an FMI 3.0 co-simulation FMU (`drivetwin fmu`, crates/cell-fmu,
docs/cosimulation.md), met by fmpy, an FMI importer nobody here wrote: its model description
validates, and simulated 5 s with a step of load torque the drive's shaft follows the motor
model: the same trajectory as the same cell and start run natively on the virtual clock
(`drivetwin scenario --samples`), within 1e-9 relative. While fmpy steps it, the cell's
socketcand server is open on the FMU's clock: python-canopen reads, enables and moves the drive
between steps."""

from __future__ import annotations

import csv
import socket
import subprocess

import numpy as np
import pytest

from conftest import CELL_LIBRARY, CHANNEL, DRIVETWIN_BIN, HOST, REPO_ROOT, add_node, free_port

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402

CELL = REPO_ROOT / "examples" / "cell_fmu" / "cell.toml"
START = REPO_ROOT / "examples" / "cell_fmu" / "start.toml"
LIBRARY = CELL_LIBRARY  # the `cell_library` fixture builds it
LOAD_AT = 1.0
LOAD_NM = 0.5
STOP = 5.0
STEP = 1e-3


@pytest.fixture(scope="module")
def cell_fmu(tmp_path_factory, cell_library):
    """The example cell packed by the binary under test, with crates/cell-fmu's library of its
    profile (conftest's `cell_library`)."""
    out = tmp_path_factory.mktemp("cell_fmu") / "cell.fmu"
    subprocess.run(
        [str(DRIVETWIN_BIN), "fmu", "--config", str(CELL), "--scenario", str(START),
         "--output", str(out), "--library", str(LIBRARY)],
        check=True, cwd=REPO_ROOT, timeout=60,
    )
    return str(out)


def test_fmpy_finds_no_problem_in_the_cell_fmu(cell_fmu):
    assert validate_fmu(cell_fmu) == []
    md = fmpy.read_model_description(cell_fmu)
    assert md.fmiVersion == "3.0"
    assert md.coSimulation.modelIdentifier == "drivetwin_cell"
    v = {x.name: x for x in md.modelVariables}
    assert (v["node1.load_torque"].causality, v["node1.load_torque"].type) == ("input", "Float64")
    assert v["node1.load_torque"].unit == "N.m"
    assert (v["node1.din0"].causality, v["node1.din0"].type) == ("input", "Boolean")
    for name, kind in [("position", "Float64"), ("velocity", "Float64"), ("current", "Float64"),
                       ("statusword", "UInt16"), ("position_actual", "Int32")]:
        assert (v[f"node1.{name}"].causality, v[f"node1.{name}"].type) == ("output", kind)
    outputs = {u.variable.name for u in md.outputs}
    assert "node1.position" in outputs and "node1.statusword" in outputs


def native_run(tmp_path) -> dict[float, dict[str, float]]:
    """The same cell and start with the load as a scenario step, sampled every STEP."""
    text = START.read_text().replace('cell = "cell.toml"', f'cell = "{CELL}"')
    text += f'\n[[step]]\nat = "{LOAD_AT}s"\nload = {LOAD_NM}\n'
    scenario = tmp_path / "native.toml"
    scenario.write_text(text)
    samples = tmp_path / "native.csv"
    subprocess.run(
        [str(DRIVETWIN_BIN), "scenario", str(scenario), "--samples", str(samples),
         "--sample-ms", str(STEP * 1000)],
        check=True, timeout=120,
    )
    with samples.open() as f:
        return {round(float(r["time_s"]), 6): r for r in csv.DictReader(f) if r["node"] == "1"}


def test_the_fmus_shaft_follows_the_same_trajectory_as_the_native_run(cell_fmu, tmp_path):
    signals = np.array(
        [(0.0, 0.0), (LOAD_AT, 0.0), (LOAD_AT, LOAD_NM), (STOP, LOAD_NM)],
        dtype=[("time", np.float64), ("node1.load_torque", np.float64)],
    )
    r = fmpy.simulate_fmu(
        cell_fmu, stop_time=STOP, step_size=STEP, output_interval=STEP, input=signals,
        output=["node1.position", "node1.velocity", "node1.current", "node1.statusword"],
    )
    native = native_run(tmp_path)
    assert len(r) == round(STOP / STEP) + 1
    fmu_pos, nat_pos = [], []
    for row in r:
        n = native[round(float(row["time"]), 6)]
        fmu_pos.append(row["node1.position"])
        nat_pos.append(float(n["position_rad"]))
        assert row["node1.velocity"] == pytest.approx(float(n["velocity_rad_s"]), rel=1e-9, abs=0)
        assert row["node1.current"] == pytest.approx(float(n["current_a"]), rel=1e-9, abs=0)
    np.testing.assert_allclose(fmu_pos, nat_pos, rtol=1e-9, atol=0)
    # The drive is enabled (operation enabled, 6041h & 6Fh = 27h) and turns; the step of load
    # torque shows in the current from LOAD_AT on.
    end = r[-1]
    assert end["node1.statusword"] & 0x6F == 0x27
    assert end["node1.position"] > 50.0
    before = r[(r["time"] > LOAD_AT - 0.2) & (r["time"] < LOAD_AT)]["node1.current"].mean()
    after = r[(r["time"] > LOAD_AT + 0.5)]["node1.current"].mean()
    assert after - before > 0.5


def pack_with_socketcand(tmp_path, port: int) -> str:
    """The example cell, without its start, with its bus's socketcand server on `port`; the
    bus instant, so a request between two steps is answered before the next one (on a timed
    bus the answer crosses in the next step)."""
    cell = tmp_path / "cell.toml"
    cell.write_text(f'[[bus]]\nsocketcand = "{HOST}:{port}"\nchannel = "{CHANNEL}"\n'
                    'bitrate = "instant"\n\n' + CELL.read_text())
    out = tmp_path / "cell.fmu"
    subprocess.run(
        [str(DRIVETWIN_BIN), "fmu", "--config", str(cell), "--output", str(out),
         "--library", str(LIBRARY)],
        check=True, cwd=REPO_ROOT, timeout=60,
    )
    return str(out)


def test_python_canopen_drives_the_cell_between_fmpy_steps(cell_fmu, tmp_path, eds_files):
    """The importer owns the clock; a client frame acts at the clock's time when it arrives,
    so SDO requests between two doSteps are answered before the next one."""
    import canopen
    from fmpy.fmi3 import FMU3Slave

    port = free_port()
    fmu = pack_with_socketcand(tmp_path, port)
    md = fmpy.read_model_description(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU3Slave(guid=md.guid, unzipDirectory=fmpy.extract(fmu),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cell")
    slave.instantiate()
    slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    steps = 0
    h = 1e-3

    def run(seconds: float):
        nonlocal steps
        for _ in range(round(seconds / h)):
            slave.doStep(steps * h, h)
            steps += 1

    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="socketcand", host=HOST, port=port, channel=CHANNEL)
    try:
        node = add_node(net, 1, eds_files["cmmp-as"])
        run(0.01)
        vendor = node.sdo.upload(0x1018, 1)
        assert int.from_bytes(vendor, "little") == node.object_dictionary[0x1018][1].default
        node.sdo.download(0x6060, 0, (3).to_bytes(1, "little"))          # profile velocity
        node.sdo.download(0x60FF, 0, (200).to_bytes(4, "little", signed=True))
        for controlword in (0x06, 0x07, 0x0F):                         # CiA 402 §6.3.1
            node.sdo.download(0x6040, 0, controlword.to_bytes(2, "little"))
            run(0.02)
        status = int.from_bytes(node.sdo.upload(0x6041, 0), "little")
        assert status & 0x6F == 0x27
        assert slave.getUInt16([vr["node1.statusword"]])[0] == status
        run(1.0)
        assert slave.getFloat64([vr["node1.velocity"]])[0] > 1.0
        assert slave.getFloat64([vr["node1.position"]])[0] > 1.0
        # The client reads at the clock's time: the same value the importer gets.
        actual = int.from_bytes(node.sdo.upload(0x6064, 0), "little", signed=True)
        assert actual != 0
        assert slave.getInt32([vr["node1.position_actual"]])[0] == actual
    finally:
        net.disconnect()
        slave.terminate()
        slave.freeInstance()
    # The instance took its server with it.
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection((HOST, port), timeout=2.0).close()
