"""The cell FMU's front ends beside socketcand, open while fmpy steps the cell
(docs/cosimulation.md, "Front ends"): a CMMO-ST's Modbus TCP server, met by pymodbus between
two fmpy steps at the FMU's clock."""

from __future__ import annotations

import socket
import subprocess

import pytest
from pymodbus.client import ModbusTcpClient

from conftest import DRIVETWIN_BIN, HOST, REPO_ROOT, free_port
from test_cell_fmu import LIBRARY, cell_fmu  # noqa: F401  (the fixture builds the library)
from test_fhpp_modbus import CCON_RECORD_ENABLED, CPOS_HALT, exchange, telegram

fmpy = pytest.importorskip("fmpy")

STEP = 1e-3


def pack(tmp_path, text: str, *extra: str) -> str:
    cell = tmp_path / "cell.toml"
    cell.write_text(text)
    out = tmp_path / "cell.fmu"
    subprocess.run(
        [str(DRIVETWIN_BIN), "fmu", "--config", str(cell), "--output", str(out),
         "--library", str(LIBRARY), *extra],
        check=True, cwd=REPO_ROOT, timeout=60,
    )
    return str(out)


class Stepped:
    """The FMU instantiated and initialised by fmpy's low-level FMI 3 API, stepped at STEP."""

    def __init__(self, fmu: str):
        from fmpy.fmi3 import FMU3Slave
        md = fmpy.read_model_description(fmu)
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.slave = FMU3Slave(guid=md.guid, unzipDirectory=fmpy.extract(fmu),
                               modelIdentifier=md.coSimulation.modelIdentifier,
                               instanceName="cell")
        self.slave.instantiate()
        self.slave.enterInitializationMode(startTime=0.0)
        self.slave.exitInitializationMode()
        self.steps = 0

    def run(self, seconds: float):
        for _ in range(round(seconds / STEP)):
            self.slave.doStep(self.steps * STEP, STEP)
            self.steps += 1

    def out(self, kind: str, name: str):
        """Output `name`'s value, read with `get<kind>` (`Float64`, `UInt16`, ...)."""
        return getattr(self.slave, "get" + kind)([self.vr[name]])[0]

    def free(self):
        self.slave.terminate()
        self.slave.freeInstance()


def test_pymodbus_enables_a_cmmo_st_in_the_cell_between_fmpy_steps(cell_fmu, tmp_path):  # noqa: F811
    """A request between two doSteps is answered at once, at the clock's time: the input
    telegram shows the drive as it is where the importer left the clock, and what the output
    telegram asks for happens in the steps that follow (FHPP: enable, SCON.ENABLED)."""
    port = free_port()
    fmu = pack(tmp_path, f"""
[[bus]]
socketcand = ""

[[drive]]
device = "cmmp-as"
node = 1

[[drive]]
device = "cmmo-st"
modbus = "{HOST}:{port}"
""")
    cell = Stepped(fmu)
    mb = ModbusTcpClient(HOST, port=port, timeout=3, retries=0)
    try:
        cell.run(0.01)
        assert mb.connect()
        s = exchange(mb, telegram(0, 0))
        assert (s["scon"], s["spos"]) == (0x10, 0x04), s      # power-on (FHPP Example 1)
        # One connection at a time: a second one is closed without a byte.
        with socket.create_connection((HOST, port), timeout=2) as second:
            second.settimeout(2)
            assert second.recv(1) == b""
        # Asked between steps; no step, no change: the clock stands.
        s = exchange(mb, telegram(CCON_RECORD_ENABLED, CPOS_HALT))
        assert s["scon"] & 0x01 == 0, s
        assert exchange(mb, telegram(CCON_RECORD_ENABLED, CPOS_HALT)) == s
        # The steps carry it out: enabled (SCON 13h) with HALT not active (SPOS 05h).
        seen = []
        for _ in range(100):
            cell.run(0.01)
            seen.append(exchange(mb, telegram(CCON_RECORD_ENABLED, CPOS_HALT)))
            if (seen[-1]["scon"], seen[-1]["spos"]) == (0x13, 0x05):
                break
        assert (seen[-1]["scon"], seen[-1]["spos"]) == (0x13, 0x05), seen[-5:]
        # And the CANopen drive beside it stepped on the same clock. The CMMO-ST, at the
        # default node-ID 1 as well, has no CANopen node: its variables are named by its place
        # in the cell file, and show what the client did.
        assert cell.slave.getUInt16([cell.vr["node1.statusword"]])[0] != 0
        assert "node1.scon" not in cell.vr
        assert cell.slave.getUInt8([cell.vr["drive1.scon"]])[0] == 0x13
    finally:
        mb.close()
        cell.free()
    # The instance took its server with it.
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection((HOST, port), timeout=2.0).close()


