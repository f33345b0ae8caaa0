"""The cell FMU's FMI-LS-BUS CAN terminal (FMI-LS-BUS 1.0, Network Abstraction;
docs/cosimulation.md), met by fmpy's low-level FMI 3 API the way a master FMU's importer uses
it: a CAN Transmit of an SDO upload request of 1018h:01 set on `can0.Rx_Data` with a tick of
`can0.Rx_Clock` crosses the cell's 125 kbit/s bus, and the drive's answer comes back as a CAN
Transmit on `can0.Tx_Data` with a tick of `can0.Tx_Clock`, in the microsecond in which the two
frames' bits (ISO 11898-1, stuff bits included) have crossed the bus. The operations are
packed and read here from the layered standard's tables, not with drivetwin's codec."""

from __future__ import annotations

import struct
import subprocess
import zipfile
import xml.etree.ElementTree as ET

import pytest

from conftest import DRIVETWIN_BIN, REPO_ROOT

fmpy = pytest.importorskip("fmpy")
from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

CELL = REPO_ROOT / "examples" / "cell_fmu" / "cell.toml"
BITRATE = 125_000  # the CMMP-AS's DIP switches at their factory setting
FESTO = 0x1D  # 1018h:01, vendor-ID
US = 1e-6
NOTIFICATIONS = "org.fmi_standard.fmi_ls_bus.Can_BusNotifications"  # §4.4.1.3


@pytest.fixture(scope="module")
def cell_fmu(tmp_path_factory, cell_library):
    """The example cell without a timeline (the drive waits pre-operational, its SDO server
    answering), packed by the binary under test with the library of its profile."""
    out = tmp_path_factory.mktemp("cell_fmu_ls_bus") / "cell.fmu"
    subprocess.run(
        [str(DRIVETWIN_BIN), "fmu", "--config", str(CELL), "--output", str(out),
         "--library", str(cell_library)],
        check=True, cwd=REPO_ROOT, timeout=60,
    )
    return str(out)


# --- FMI-LS-BUS 1.0 §4.4.1: CAN operations, little-endian -----------------------------------

def can_transmit(can_id: int, data: bytes) -> bytes:
    """CAN Transmit (0x10): OP Code, Length = 16 + DL, ID, Ide, Rtr, Data Length, Data."""
    return struct.pack("<IIIBBH", 0x10, 16 + len(data), can_id, 0, 0, len(data)) + data


def operations(binary: bytes) -> list[tuple[int, bytes]]:
    """(OP Code, arguments) of each operation in a binary value."""
    ops, at = [], 0
    while at < len(binary):
        code, length = struct.unpack_from("<II", binary, at)
        assert length >= 8 and at + length <= len(binary), binary[at:].hex()
        ops.append((code, binary[at + 8:at + length]))
        at += length
    return ops


def transmitted(binary: bytes) -> list[tuple[int, bytes]]:
    """(ID, data) of each CAN Transmit."""
    out = []
    for code, args in operations(binary):
        assert code == 0x10, f"not a CAN Transmit: {code:#x}"
        can_id, ide, rtr, dl = struct.unpack_from("<IBBH", args)
        assert (ide, rtr) == (0, 0) and len(args) == 8 + dl
        out.append((can_id, args[8:]))
    return out


# --- ISO 11898-1: the bits a classic base frame occupies ------------------------------------

def frame_bits(can_id: int, data: bytes) -> int:
    bits = [0] + [(can_id >> i) & 1 for i in range(10, -1, -1)] + [0, 0, 0]  # SOF id RTR IDE r0
    bits += [(len(data) >> i) & 1 for i in range(3, -1, -1)]
    for b in data:
        bits += [(b >> i) & 1 for i in range(7, -1, -1)]
    crc = 0
    for bit in bits:  # CRC-15, x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1
        top = (crc >> 14) & 1
        crc = (crc << 1) & 0x7FFF
        if top != bit:
            crc ^= 0x4599
    bits += [(crc >> i) & 1 for i in range(14, -1, -1)]
    stuff, run, last = 0, 0, None
    for bit in bits:
        run = run + 1 if bit == last else 1
        last = bit
        if run == 5:
            stuff, last, run = stuff + 1, 1 - bit, 1
    return len(bits) + stuff + 1 + 2 + 7 + 3  # CRC delimiter, ACK, EOF, intermission


# --- the importer -----------------------------------------------------------------------------

