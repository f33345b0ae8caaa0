"""The generic CiA 402 drive from an EDS as an EtherCAT slave (`eds = "..."` with
`interfaces = ["ethercat"]`), under pysoem over a veth pair: SOEM finds it, its SII identity
is the EDS's and CoE 1018h says the same, the cyclic synchronous position PDOs are assigned
over CoE in Pre-Op (1C12h = 1600h + 1602h: controlword, target position; 1C13h = 1A02h:
statusword, position actual value), it goes to Op in free run (the frame is the drive's time
base, as CMMP-AS §2.11 "without DC"), is enabled through the controlword in the outputs and
follows a ramp of set-points every 10 ms. A file EtherCAT cannot take is refused at start with
what to change. The chain under DC at 1 and 4 kHz is `field/test_field_soem_chain.py`'s.

Needs root and `ip`; skips otherwise.
"""

from __future__ import annotations

import json
import struct
import subprocess
import time
from pathlib import Path

import pytest

from conftest import DRIVETWIN_BIN, Realtime, ecat_twin_run, free_port

pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")

EDS = Path(__file__).resolve().parent / "data" / "eds" / "epos4_like.eds"
CYCLE_MS = 10
CYCLE_S = CYCLE_MS / 1000
# [DeviceInfo] of the file, which is its 1018h:01-03.
IDENTITY = (0xFB, 0x65500000, 0x01700000)


def cell(tmp_path: Path, eds: Path = EDS) -> Path:
    path = tmp_path / "eds-ethercat.toml"
    path.write_text(f'[[drive]]\neds = "{eds}"\nnode = 1\ninterfaces = ["ethercat"]\n'
                    f'[drive.objects]\n"60C2:01" = {CYCLE_MS}\n"60C2:02" = -3\n')
    return path


def u32(b: bytes) -> int:
    return struct.unpack("<I", b[:4])[0]


def assign_csp(s) -> None:
    """The cyclic synchronous position PDOs over CoE in Pre-Op (1C12h = 1600h + 1602h:
    controlword, target position; 1C13h = 1A02h: statusword, position actual value), as
    CiA 301 changes an assignment, and 6060h = 8 (CSP)."""
    for index, pdos in ((0x1C12, (0x1600, 0x1602)), (0x1C13, (0x1A02,))):
        s.sdo_write(index, 0, bytes([0]))
        for k, pdo in enumerate(pdos, 1):
            s.sdo_write(index, k, struct.pack("<H", pdo))
        s.sdo_write(index, 0, bytes([len(pdos)]))
    s.sdo_write(0x6060, 0, bytes([8]))


class Cycles:
    """Process data every `CYCLE_S`, as a PLC's cyclic task: controlword `cw` and `target` out,
    the working counter, statusword and position actual value in, then the master sleeps to
    the next period."""

    def __init__(self, master, s) -> None:
        self.master, self.s = master, s
        self.target = 0
        self.due = time.monotonic()

    def __call__(self, cw: int) -> tuple[int, int, int]:
        self.s.output = struct.pack("<Hi", cw, self.target)
        self.master.send_processdata()
        wkc = self.master.receive_processdata(100_000)
        self.due += CYCLE_S
        time.sleep(max(0.0, self.due - time.monotonic()))
        sw, pos = struct.unpack("<Hi", bytes(self.s.input))
        return wkc, sw, pos

    def to_op(self) -> None:
        """Valid outputs first, then Op requested, cycling until the slave is there (as
        SOEM's simple_test); the target then starts where the drive stands."""
        self.master.state = pysoem.OP_STATE
        self(0)
        self.master.write_state()
        for _ in range(100):
            self(0)
            if self.master.read_state() == pysoem.OP_STATE:
                break
        assert self.s.state == pysoem.OP_STATE, hex(self.s.al_status)
        _, _, self.target = self(0)

    def enable(self) -> int:
        """CiA 402 enable: controlword 6 → 7 → Fh until the statusword (mask 6Fh) shows
        21h → 23h → 27h; the cycles with a wrong working counter meanwhile."""
        bad_wkc = 0
        for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)):
            for _ in range(100):
                wkc, sw, _ = self(cw)
                bad_wkc += wkc != self.master.expected_wkc
                if sw & 0x6F == want:
                    break
            assert sw & 0x6F == want, hex(sw)
        return bad_wkc