def native_run(tmp_path, cell_text: str, seconds: float) -> dict[float, dict[str, str]]:
    """The example start on `cell_text`, run by `drivetwin scenario`, sampled every STEP."""
    from test_cell_fmu import START
    cell = tmp_path / "native_cell.toml"
    cell.write_text(cell_text)
    text = START.read_text().replace('cell = "cell.toml"', f'cell = "{cell}"')
    text = text.replace('until = "5s"', f'until = "{seconds}s"')
    scenario = tmp_path / "native.toml"
    scenario.write_text(text)
    samples = tmp_path / "native.csv"
    subprocess.run(
        [str(DRIVETWIN_BIN), "scenario", str(scenario), "--samples", str(samples),
         "--sample-ms", str(STEP * 1000)],
        check=True, timeout=120,
    )
    import csv
    with samples.open() as f:
        return {round(float(r["time_s"]), 6): r for r in csv.DictReader(f) if r["node"] == "1"}


def test_a_parameter_set_before_initialisation_is_the_cell_files_key(cell_fmu, tmp_path):  # noqa: F811
    """`node1.motor.inertia`, a fixed parameter whose start is the built cell's value, set by
    fmpy before the FMU initialises: the FMU runs as the native run of the cell file with
    that `[drive.motor] inertia`, not as the file packed."""
    from test_cell_fmu import CELL
    md = fmpy.read_model_description(cell_fmu)
    v = {x.name: x for x in md.modelVariables}
    p = v["node1.motor.inertia"]
    assert (p.causality, p.variability, p.type, p.unit) == ("parameter", "fixed", "Float64", "kg.m2")
    assert float(p.start) == 3e-5                                  # the CMMP-AS's motor data
    assert v["node1.motor.coulomb_friction"].causality == "parameter"
    heavy = 3e-4
    seconds = 0.5
    outputs = ["node1.velocity", "node1.current"]
    packed = fmpy.simulate_fmu(cell_fmu, stop_time=seconds, step_size=STEP,
                               output_interval=STEP, output=outputs)
    tuned = fmpy.simulate_fmu(cell_fmu, stop_time=seconds, step_size=STEP,
                              output_interval=STEP, output=outputs,
                              start_values={"node1.motor.inertia": heavy})
    native = native_run(tmp_path, CELL.read_text() + f"[drive.motor]\ninertia = {heavy}\n", seconds)
    for row in tuned:
        n = native[round(float(row["time"]), 6)]
        assert row["node1.velocity"] == pytest.approx(float(n["velocity_rad_s"]), rel=1e-9, abs=0)
        assert row["node1.current"] == pytest.approx(float(n["current_a"]), rel=1e-9, abs=0)
    # Ten times the inertia takes more current to reach the same speed.
    assert max(abs(r["node1.current"]) for r in tuned) > max(abs(r["node1.current"]) for r in packed)


