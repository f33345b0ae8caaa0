"""The example load FMU (crates/conveyor-fmu, its model crates/conveyor; docs/cosimulation.md),
met by fmpy, an FMI importer nobody here wrote: its model description validates, and stepped
with a turning shaft the belt follows, carries its friction as load torque on the shaft, and
the light barrier sees the belt pass its window. Its FMI 2.0 build (the same library,
target/fmu/conveyor-fmi2.fmu) validates as well and gives the same values, step for step."""

from __future__ import annotations

import json
import re
import subprocess
import urllib.error
import urllib.request

import numpy as np
import pytest

from conftest import DRIVETWIN_BIN, HOST, REPO_ROOT, free_port, run_cli, wait_until

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402

FMU = REPO_ROOT / "target" / "fmu" / "conveyor.fmu"
FMU2 = REPO_ROOT / "target" / "fmu" / "conveyor-fmi2.fmu"


@pytest.fixture(scope="module")
def conveyor_fmu():
    """Built from source and packed by scripts/conveyor-fmu (a no-op rebuild when it is)."""
    subprocess.run([str(REPO_ROOT / "scripts" / "conveyor-fmu")], check=True, cwd=REPO_ROOT)
    return str(FMU)


@pytest.fixture(scope="module")
def conveyor_fmu2(conveyor_fmu):
    """The FMI 2.0 build, packed by the same scripts/conveyor-fmu run."""
    return str(FMU2)


def test_fmpy_finds_no_problem_in_the_conveyor_fmu(conveyor_fmu):
    assert validate_fmu(conveyor_fmu) == []
    md = fmpy.read_model_description(conveyor_fmu)
    assert md.fmiVersion == "3.0"
    assert md.coSimulation.modelIdentifier == "conveyor"
    causality = {v.name: (v.causality, v.type) for v in md.modelVariables}
    assert causality["shaft_angle"] == ("input", "Float64")
    assert causality["shaft_speed"] == ("input", "Float64")
    assert causality["load_torque"] == ("output", "Float64")
    assert causality["belt_position"] == ("output", "Float64")
    assert causality["light_barrier"] == ("output", "Boolean")


def test_fmpy_finds_no_problem_in_the_fmi2_build(conveyor_fmu2):
    assert validate_fmu(conveyor_fmu2) == []
    md = fmpy.read_model_description(conveyor_fmu2, validate=True)
    assert md.fmiVersion == "2.0"
    assert md.coSimulation.modelIdentifier == "conveyor"
    causality = {v.name: (v.causality, v.type) for v in md.modelVariables}
    assert causality["shaft_angle"] == ("input", "Real")
    assert causality["shaft_speed"] == ("input", "Real")
    assert causality["load_torque"] == ("output", "Real")
    assert causality["light_barrier"] == ("output", "Boolean")
    assert causality["mass"] == ("parameter", "Real")


def turning_shaft(fmu: str):
    """The FMU stepped by fmpy for 2 s at 1 ms with the shaft at 10 rad/s."""
    w = 10.0
    t = np.linspace(0.0, 2.0, 2001)
    signals = np.zeros(len(t), dtype=[("time", np.float64), ("shaft_angle", np.float64), ("shaft_speed", np.float64)])
    signals["time"] = t
    signals["shaft_angle"] = w * t
    signals["shaft_speed"] = w
    return fmpy.simulate_fmu(
        fmu,
        stop_time=2.0,
        step_size=1e-3,
        input=signals,
        output=["belt_position", "belt_speed", "load_torque", "light_barrier"],
    )