def test_the_eds_drive_goes_to_op_and_follows_csp_pdos(veth, tmp_path):
    with ecat_twin_run(veth, tmp_path, "--config", str(cell(tmp_path)), realtime=True) as (master_if, _):
        master = pysoem.Master()
        master.open(master_if)
        try:
            assert master.config_init() == 1
            s = master.slaves[0]
            assert (s.man, s.id, s.rev) == IDENTITY
            # SII words 8, 0Ah, 0Ch (ETG.1000.6 Tab. 16) and CoE 1018h:01-03.
            assert [u32(s.eeprom_read(w)) for w in (0x08, 0x0A, 0x0C)] == list(IDENTITY)
            assert [u32(s.sdo_read(0x1018, k)) for k in (1, 2, 3)] == list(IDENTITY)
            assert struct.unpack("<H", s.sdo_read(0x1C12, 1)[:2])[0] == 0x1600
            assign_csp(s)
            master.config_map()
            assert (len(s.output), len(s.input)) == (6, 6)
            assert master.state_check(pysoem.SAFEOP_STATE, 5_000_000) == pysoem.SAFEOP_STATE

            cycle = Cycles(master, s)
            cycle.to_op()
            bad_wkc = cycle.enable()
            assert s.sdo_read(0x6061, 0)[0] == 8, "CSP"
            start = cycle.target
            for _ in range(100):
                cycle.target += 50
                wkc, sw, pos = cycle(0x0F)
                bad_wkc += wkc != master.expected_wkc
            for _ in range(10):
                wkc, sw, pos = cycle(0x0F)
                bad_wkc += wkc != master.expected_wkc
            assert bad_wkc == 0
            assert sw & 0x6F == 0x27, hex(sw)
            assert cycle.target == start + 5000
            assert abs(pos - cycle.target) < 50, (pos, cycle.target)
            assert master.read_state() == pysoem.OP_STATE
        finally:
            master.close()


def api_in(ns: str, path: str, port: int):
    """GET `path` of the twin's REST API inside its namespace: (status, JSON)."""
    r = subprocess.run(["ip", "netns", "exec", ns, "curl", "-s", "-o", "-", "-w", "\n%{http_code}",
                        f"http://127.0.0.1:{port}{path}"], capture_output=True, text=True, timeout=10)
    text, _, code = r.stdout.rpartition("\n")
    return int(code or 0), json.loads(text) if text else None


def test_the_console_shows_the_dictionary_the_slave_serves(veth, tmp_path):
    """The console's dictionary of the drive is its EtherCAT slave's: the sync manager objects
    1C00h / 1C12h / 1C13h the twin adds to the file's are listed and read through the REST
    API with the values CoE gives, beside the file's own objects."""
    ns = veth[0]
    subprocess.run(["ip", "-n", ns, "link", "set", "lo", "up"], check=True, timeout=10)
    port = free_port()
    with ecat_twin_run(veth, tmp_path, "--config", str(cell(tmp_path)), "--http", f"127.0.0.1:{port}"):
        status, drives = api_in(ns, "/api/drives", port)
        assert status == 200 and drives[0]["interface"] == "ethercat", drives
        status, objects = api_in(ns, "/api/drives/0/objects", port)
        assert status == 200, objects
        listed = {(int(o["index"], 16), o["sub"]) for o in objects}
        for entry in ((0x1C00, 0), (0x1C00, 4), (0x1C12, 0), (0x1C12, 1), (0x1C13, 1), (0x6040, 0), (0x1600, 1)):
            assert entry in listed, f"{entry[0]:04X}h:{entry[1]:02X} not in the console's dictionary"
        status, o = api_in(ns, "/api/drives/0/objects/1C12/1", port)
        assert status == 200, o
        assert o["raw"] == "0016", o  # 1600h, in the bytes of the wire
        status, o = api_in(ns, "/api/drives/0/objects/1C00/3", port)
        assert status == 200 and o["value"] == "3", o
        status, params = api_in(ns, "/api/drives/0/parameters", port)
        assert status == 200, params


DC_CYCLES = 500