def test_a_parameter_the_cell_refuses_fails_the_initialisation_with_the_key(cell_fmu):  # noqa: F811
    from fmpy.fmi3 import FMU3Slave
    md = fmpy.read_model_description(cell_fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    messages = []
    slave = FMU3Slave(guid=md.guid, unzipDirectory=fmpy.extract(cell_fmu),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cell")
    slave.instantiate(loggingOn=True,
                      logMessage=lambda _env, status, category, message: messages.append(message))
    try:
        slave.setFloat64([vr["node1.motor.inertia"]], [-1.0])
        with pytest.raises(Exception):       # the cell is built by the end of initialisation
            slave.enterInitializationMode(startTime=0.0)
            slave.exitInitializationMode()
        assert any(b"inertia" in m for m in messages), messages
    finally:
        slave.freeInstance()


@pytest.fixture
def veth_pair():
    """A veth pair in the test's own network namespace: (the FMU's end, the master's end).
    The importer is this process, so the FMU's raw socket is opened here (root or
    CAP_NET_RAW); skips with a message otherwise."""
    import os
    import shutil
    from conftest import ip, ip_steps
    if os.geteuid() != 0:
        pytest.skip("EtherCAT over veth needs root (raw sockets)")
    if shutil.which("ip") is None:
        pytest.skip("`ip` (iproute2) is not installed")
    tag = f"{os.getpid() % 100000}"
    fmu_if, master_if = f"dtfA{tag}", f"dtfB{tag}"
    try:
        ip_steps([
            ("link", "add", master_if, "type", "veth", "peer", "name", fmu_if),
            ("link", "set", fmu_if, "up"),
            ("link", "set", master_if, "up"),
        ])
        yield fmu_if, master_if
    finally:
        ip("link", "del", master_if)  # deletes the peer too


def to_op(master, cycle) -> None:
    """Op, requested while the process data is exchanged (as SOEM's examples do): `cycle(cw)`
    steps the FMU and exchanges once; the caller checks the state reached."""
    pysoem = pytest.importorskip("pysoem")
    master.state = pysoem.OP_STATE
    cycle(0)
    master.write_state()
    for _ in range(100):
        cycle(0)
        if master.read_state() == pysoem.OP_STATE:
            break


def enable(master, cycle) -> int:
    """Shutdown, switch on, enable operation: one controlword per step until the statusword
    shows it, every working counter right; the last statusword."""
    sw = 0
    for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)):
        for _ in range(100):
            wkc, sw = cycle(cw)
            assert wkc == master.expected_wkc
            if sw & 0x6F == want:
                break
        assert sw & 0x6F == want, f"controlword {cw:#x}: statusword {sw:#06x}"
    return sw