def test_a_turning_shaft_moves_the_belt_through_the_light_barrier(conveyor_fmu):
    # 10 rad/s on a 10 mm pulley: 0.1 m/s of belt; the barrier's window is 0.10 … 0.12 m.
    r = turning_shaft(conveyor_fmu)
    end = r[-1]
    assert end["belt_speed"] == pytest.approx(0.1, rel=1e-6)
    # Steady: the belt carries the mass's friction, 5 N·s/m · 0.1 m/s + 2 N, on a 10 mm pulley.
    assert end["load_torque"] == pytest.approx(0.025, rel=1e-3)
    inside = r["light_barrier"]
    pos = r["belt_position"]
    assert inside.any()
    assert ((pos >= 0.10) & (pos <= 0.12) == inside).all()


def test_the_fmi2_build_gives_the_same_values_step_for_step(conveyor_fmu, conveyor_fmu2):
    r3 = turning_shaft(conveyor_fmu)
    r2 = turning_shaft(conveyor_fmu2)
    assert len(r2) == len(r3)
    for name in ("belt_position", "belt_speed", "load_torque", "light_barrier"):
        assert (r2[name] == r3[name]).all(), name


def api(url: str, method: str = "GET", body: dict | None = None) -> tuple[int, dict]:
    """One REST call to the console; its status and JSON body."""
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method=method,
                                 headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def console(twin) -> str:
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the 'web console on' line")
    m = re.match(r"web console on (http://127\.0\.0\.1:\d+/)$", line)
    assert m, line
    return m.group(1)


def test_a_load_fmu_is_coupled_shown_and_uncoupled_over_rest(launch, conveyor_fmu2):
    """PUT /api/drives/0/load/fmu couples the FMI 2.0 conveyor while the cell runs; GET
    /api/drives/0/load shows it stepping with its mapped values; a missing variable is refused
    by name (400); DELETE uncouples it."""
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    load = console(twin) + "api/drives/0/load"
    assert api(load) == (200, {"fmu": None, "failure": None})
    table = {"fmu": conveyor_fmu2, "angle": "shaft_angle", "speed": "shaft_speed",
             "load_torque": "load_torque", "position": "belt_position",
             "switches": {"home": "light_barrier"}}
    status, view = api(load + "/fmu", "PUT", table)
    assert status == 200, view
    assert view["fmu"]["fmi_version"] == "2.0"
    assert view["fmu"]["mapping"]["load_torque"] == "load_torque"
    stepping = wait_until(lambda: (v := api(load)[1])["fmu"]["steps"] > 100 and v, 5.0,
                          what="the FMU to step")
    roles = {v["role"]: v for v in stepping["fmu"]["variables"]}
    assert roles["home"]["variable"] == "light_barrier"
    assert roles["home"]["level"] is False
    assert "value" in roles["load_torque"]
    status, refused = api(load + "/fmu", "PUT", {**table, "load_torque": "belt_torque"})
    assert status == 400
    assert "no variable `belt_torque` (mapped as `load_torque`)" in refused["error"]
    assert api(load + "/fmu", "DELETE") == (200, {"fmu": None, "failure": None})


def said_by_the_fmu(stderr: str) -> bool:
    """The error that stops the cell carries the conveyor FMU's own message."""
    errors = [l for l in stderr.splitlines() if l.startswith("error:")]
    return any("returned Error: mass -1 kg must be positive" in l for l in errors)


