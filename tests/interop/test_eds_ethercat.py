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

import struct
import subprocess
import time
from pathlib import Path

import pytest

from conftest import DRIVETWIN_BIN, ecat_twin_run

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
            for index, pdos in ((0x1C12, (0x1600, 0x1602)), (0x1C13, (0x1A02,))):
                s.sdo_write(index, 0, bytes([0]))
                for k, pdo in enumerate(pdos, 1):
                    s.sdo_write(index, k, struct.pack("<H", pdo))
                s.sdo_write(index, 0, bytes([len(pdos)]))
            s.sdo_write(0x6060, 0, bytes([8]))
            master.config_map()
            assert (len(s.output), len(s.input)) == (6, 6)
            assert master.state_check(pysoem.SAFEOP_STATE, 5_000_000) == pysoem.SAFEOP_STATE

            target = 0
            due = time.monotonic()

            def cycle(cw: int) -> tuple[int, int, int]:
                nonlocal due
                s.output = struct.pack("<Hi", cw, target)
                master.send_processdata()
                wkc = master.receive_processdata(100_000)
                due += CYCLE_S
                time.sleep(max(0.0, due - time.monotonic()))
                sw, pos = struct.unpack("<Hi", bytes(s.input))
                return wkc, sw, pos

            master.state = pysoem.OP_STATE
            cycle(0)
            master.write_state()
            for _ in range(100):
                cycle(0)
                if master.read_state() == pysoem.OP_STATE:
                    break
            assert s.state == pysoem.OP_STATE, hex(s.al_status)
            _, _, target = cycle(0)
            bad_wkc = 0
            for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)):
                for _ in range(100):
                    wkc, sw, pos = cycle(cw)
                    bad_wkc += wkc != master.expected_wkc
                    if sw & 0x6F == want:
                        break
                assert sw & 0x6F == want, hex(sw)
            assert s.sdo_read(0x6061, 0)[0] == 8, "CSP"
            start = target
            for _ in range(100):
                target += 50
                wkc, sw, pos = cycle(0x0F)
                bad_wkc += wkc != master.expected_wkc
            for _ in range(10):
                wkc, sw, pos = cycle(0x0F)
                bad_wkc += wkc != master.expected_wkc
            assert bad_wkc == 0
            assert sw & 0x6F == 0x27, hex(sw)
            assert target == start + 5000
            assert abs(pos - target) < 50, (pos, target)
            assert master.read_state() == pysoem.OP_STATE
        finally:
            master.close()


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