def test_soem_takes_an_ethercat_slave_of_the_cell_to_op_and_moves_it_between_fmpy_steps(
        cell_fmu, tmp_path, veth_pair):  # noqa: F811
    """The cell's EtherCAT chain is open while fmpy steps it: pysoem, on the other end of a
    veth pair, finds the slave, reads its identity over CoE and takes it to Safe-Op between
    two steps (a slave serves its mailbox and AL state after every frame); the CANopen drive
    beside it steps on the same clock. Then, one process-data exchange per fmpy step (the
    master's cycle is the importer's step, free run), the slave goes to Op, the controlword
    enables it in profile velocity mode (CiA 402 §6.3.1) and its shaft turns: the FMU's
    `drive1.*` outputs (the drive of the second `[[drive]]`, which has no CANopen node) are
    what the master reads, and its position follows the move."""
    pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")
    from conftest import product_code
    fmu_if, master_if = veth_pair
    fmu = pack(tmp_path, f"""
[[bus]]
socketcand = ""

[[drive]]
device = "cmmp-as"
node = 1

[[drive]]
device = "cmmp-as"
node = 2
ethercat = "{fmu_if}"
""")
    cell = Stepped(fmu)
    master = pysoem.Master()
    master.open(master_if)

    out = cell.out

    def cycle(cw: int) -> tuple[int, int]:
        """One fmpy step, then one process-data exchange at the step's end: (wkc, statusword)."""
        cell.run(STEP)
        slave.output = cw.to_bytes(2, "little")
        master.send_processdata()
        wkc = master.receive_processdata(100_000)
        return wkc, int.from_bytes(bytes(slave.input[:2]), "little")

    try:
        cell.run(0.01)
        assert master.config_init() == 1, "one slave on the wire"
        slave = master.slaves[0]
        assert (slave.man, slave.id) == (0x1D, product_code())
        assert int.from_bytes(slave.sdo_read(0x1018, 1), "little") == 0x1D
        slave.sdo_write(0x6065, 0, (12345).to_bytes(4, "little"))
        assert int.from_bytes(slave.sdo_read(0x6065, 0), "little") == 12345
        slave.sdo_write(0x6060, 0, bytes([3]))                          # profile velocity
        slave.sdo_write(0x60FF, 0, (2000).to_bytes(4, "little", signed=True))
        assert master.config_map() == 4                              # controlword / statusword
        assert master.state_check(pysoem.SAFEOP_STATE, 2_000_000) == pysoem.SAFEOP_STATE, \
            f"Safe-Op: AL status code {slave.al_status:#x}"
        cell.run(0.1)
        assert master.read_state() == pysoem.SAFEOP_STATE
        assert out("UInt16", "node1.statusword") != 0

        # Op, requested while the process data is exchanged (as SOEM's examples do).
        to_op(master, cycle)
        assert slave.state == pysoem.OP_STATE, f"Op: {slave.state:#x} code {slave.al_status:#x}"

        # Shutdown, switch on, enable operation: one controlword per step until it shows.
        sw = enable(master, cycle)
        assert out("UInt16", "drive1.statusword") == sw, "the FMU's statusword is the master's"
        start = out("Float64", "drive1.position")
        for _ in range(300):
            wkc, sw = cycle(0x0F)
            assert wkc == master.expected_wkc
        assert master.read_state() == pysoem.OP_STATE, f"AL status code {slave.al_status:#x}"
        assert sw & 0x6F == 0x27
        moved = out("Float64", "drive1.position") - start
        assert moved > 0.1, f"the shaft turned {moved} rad in 0.3 s"
        assert out("Float64", "drive1.velocity") > 0
        assert out("Int32", "drive1.position_actual") > 0
        # The CANopen drive beside it was never enabled: it stands.
        assert abs(out("Float64", "node1.velocity")) < 1e-9
    finally:
        master.close()
        cell.free()