class Cell:
    """fmpy's FMU3Slave, stepped with event mode as the layered standard has it."""

    def __init__(self, path: str, notifications: bool = False):
        md = read_model_description(path)
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU3Slave(guid=md.guid, unzipDirectory=extract(path),
                             modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName="cell")
        self.fmu.instantiate(eventModeUsed=True)
        if notifications:
            self.fmu.setBoolean([self.vr[NOTIFICATIONS]], [True])
        self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.exitInitializationMode()
        self.fmu.updateDiscreteStates()
        self.fmu.enterStepMode()
        self.t = 0.0

    def step(self, h: float) -> bytes | None:
        """One doStep; the operations of a Tx_Clock tick, if the step asks for Event Mode."""
        event, terminate, early, _ = self.fmu.doStep(self.t, h)
        assert not terminate and not early
        self.t += h
        if not event:
            return None
        self.fmu.enterEventMode()
        ticked, = self.fmu.getClock([self.vr["can0.Tx_Clock"]])
        data, = self.fmu.getBinary([self.vr["can0.Tx_Data"]])
        self.fmu.updateDiscreteStates()
        self.fmu.enterStepMode()
        assert ticked
        return data

    def receive(self, binary: bytes) -> bytes | None:
        """An Event Mode in which `binary` is set on Rx_Data and Rx_Clock ticks; the answer
        on Tx, if Tx_Clock ticks at once."""
        self.fmu.enterEventMode()
        self.fmu.setBinary([self.vr["can0.Rx_Data"]], [binary])
        self.fmu.setClock([self.vr["can0.Rx_Clock"]], [True])
        self.fmu.updateDiscreteStates()
        ticked, = self.fmu.getClock([self.vr["can0.Tx_Clock"]])
        data, = self.fmu.getBinary([self.vr["can0.Tx_Data"]]) if ticked else (None,)
        self.fmu.enterStepMode()
        return data

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def test_fmpy_validates_the_terminal_and_its_layered_standard_files(cell_fmu):
    assert validate_fmu(cell_fmu) == []
    md = read_model_description(cell_fmu)
    v = {x.name: x for x in md.modelVariables}
    assert md.coSimulation.hasEventMode
    for name, causality, kind in [("Rx_Data", "input", "Binary"), ("Rx_Clock", "input", "Clock"),
                                  ("Tx_Data", "output", "Binary"), ("Tx_Clock", "output", "Clock")]:
        assert (v[f"can0.{name}"].causality, v[f"can0.{name}"].type) == (causality, kind)
    with zipfile.ZipFile(cell_fmu) as z:
        terminals = ET.fromstring(z.read("terminalsAndIcons/terminalsAndIcons.xml"))
        manifest = ET.fromstring(z.read("extra/org.fmi-standard.fmi-ls-bus/fmi-ls-manifest.xml"))
    t, = terminals.iter("Terminal")
    assert (t.get("terminalKind"), t.get("matchingRule")) == (
        "org.fmi-ls-bus.network-terminal", "org.fmi-ls-bus.transceiver")
    members = {m.get("memberName"): m.get("variableName") for m in t.iter("TerminalMemberVariable")}
    assert members == {m: f"can0.{m}" for m in ["Rx_Data", "Rx_Clock", "Tx_Data", "Tx_Clock"]}
    ls = "{http://fmi-standard.org/fmi-ls-manifest}"
    assert manifest.get(f"{ls}fmi-ls-name") == "org.fmi-standard.fmi-ls-bus"
    assert manifest.get(f"{ls}fmi-ls-version") == "1.0.0"
    assert manifest.get("isBusSimulationFMU") == "false"


def test_an_sdo_upload_on_rx_is_answered_on_tx_at_the_time_the_bus_takes(cell_fmu):
    cell = Cell(cell_fmu)
    try:
        # The drive boots at 0: its boot-up message is on Tx after the first step.
        seen = []
        for _ in range(10):
            ops = cell.step(1e-3)
            if ops is not None:
                seen += transmitted(ops)
        assert (0x701, b"\x00") in seen
        t0 = cell.t
        request = bytes([0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])  # upload 1018h:01 (CiA 301)
        assert cell.receive(can_transmit(0x601, request)) is None
        answer = None
        for _ in range(5000):
            ops = cell.step(US)
            if ops is not None:
                answer = transmitted(ops)
                break
        assert answer is not None, "no answer in 5 ms"
        expected = bytes([0x43, 0x18, 0x10, 0x01]) + struct.pack("<I", FESTO)
        assert answer == [(0x581, expected)]
        # The request crosses, the drive answers at its end of frame, the answer crosses.
        bits = frame_bits(0x601, request) + frame_bits(0x581, expected)
        crossed = t0 + bits / BITRATE
        assert cell.t - US - 1e-9 < crossed <= cell.t + 1e-9, (crossed, cell.t)
    finally:
        cell.close()


def test_an_unreadable_operation_is_answered_with_a_format_error(cell_fmu):
    cell = Cell(cell_fmu)
    try:
        cell.step(1e-3)
        junk = struct.pack("<II", 0x77, 9) + b"\xAA"
        ops = operations(cell.receive(junk))
        assert ops == [(0x01, struct.pack("<H", len(junk)) + junk)]
    finally:
        cell.close()


def test_with_bus_notifications_the_request_is_confirmed_at_its_end_of_frame(cell_fmu):
    """FMI-LS-BUS §4.4.1.2.2: with `Can_BusNotifications` set, the master's frame that a drive
    received is confirmed (Confirm, 0x20, its ID) in the step in which its bits have crossed,
    before the drive's answer; without it (the default) no Confirm comes."""
    md = read_model_description(cell_fmu)
    v = {x.name: x for x in md.modelVariables}
    assert (v[NOTIFICATIONS].causality, v[NOTIFICATIONS].type) == ("structuralParameter", "Boolean")
    cell = Cell(cell_fmu, notifications=True)
    try:
        for _ in range(10):
            cell.step(1e-3)
        t0 = cell.t
        request = bytes([0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])
        assert cell.receive(can_transmit(0x601, request)) is None
        got = []
        for _ in range(5000):
            ops = cell.step(US)
            if ops is not None:
                got += [(cell.t, code, args) for code, args in operations(ops)]
            if any(code == 0x10 for _, code, _ in got):
                break
        (t_confirm, code, args), (_, answer, _) = got
        assert (code, args) == (0x20, struct.pack("<I", 0x601))
        assert answer == 0x10
        crossed = t0 + frame_bits(0x601, request) / BITRATE
        assert t_confirm - US - 1e-9 < crossed <= t_confirm + 1e-9, (crossed, t_confirm)
    finally:
        cell.close()
