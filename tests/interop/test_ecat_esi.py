"""`drivetwin esi` says what the slave says: the ESI of each drive that speaks EtherCAT, parsed
here, against what SOEM (pysoem) and `drivetwin ecat` read back from the running twin over a
veth pair: identity (vendor, product code, revision: SII words 8–0Dh), the sync managers SOEM
configures from the SII (start addresses and control bytes read back from 0x0800), the default
PDO assignment and its mapping read over CoE (1C12h / 1C13h, 1600h / 1A00h), and the object
list of the CoE dictionary (SDO information) against the ESI's `<Dictionary>` (the ESI lists
the objects the device file hides from CoE as well: `coe_hidden`).

Every drive that speaks EtherCAT: the CMMP-AS (its device file's `[device.ethercat]`) and the
generic CiA 402 drive from an EDS (`drivetwin esi --eds FILE`: the file's dictionary with the
sync manager objects the twin adds on EtherCAT). Needs root and `ip`; skips otherwise.
"""

from __future__ import annotations

import json
import struct
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from conftest import ecat_twin_run, run_cli

pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")

ROOT = Path(__file__).resolve().parents[2]


def hexnum(text: str) -> int:
    text = text.strip()
    return int(text[2:], 16) if text.startswith("#x") else int(text)


def esi_of(*args: str) -> ET.Element:
    r = run_cli("esi", *args)
    assert r.returncode == 0, r.stderr
    return ET.fromstring(r.stdout)


def esi_facts(root: ET.Element) -> dict:
    dev = root.find("./Descriptions/Devices/Device")
    ty = dev.find("Type")
    pdos = {}
    for tag in ("RxPdo", "TxPdo"):
        for p in dev.findall(tag):
            if p.get("Sm") is None:
                continue
            pdos[hexnum(p.findtext("Index"))] = [
                (hexnum(e.findtext("Index")), int(e.findtext("SubIndex") or 0), int(e.findtext("BitLen")))
                for e in p.findall("Entry")
            ]
    return {
        "vendor": hexnum(root.findtext("./Vendor/Id")),
        "product": hexnum(ty.get("ProductCode")),
        "revision": hexnum(ty.get("RevisionNo")),
        "sms": [(hexnum(sm.get("StartAddress")), hexnum(sm.get("ControlByte"))) for sm in dev.findall("Sm")],
        "assigned": {sm: [hexnum(p.findtext("Index")) for p in dev.findall(tag) if p.get("Sm") == sm]
                     for tag, sm in (("RxPdo", "2"), ("TxPdo", "3"))},
        "pdos": pdos,
        "objects": sorted(hexnum(o.findtext("Index"))
                          for o in dev.findall("./Profile/Dictionary/Objects/Object")),
        # (AssignActivate, SYNC0 at the master's cycle) of each `Dc/OpMode`.
        "dc": [(hexnum(m.findtext("AssignActivate")),
                m.find("CycleTimeSync0") is not None and m.find("CycleTimeSync0").get("Factor") == "1")
               for m in dev.findall("./Dc/OpMode")],
    }


def read_back(master_if: str) -> dict:
    """What SOEM reads from the one slave on `master_if`."""
    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 1
        s = master.slaves[0]
        u8 = lambda i, sub: s.sdo_read(i, sub)[0]
        u16 = lambda i, sub: struct.unpack("<H", s.sdo_read(i, sub)[:2])[0]
        u32 = lambda i, sub: struct.unpack("<I", s.sdo_read(i, sub)[:4])[0]
        assigned = {sm: [u16(i, k) for k in range(1, u8(i, 0) + 1)]
                    for sm, i in (("2", 0x1C12), ("3", 0x1C13))}
        pdos = {}
        for pdo in assigned["2"] + assigned["3"]:
            pdos[pdo] = [((v >> 16), (v >> 8) & 0xFF, v & 0xFF)
                         for v in (u32(pdo, k) for k in range(1, u8(pdo, 0) + 1)) if v]
        master.config_map()
        raw = s._fprd(0x0800, 32, 100_000)
        sms = [(struct.unpack_from("<H", raw, 8 * n)[0], raw[8 * n + 4]) for n in range(4)]
        # ESC features 0008h bit 2: distributed clocks. SOEM's DC set-up (ecx_configdc, then
        # ecx_dcsync0 at 1 ms, the drives' default 60C2h) writes 0980h-0981h; read back.
        dc_supported = bool(struct.unpack("<H", s._fprd(0x0008, 2, 100_000))[0] & 0x0004)
        master.config_dc()
        s.dc_sync(1, 1_000_000)
        assign_activate = struct.unpack("<H", s._fprd(0x0980, 2, 100_000))[0]
        cycle = struct.unpack("<I", s._fprd(0x09A0, 4, 100_000))[0]
        return {
            "vendor": s.man, "product": s.id, "revision": s.rev,
            "assigned": assigned, "pdos": pdos, "sms": sms,
            "objects": sorted(o.index for o in s.od),
            "dc_supported": dc_supported, "dc_sync0": (assign_activate, cycle),
        }
    finally:
        master.close()