@pytest.mark.parametrize("form", ["named", "interfaces"])
def test_a_cell_of_ethercat_slaves_alone_is_an_fmu_soem_drives_between_fmpy_steps(
        cell_fmu, tmp_path, veth_pair, form):  # noqa: F811
    """A cell whose only drives are EtherCAT slaves (no CAN node, no CMMO-ST) is an FMU: its
    variables are `driveK`'s, K the `[[drive]]` index, doStep advances the slaves' drives
    and the chain is open while fmpy steps it. pysoem takes both slaves to Op between steps
    and enables the second; its shaft turns in the FMU's outputs. Each slave's
    `[drive.motor]` keys are parameters, as a CANopen CMMP-AS's are. The chain is named in
    the cell file (`ethercat = "IF"`), or the slaves list `interfaces = ["ethercat"]` and
    `drivetwin fmu --ethercat IF` gives it, as `drivetwin run --ethercat IF` does."""
    pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")
    fmu_if, master_if = veth_pair
    chain = f'ethercat = "{fmu_if}"' if form == "named" else 'interfaces = ["ethercat"]'
    extra = [] if form == "named" else ["--ethercat", fmu_if]
    fmu = pack(tmp_path, f"""
[[drive]]
device = "cmmp-as"
node = 1
{chain}

[[drive]]
device = "cmmp-as"
node = 2
{chain}
[drive.motor]
inertia = 4e-5
""", *extra)
    md = fmpy.read_model_description(fmu)
    v = {x.name: x for x in md.modelVariables}
    assert not any(n.startswith("node") for n in v), sorted(v)
    for name in ("drive0.statusword", "drive1.position", "drive1.load_torque", "drive1.display"):
        assert name in v, name
    assert (v["drive1.motor.inertia"].causality, float(v["drive1.motor.inertia"].start)) == \
        ("parameter", 4e-5)
    assert float(v["drive0.motor.inertia"].start) == 3e-5            # the CMMP-AS's motor data
    cell = Stepped(fmu)
    master = pysoem.Master()
    master.open(master_if)

    out = cell.out

    def cycle(cw: int) -> tuple[int, int]:
        cell.run(STEP)
        for s in master.slaves:
            s.output = (cw if s is master.slaves[1] else 0).to_bytes(2, "little")
        master.send_processdata()
        wkc = master.receive_processdata(100_000)
        return wkc, int.from_bytes(bytes(master.slaves[1].input[:2]), "little")

    try:
        cell.run(0.01)
        assert master.config_init() == 2, "two slaves on the wire"
        slave = master.slaves[1]
        slave.sdo_write(0x6060, 0, bytes([3]))                          # profile velocity
        slave.sdo_write(0x60FF, 0, (2000).to_bytes(4, "little", signed=True))
        master.config_map()
        assert master.state_check(pysoem.SAFEOP_STATE, 2_000_000) == pysoem.SAFEOP_STATE
        to_op(master, cycle)
        assert master.read_state() == pysoem.OP_STATE
        sw = enable(master, cycle)
        assert out("UInt16", "drive1.statusword") == sw, "the FMU's statusword is the master's"
        start = out("Float64", "drive1.position")
        for _ in range(300):
            cycle(0x0F)
        assert out("Float64", "drive1.position") - start > 0.1
        assert abs(out("Float64", "drive0.velocity")) < 1e-9, "the first slave was not enabled"
    finally:
        master.close()
        cell.free()


def test_a_nanotec_steppers_keys_are_parameters_and_checked_as_the_cell_files(cell_fmu, tmp_path):  # noqa: F811
    """A Nanotec stepper's `[drive.stepper]` keys are FMI parameters (start: the cell file's
    value); a value set before initialisation is written into that section and checked as the
    key is: a negative load inertia fails the initialisation naming it."""
    from fmpy.fmi3 import FMU3Slave
    fmu = pack(tmp_path, """
[[bus]]
socketcand = ""

[[drive]]
device = "nanotec-pd4n"
node = 5
[drive.stepper]
load_inertia = 2e-5
""")
    md = fmpy.read_model_description(fmu)
    v = {x.name: x for x in md.modelVariables}
    p = v["node5.stepper.load_inertia"]
    assert (p.causality, p.variability, float(p.start)) == ("parameter", "fixed", 2e-5)
    assert "node5.motor.inertia" not in v
    messages = []
    slave = FMU3Slave(guid=md.guid, unzipDirectory=fmpy.extract(fmu),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cell")
    slave.instantiate(loggingOn=True,
                      logMessage=lambda _env, status, category, message: messages.append(message))
    try:
        slave.setFloat64([p.valueReference], [-1.0])
        with pytest.raises(Exception):
            slave.enterInitializationMode(startTime=0.0)
            slave.exitInitializationMode()
        assert any(b"stepper.load_inertia" in m for m in messages), messages
    finally:
        slave.freeInstance()
    # A servo motor's shaft key on the stepper is refused when the FMU is made, by name.
    cell = tmp_path / "servo.toml"
    cell.write_text('[[bus]]\nsocketcand = ""\n[[drive]]\ndevice = "nanotec-pd4n"\nnode = 5\n'
                    '[drive.motor]\ninertia = 2e-5\n')
    r = subprocess.run([str(DRIVETWIN_BIN), "fmu", "--config", str(cell), "--output",
                        str(tmp_path / "servo.fmu"), "--library", str(LIBRARY)],
                       cwd=REPO_ROOT, timeout=60, capture_output=True, text=True)
    assert r.returncode != 0
    assert "motor.inertia" in r.stderr, r.stderr
