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
        return {
            "vendor": s.man, "product": s.id, "revision": s.rev,
            "assigned": assigned, "pdos": pdos, "sms": sms,
            "objects": sorted(o.index for o in s.od),
        }
    finally:
        master.close()


def check(esi: dict, got: dict, hidden: list[int]) -> None:
    assert (got["vendor"], got["product"], got["revision"]) == (esi["vendor"], esi["product"], esi["revision"])
    assert got["sms"] == esi["sms"], "SMs as SOEM configured them from the SII"
    assert got["assigned"] == esi["assigned"], "1C12h / 1C13h"
    assert got["pdos"] == esi["pdos"], "the default mapping read over CoE"
    assert got["objects"] == sorted(set(esi["objects"]) - set(hidden)), "the CoE dictionary"


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
