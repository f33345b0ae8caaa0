"""A Nanotec SMCI47-S with a BLDC motor on its Hall sensors, chosen in the cell file
(`motor_type = "bldc-hall"`), moved in Profile Position by python-canopen's BaseNode402 over
socketcand against the real binary (the manual's text kept beside the project,
seeds/003_ef071fe40f10c01c.txt §1.2 "Motortyp", §11.5 2004h:07 / 2004h:0C, Appendix 18.2;
spec/nanotec-canopen.md §6).

What it shows: the cell starts with the motor the file names (2004h:07 = 1, closed loop
200Ah = 1, the BLDC load-angle curve of Appendix 18.2 in 200Ch), and the actual position
6064h climbs to the PP target counted in Hall edges: the DB57-like default motor has 4 pole
pairs, 6 × 4 = 24 Hall edges a revolution, so every reading is a whole number of
2000 / 24 user units (2000 user units = one revolution, 6092h default).
"""

from __future__ import annotations

import time
from pathlib import Path

from conftest import CHANNEL, wait_until
from test_nanotec_cia402 import enable, node402

NODE = 34
EDGES_PER_REV = 24  # 6 Hall states × 4 pole pairs (drive::bldc::BldcData::default())
UNITS_PER_REV = 2000  # 6092h = 2000 / 1 (§6)
TARGET = 4000  # two revolutions


def bldc_cell(path: Path, motor_type: str) -> Path:
    path.write_text("\n".join([
        "[bus]",
        'socketcand = "127.0.0.1:1"',
        f'channel = "{CHANNEL}"',
        "",
        "[[drive]]",
        'device = "nanotec-smci47s"',
        f"node = {NODE}",
        f'motor_type = "{motor_type}"',
        "",
    ]))
    return path


def hall_edges(units: int) -> float:
    """A position in user units as a number of Hall edges."""
    return units * EDGES_PER_REV / UNITS_PER_REV


def test_bldc_from_the_cell_file_climbs_to_its_pp_target_in_hall_edges(
        tmp_path, launch, connect, eds_files):
    twin = launch(config=bldc_cell(tmp_path / "cell.toml", "bldc-hall"))
    node = node402(connect(twin), NODE, eds_files["nanotec-smci47s"])
    # The motor the cell file names, set at start-up.
    assert node.sdo[0x2004][7].raw == 1, "2004h:07 = 1: BLDC with Hall sensors"
    assert node.sdo[0x2004][0x0C].raw == 0x243015, "the default Hall table (DB57)"
    assert [node.sdo[0x200C][n].raw for n in range(1, 8)] == [
        16384, 16500, 17000, 17500, 18000, 18500, 19000], "Appendix 18.2"
    enable(node, "PROFILED POSITION")
    assert node.sdo[0x200A].raw == 1, "a BLDC runs closed loop"
    start = node.sdo[0x6064].raw
    node.sdo[0x6081].raw = 2000  # 1 rev/s
    node.sdo[0x6083].raw = 8000
    node.sdo[0x6084].raw = 8000
    node.sdo[0x607A].raw = TARGET
    node.controlword = 0x1F
    wait_until(lambda: node.sdo[0x6041].raw & 0x1000, 1.0, what="set-point acknowledge")
    node.controlword = 0x0F
    step = UNITS_PER_REV / EDGES_PER_REV
    near = 2 * step + 1  # the Hall-only position loop settles within two edges (see below)
    readings = []
    t0 = time.monotonic()
    while time.monotonic() - t0 < 10.0:
        readings.append(node.sdo[0x6064].raw)
        # The profile is over (6062h at the target) and the shaft near it.
        if (len(readings) >= 3 and all(abs(p - TARGET) <= near for p in readings[-3:])
                and node.sdo[0x6062].raw == TARGET):
            break
        time.sleep(0.05)
    # It climbed: many readings on the way, in order (one Hall edge of jitter allowed: the
    # speed seen through 24 edges a turn is coarse, the motion jerky).
    between = [p for p in readings if start + 100 < p < TARGET - 100]
    assert len(between) >= 5, f"seen on the way: {readings}"
    assert all(b >= a - step - 1 for a, b in zip(readings, readings[1:])), readings
    # At the target within two Hall edges. Hall-only (2004h:07 = 1), the position and speed
    # feedback are the 24 edges a turn: the servo cascade's speed estimate from one edge
    # per controller cycle is coarse, and at standstill the shaft hunts by an edge beside
    # the target instead of settling on it (target reached, bit 10, comes and goes).
    assert abs(readings[-1] - TARGET) <= near, readings
    # Every reading is a whole number of Hall edges (6064h rounds to a user unit).
    for p in readings:
        e = hall_edges(p)
        assert abs(e - round(e)) <= EDGES_PER_REV / UNITS_PER_REV, f"{p} is not on a Hall edge"