def test_drivetwin_run_stops_with_the_error_of_a_failing_load(tmp_path, conveyor_fmu):
    """A load whose doStep returns an error (a mass of -1 kg) ends `drivetwin run`, on the
    virtual clock and in real time, with the FMU's error, the FMU's own log message in it, and
    a non-zero exit."""
    cell = tmp_path / "cell.toml"
    cell.write_text(
        '[[drive]]\ndevice = "cmmp-as"\nnode = 1\n[drive.load]\n'
        f'fmu = "{conveyor_fmu}"\nspeed = "shaft_speed"\nload_torque = "load_torque"\n'
        '[drive.load.parameters]\nmass = -1.0\n')
    r = run_cli("run", "--config", str(cell), "--virtual-seconds", "1", timeout=60)
    assert r.returncode != 0
    assert "fmi3DoStep at t = 0 s returned Error" in r.stderr, r.stderr
    assert said_by_the_fmu(r.stderr)
    r = subprocess.run([str(DRIVETWIN_BIN), "run", "--config", str(cell), "--socketcand",
                        "127.0.0.1:0", "--http", "127.0.0.1:0"],
                       capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert r.returncode != 0
    assert "fmi3DoStep at t = 0 s returned Error" in r.stderr, r.stderr
    assert said_by_the_fmu(r.stderr)


def test_a_load_fmu_is_coupled_to_a_cmmo_st_over_rest(launch, tmp_path, conveyor_fmu2):
    """The same REST calls on a CMMO-ST (FHPP over Modbus TCP, drive 1 after the CMMP-AS on
    the bus): the conveyor steps with its 1 ms FHPP cycle, its light barrier is the CMMO-ST's
    reference switch; a limit switch, which the CMMO-ST has no input for (its ends of travel
    are fixed stops), is refused (400); DELETE uncouples it."""
    cell = tmp_path / "cell.toml"
    cell.write_text('[[drive]]\ndevice = "cmmp-as"\nnode = 1\n\n'
                    f'[[drive]]\ndevice = "cmmo-st"\nmodbus = "{HOST}:{free_port()}"\n')
    twin = launch(config=cell, extra=("--http", "127.0.0.1:0"))
    load = console(twin) + "api/drives/1/load"
    assert api(load) == (200, {"fmu": None, "failure": None})
    table = {"fmu": conveyor_fmu2, "angle": "shaft_angle", "speed": "shaft_speed",
             "load_torque": "load_torque", "position": "belt_position",
             "switches": {"home": "light_barrier"}}
    status, view = api(load + "/fmu", "PUT", table)
    assert status == 200, view
    assert view["fmu"]["fmi_version"] == "2.0"
    stepping = wait_until(lambda: (v := api(load)[1])["fmu"]["steps"] > 100 and v, 5.0,
                          what="the FMU to step")
    roles = {v["role"]: v for v in stepping["fmu"]["variables"]}
    assert roles["home"]["variable"] == "light_barrier"
    assert roles["home"]["level"] is False
    status, refused = api(load + "/fmu", "PUT",
                          {**table, "switches": {"limit_positive": "light_barrier"}})
    assert status == 400, refused
    assert "limit_positive" in refused["error"], refused
    # The refused table changed nothing: the conveyor still steps.
    assert api(load)[1]["fmu"]["mapping"]["switches"] == {"home": "light_barrier"}
    assert api(load + "/fmu", "DELETE") == (200, {"fmu": None, "failure": None})
    # The CANopen drive beside it has none.
    assert api(console(twin) + "api/drives/0/load") == (200, {"fmu": None, "failure": None})


def test_drivetwin_run_stops_with_the_error_of_a_cmmo_sts_failing_load(tmp_path, conveyor_fmu):
    """A CMMO-ST's load whose doStep returns an error ends `drivetwin run` (real time; the
    CMMO-ST has no --virtual-seconds) with the FMU's error and a non-zero exit, as a CiA 402
    drive's does."""
    cell = tmp_path / "cell.toml"
    cell.write_text(
        f'[[drive]]\ndevice = "cmmo-st"\nmodbus = "{HOST}:{free_port()}"\n[drive.load]\n'
        f'fmu = "{conveyor_fmu}"\nspeed = "shaft_speed"\nload_torque = "load_torque"\n'
        '[drive.load.parameters]\nmass = -1.0\n')
    r = subprocess.run([str(DRIVETWIN_BIN), "run", "--config", str(cell), "--socketcand",
                        "127.0.0.1:0", "--http", "127.0.0.1:0"],
                       capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert r.returncode != 0
    assert "fmi3DoStep at t = 0 s returned Error" in r.stderr, r.stderr
    assert said_by_the_fmu(r.stderr)