def check(esi: dict, got: dict, hidden: list[int]) -> None:
    assert (got["vendor"], got["product"], got["revision"]) == (esi["vendor"], esi["product"], esi["revision"])
    assert got["sms"] == esi["sms"], "SMs as SOEM configured them from the SII"
    assert got["assigned"] == esi["assigned"], "1C12h / 1C13h"
    assert got["pdos"] == esi["pdos"], "the default mapping read over CoE"
    assert got["objects"] == sorted(set(esi["objects"]) - set(hidden)), "the CoE dictionary"
    # The ESI offers DC where the ESC has it, and its SYNC0 mode is what SOEM's DC set-up
    # leaves in 0980h-0981h (SYNC0 at the cycle SOEM gave, Factor 1 of the master's cycle).
    assert got["dc_supported"] and esi["dc"], "a DC slave describes its Dc modes"
    assert (0x0000, False) in esi["dc"], "SM-synchronous"
    assert (got["dc_sync0"][0], True) in esi["dc"], f"SYNC0 as SOEM set it: {got['dc_sync0']}"
    assert got["dc_sync0"][1] == 1_000_000, "SYNC0 cycle 09A0h"


def test_the_cmmp_as_esi_is_what_soem_reads_back(veth, tmp_path):
    esi = esi_facts(esi_of("--device", "cmmp-as"))
    hidden = tomllib.loads((ROOT / "devices" / "cmmp-as.toml").read_text())["device"]["ethercat"]["coe_hidden"]
    with ecat_twin_run(veth, tmp_path) as (master_if, _):
        check(esi, read_back(master_if), hidden)
        # The twin's own master reads the same identity.
        scan = json.loads(run_cli("ecat", "scan", "-i", master_if, "--json").stdout)
        (s,) = scan["slaves"]
        assert (s["vendor_id"], s["product_code"]) == (esi["vendor"], esi["product"]), s


def test_the_eds_drive_esi_is_what_soem_reads_back(veth, tmp_path):
    eds = ROOT / "tests" / "interop" / "data" / "eds" / "epos4_like.eds"
    esi = esi_facts(esi_of("--eds", str(eds)))
    assert (esi["vendor"], esi["product"], esi["revision"]) == (0xFB, 0x65500000, 0x01700000)
    assert esi["assigned"] == {"2": [0x1600], "3": [0x1A00]}
    assert {0x1C00, 0x1C12, 0x1C13} <= set(esi["objects"])
    cell = tmp_path / "eds.toml"
    cell.write_text(f'[[drive]]\neds = "{eds}"\ninterfaces = ["ethercat"]\n')
    with ecat_twin_run(veth, tmp_path, "--config", str(cell)) as (master_if, _):
        check(esi, read_back(master_if), [])


def device_files() -> list[dict]:
    return [tomllib.loads(p.read_text())["device"] for p in sorted((ROOT / "devices").glob("*.toml"))]


@pytest.mark.parametrize("device", [d for d in device_files() if "ethercat" not in d.get("interfaces", [])],
                         ids=lambda d: d["name"])
def test_the_esi_of_a_device_without_ethercat_is_refused(device, tmp_path):
    """A device without an EtherCAT interface has no ESI: `drivetwin esi` refuses it with a
    usage error (exit code 2) naming the device and the interfaces it has, and writes no
    file a configurator could import."""
    out = tmp_path / "device.xml"
    r = run_cli("esi", "--device", device["name"], "--output", str(out))
    assert r.returncode == 2, r
    assert not out.exists(), "no file written"
    assert r.stdout == ""
    assert device["name"] in r.stderr and "no EtherCAT interface" in r.stderr, r.stderr
    for interface in device.get("interfaces", []):
        assert interface in r.stderr, r.stderr