def test_the_eds_drive_follows_csp_on_dc_sync0_every_cycle(veth, tmp_path):
    """The same drive on distributed clocks, as field code runs it: `config_dc`, SYNC0 every
    10 ms (the interpolation period 60C2h), Safe-Op and Op, a new CSP set-point in every
    cycle for 500 cycles. Every cycle the actual position stands within a few set-points of
    the last one sent (the outputs are taken at the next SYNC0, the inputs latched there),
    with the working counter right and the drive enabled throughout. When the master stops,
    the drive reports the lost synchronisation in its statusword and a CoE emergency, as the
    CMMP-AS does (`test_ethercat.py`): a master held off the CPU for three cycles sees a
    fault, not a drive that stands enabled and no longer follows. Master and twin run at
    SCHED_FIFO where allowed, as a DC master and a drive's firmware do."""
    with ecat_twin_run(veth, tmp_path, "--config", str(cell(tmp_path)), realtime=True) as (master_if, _):
        master = pysoem.Master()
        master.open(master_if)
        try:
            with Realtime():
                _follow_on_dc(master)
        finally:
            master.close()


def _follow_on_dc(master) -> None:
    assert master.config_init() == 1
    s = master.slaves[0]
    assign_csp(s)
    assert master.config_dc(), "the slave has distributed clocks"
    s.dc_sync(True, CYCLE_MS * 1_000_000)
    master.config_map()
    assert (len(s.output), len(s.input)) == (6, 6)
    assert master.state_check(pysoem.SAFEOP_STATE, 5_000_000) == pysoem.SAFEOP_STATE, hex(s.al_status)

    cycle = Cycles(master, s)
    cycle.to_op()
    cycle.enable()
    step = 50
    # A set-point goes out in cycle n, is taken at the next SYNC0 and shows in the inputs
    # latched at a SYNC0 after it: the position lags a few set-points, never more.
    lag_max = 4 * step
    bad_wkc = 0
    behind = []
    for n in range(DC_CYCLES):
        cycle.target += step
        wkc, sw, pos = cycle(0x0F)
        bad_wkc += wkc != master.expected_wkc
        if n >= 4 and not -step <= cycle.target - pos <= lag_max + step:
            behind.append((n, cycle.target - pos, hex(sw)))
    assert bad_wkc == 0
    assert sw & 0x6F == 0x27, hex(sw)
    assert behind == [], f"{len(behind)} of {DC_CYCLES} cycles off the set-points, first {behind[:5]}"
    assert master.read_state() == pysoem.OP_STATE, hex(s.al_status)

    # The master stops for 0.2 s (20 SYNC0 cycles): the slave falls back to Safe-Op with the
    # synchronisation error and takes no more set-points, and the drive says so (CiA 402
    # 8700h "sync controller", Fault) instead of standing enabled on the last one.
    time.sleep(0.2)
    master.read_state()
    assert s.state == pysoem.SAFEOP_STATE | pysoem.STATE_ERROR, hex(s.state)
    assert s.al_status == 0x001A, hex(s.al_status)
    emergencies = []
    s.add_emergency_callback(emergencies.append)
    sw = struct.unpack("<H", s.sdo_read(0x6041, 0)[:2])[0]
    assert sw & 0x08, f"the drive reports the error: statusword {sw:#06x}"
    assert [(e.error_code, e.error_reg) for e in emergencies] == [(0x8700, 0x11)], emergencies


def test_an_eds_with_its_own_sync_manager_objects_is_refused(veth, tmp_path):
    """A file that lists 1C12h itself (as a CoE device's might) is refused at start, naming
    the object and what to change."""
    lines = EDS.read_text().splitlines()
    at = lines.index("[OptionalObjects]")
    count = int(lines[at + 1].split("=")[1])
    lines[at + 1] = f"SupportedObjects={count + 1}"
    lines.insert(at + 2 + count, f"{count + 1}=0x1C12")
    lines += ["", "[1C12]", "ParameterName=RxPDO assign", "ObjectType=0x7", "DataType=0x0005",
              "AccessType=rw", "DefaultValue=0", "PDOMapping=0"]
    eds = tmp_path / "own_1c12.eds"
    eds.write_text("\n".join(lines) + "\n")
    ns, twin_if, _ = veth
    r = subprocess.run(["ip", "netns", "exec", ns, str(DRIVETWIN_BIN), "run", "--ethercat", twin_if,
                        "--config", str(cell(tmp_path, eds))], capture_output=True, text=True, timeout=30)
    assert r.returncode != 0, r.stdout
    assert "1C12h, a sync manager object of EtherCAT" in r.stderr and "remove it" in r.stderr, r.stderr
