"""A Nanotec SMCI47-S twin (`drivetwin run --device nanotec-smci47s --node 34`) driven over
socketcand by python-canopen's BaseNode402 with the drive's EDS, and by `drivetwin drive` (the
manual and its extract, kept beside the project as seeds/003_ef071fe40f10c01c.txt and
spec/nanotec-canopen.md §5): PP, HM (35, the switch method 19, the index method 33), VL (6060h =
2), IP on a 10 ms SYNC and TQ in closed loop, each asserting that the simulated shaft moves as
physics says, not that a value is echoed; the software-limit EMCY 0800h (§7.1) through
python-canopen's EMCY consumer; one python-canopen network moving a CMMP-AS (node 1) and the
Nanotec (node 34) of one cell file at the same time.

Units at the defaults (§6): 2000 user units per output revolution (6092h = 2000 / 1), PP and
homing speeds in user units/s; VL speeds in the units of 604Ch = 60 / 2000 (1000 = 30 min⁻¹ =
1000 user units/s).
"""

from __future__ import annotations

import threading
import time

import can
import pytest
from canopen import SdoAbortedError
from canopen.profiles.p402 import BaseNode402

from conftest import (DRIVETWIN_BIN, HOST, Realtime, cmmp_switches, realtime_prefix, run_cli,
                      wait_until, write_cell)

NODE = 34
PERIOD = 0.010  # SYNC, s


def node402(net, node_id: int, eds, nanotec: bool = True) -> BaseNode402:
    """A BaseNode402 on `net` with its PDOs read.

    A Nanotec's default TPDO1 is the statusword on change (§2.6), which BaseNode402 takes as
    its statusword: the node goes Operational, and TPDO1 is commissioned for a master that
    polls it: the 100 ms default inhibit time set to 0 and an event timer of 10 ms (1800h:03
    and :05, written with the PDO disabled as CiA 301 wants). BaseNode402 reads the cached
    TPDO value right after a controlword (100 ms inhibit would show it a stale state), and
    once it has seen two TPDOs it waits for a fresh one at most 0.2 s (an on-change-only TPDO
    would time out while nothing changes, e.g. during homing). The CMMP-AS stays
    Pre-Operational: BaseNode402 then reads its statusword by SDO."""
    node = BaseNode402(node_id, str(eds))
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    node.nmt.state = "PRE-OPERATIONAL"
    if nanotec:
        node.tpdo.read()
        node.tpdo[1].inhibit_time = 0
        node.tpdo[1].event_timer = 10
        node.tpdo[1].save()
        assert node.sdo[0x1800][3].raw == 0 and node.sdo[0x1800][5].raw == 10
    node.setup_402_state_machine()
    if nanotec:
        node.nmt.state = "OPERATIONAL"
        node.tpdo[1].wait_for_reception(1.0)
    return node


@pytest.fixture
def nanotec(launch, connect, eds_files):
    twin = launch("nanotec-smci47s", NODE)
    node = node402(connect(twin), NODE, eds_files["nanotec-smci47s"])
    return twin, node


def position(node) -> int:
    return node.sdo[0x6064].raw


def speed(read, seconds: float) -> tuple[float, float]:
    """The shaft's speed from two readings of `read()` `seconds` apart, as the least and the
    most it can be given how long each reading took (units/s): a loaded machine delays
    replies, not the simulated motor."""
    t0 = time.monotonic()
    a = read()
    t1 = time.monotonic()
    time.sleep(seconds)
    t2 = time.monotonic()
    b = read()
    t3 = time.monotonic()
    moved = b - a
    return moved / (t3 - t0), moved / max(t2 - t1, 1e-3)


def assert_speed(read, seconds: float, low: float, high: float):
    """The speed over `seconds` lies in [low, high] units/s (see `speed`)."""
    least, most = speed(read, seconds)
    if low < 0:
        least, most = most, least
    assert least <= high and most >= low, f"{least:.0f} … {most:.0f} units/s, not in {low} … {high}"
    return least, most


def enable(node, mode: str):
    node.op_mode = mode
    assert node.op_mode == mode, "6061h shows the mode"
    node.state = "OPERATION ENABLED"
    assert node.sdo[0x6041].raw & 0x6F == 0x27


def pp_move(node, target: int, timeout: float = 5.0) -> float:
    """Absolute PP move with the set-point handshake (§5.1); the time to target reached."""
    node.sdo[0x607A].raw = target
    t0 = time.monotonic()
    node.controlword = 0x1F
    wait_until(lambda: node.sdo[0x6041].raw & 0x1000, 1.0, what="set-point acknowledge")
    node.controlword = 0x0F
    wait_until(lambda: node.sdo[0x6041].raw & 0x1400 == 0x0400, timeout, interval=0.01,
               what="target reached")
    return time.monotonic() - t0


def test_state_machine_and_the_modes_of_6502h(nanotec):
    _, node = nanotec
    assert node.sdo[0x6502].raw == 0x6B
    assert node.state == "SWITCH ON DISABLED"
    assert node.statusword == 0x0260, "§2.4: bit 5 and bit 9 set in Switch On Disabled"
    node.state = "OPERATION ENABLED"
    assert node.statusword == 0x0237
    for mode in ("PROFILED POSITION", "VELOCITY", "HOMING", "INTERPOLATED POSITION"):
        node.op_mode = mode
        assert node.op_mode == mode
    # PV is not a Nanotec mode: BaseNode402 refuses it from 6502h, the drive from 6060h.
    with pytest.raises(TypeError):
        node.op_mode = "PROFILED VELOCITY"
    node.state = "SWITCH ON DISABLED"
    assert node.statusword & 0x4F == 0x40


def test_profile_position_moves_the_shaft_at_the_profile_speed(nanotec):
    _, node = nanotec
    enable(node, "PROFILED POSITION")
    node.sdo[0x6081].raw = 4000  # 2 rev/s
    node.sdo[0x6083].raw = 16000
    node.sdo[0x6084].raw = 16000
    took = pp_move(node, 8000)
    # Trapezoid: 0.25 s ramps each side, 8000 units at 4000 units/s cruise: 2.25 s in all.
    assert 2.0 < took < 4.5, took
    assert abs(position(node) - 8000) <= 2
    # Halfway through a move back the shaft is halfway.
    node.sdo[0x607A].raw = 0
    node.controlword = 0x1F
    wait_until(lambda: node.sdo[0x6041].raw & 0x1000, 1.0, what="set-point acknowledge")
    node.controlword = 0x0F
    time.sleep(1.0)
    mid = position(node)
    assert 2000 < mid < 6000, mid
    wait_until(lambda: node.sdo[0x6041].raw & 0x0400, 5.0, what="target reached")
    assert abs(position(node)) <= 2


def test_homing_35_and_switch_method_19(nanotec):
    _, node = nanotec
    # 35: the position becomes 607Ch, nothing moves (§5.2).
    node.sdo[0x607C].raw = 777
    node.sdo[0x6098].raw = 35
    assert node.homing(timeout=5)
    assert abs(position(node) - 777) <= 1
    # 19 from 1 revolution below the switch: clockwise at 6099h:01 onto the cam (0.61 rev
    # above the old zero, 1 rev ahead), counter-clockwise at 6099h:02 until it is free. The
    # shaft's travel takes its time at the speeds of 6099h.
    enable(node, "PROFILED POSITION")
    pp_move(node, 777 - 2000)
    node.sdo[0x607C].raw = 0
    node.sdo[0x6098].raw = 19
    node.sdo[0x6099][1].raw = 2000
    node.sdo[0x6099][2].raw = 400
    t0 = time.monotonic()
    assert node.homing(timeout=15)
    took = time.monotonic() - t0
    # 2 × 1.6 rev at 1 rev/s would be the minimum if nothing were simulated; the search alone
    # is 1.6 rev at 2000 units/s.
    assert took > 1.2, took
    assert node.sdo[0x6041].raw & 0x3400 == 0x1400, "homing attained, target reached"
    assert abs(position(node)) <= 2, "the home offset 0 at the switch edge"


def test_homing_33_reverses_off_the_index_mark(nanotec):
    """§5.2 method 33: clockwise at 6099h:02 to the index mark (a quarter output revolution,
    500 units, in the twin's default travel), reverse, off the mark, stop; the mark reads the
    home offset, the shaft stands just counter-clockwise of it."""
    _, node = nanotec
    node.sdo[0x6098].raw = 33
    node.sdo[0x6099][2].raw = 500
    node.sdo[0x607C].raw = 0
    t0 = time.monotonic()
    assert node.homing(timeout=10)
    # 500 units at 500 units/s out, then the short way back.
    assert time.monotonic() - t0 > 0.8
    assert -20 <= position(node) <= 0, position(node)


def test_velocity_mode_vl_turns_the_shaft(nanotec):
    _, node = nanotec
    enable(node, "VELOCITY")
    node.sdo[0x6042].raw = 1000
    # Bit 10 may still be the stopped drive's for a cycle: wait for the demand 6043h.
    wait_until(lambda: node.sdo[0x6043].raw == 1000, 3.0, what="the ramp's end")
    assert node.sdo[0x6041].raw & 0x0400, "speed reached"
    # 1000 VL units = 30 min⁻¹ = 1000 position units/s.
    assert_speed(lambda: position(node), 0.5, 900, 1100)
    # 6044h shows a value in closed loop only (§6.5: "Nur bei aktiviertem Closed Loop wird ein
    # Wert ausgegeben"); the factory drive runs open loop.
    assert node.sdo[0x200A].raw == 0
    assert {node.sdo[0x6044].raw for _ in range(20)} == {0}
    # Backwards (§5.3: negative = counter-clockwise).
    node.sdo[0x6042].raw = -1000
    wait_until(lambda: node.sdo[0x6043].raw == -1000, 3.0, what="reversed")
    assert_speed(lambda: position(node), 0.5, -1100, -900)
    # Above 6046h:02 clamps with bit 11 (§5.3).
    node.sdo[0x6046][2].raw = 1500
    node.sdo[0x6042].raw = 3000
    wait_until(lambda: node.sdo[0x6043].raw == 1500, 3.0, what="clamped to the maximum")
    assert node.sdo[0x6041].raw & 0x0800
    node.sdo[0x6042].raw = 0
    wait_until(lambda: node.sdo[0x6043].raw == 0, 3.0, what="stopped")


def test_vl_in_closed_loop_reads_a_steady_6044h(nanotec):
    """Closed loop (2001h = 1): 6044h is the measured speed, steady within a few % at
    6042h = 2000 (60 min⁻¹) however often a master polls it."""
    _, node = nanotec
    node.sdo[0x2001].raw = 1
    wait_until(lambda: node.sdo[0x200A].raw == 1, 1.0, what="closed loop on (200Ah)")
    enable(node, "VELOCITY")
    node.sdo[0x6042].raw = 2000
    wait_until(lambda: node.sdo[0x6043].raw == 2000, 3.0, what="the ramp's end")
    wait_until(lambda: abs(node.sdo[0x6044].raw - 2000) < 60, 2.0, what="6044h at the speed")
    samples = [node.sdo[0x6044].raw for _ in range(100)]
    assert all(abs(v - 2000) <= 60 for v in samples), samples


def test_torque_in_closed_loop_accelerates_to_the_607f_limit(nanotec):
    _, node = nanotec
    with pytest.raises(SdoAbortedError) as refused:
        node.op_mode = "PROFILED TORQUE"
    assert refused.value.code == 0x0800_0022, "refused in open loop (§5.5)"
    node.sdo[0x2001].raw = 1
    wait_until(lambda: node.sdo[0x200A].raw == 1, 1.0, what="closed loop on (200Ah)")
    node.sdo[0x607F].raw = 120  # min⁻¹: 2 rev/s = 4000 units/s
    enable(node, "PROFILED TORQUE")
    node.sdo[0x6071].raw = 300
    time.sleep(0.3)
    # At the 607Fh limit (the torque fades over its last 5 %).
    assert_speed(lambda: position(node), 0.5, 3500, 4100)
    node.sdo[0x6071].raw = -300
    time.sleep(0.5)
    assert_speed(lambda: position(node), 0.5, -4100, -3500)
    # Halt (bit 8) holds the motor: bit 10 with bit 8 = stopped (§5.5 table).
    node.controlword = 0x010F
    wait_until(lambda: node.sdo[0x6041].raw & 0x0400, 2.0, what="stopped")
    time.sleep(0.1)
    a = position(node)
    time.sleep(0.3)
    # Within a full step (10 units at 2000 units/rev): the closed loop's PI against the
    # shaft's friction may hunt by a few units at standstill, never by a step.
    assert abs(position(node) - a) < 10


class SyncProducer:
    """SYNC every PERIOD from its own socketcand connection (see test_ip_mode.py)."""

    def __init__(self, bus):
        self.bus = bus
        self.task = None

    def start(self):
        self.task = self.bus.send_periodic(
            can.Message(arbitration_id=0x080, data=b"", is_extended_id=False), PERIOD)

    def stop(self):
        if self.task is not None:
            self.task.stop()
            self.task = None


def test_interpolated_position_follows_sync_paced_set_points(launch, connect, raw_bus, eds_files):
    """§5.4: PLL on the SYNC (bit 8), 60C1h:01 taken at the next SYNC, bit 12 IP active."""
    with Realtime():
        twin = launch("nanotec-smci47s", NODE, prefix=realtime_prefix())
        node = node402(connect(twin), NODE, eds_files["nanotec-smci47s"])
        sync = SyncProducer(raw_bus(twin))
        try:
            sync.start()
            enable(node, "INTERPOLATED POSITION")
            wait_until(lambda: node.sdo[0x6041].raw & 0x0100, 3.0, what="PLL synchronised (bit 8)")
            start = node.sdo[0x6062].raw  # open loop: the demand (§5.4 caveat)
            node.sdo[0x60C1][1].raw = start
            node.controlword = 0x1F
            wait_until(lambda: node.sdo[0x6041].raw & 0x1000, 2.0, what="IP active (bit 12)")
            # 1.5 s of set-points, 30 units further every 10 ms: 3000 units/s = 1.5 rev/s.
            target = start
            t0 = time.monotonic()
            mid = None
            for k in range(150):
                target += 30
                node.sdo[0x60C1][1].raw = target
                if k == 75:
                    mid = position(node)
                delay = t0 + (k + 1) * PERIOD - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            assert mid is not None and 1000 < mid - start < 3500, mid - start
            wait_until(lambda: abs(position(node) - target) <= 5, 2.0, what="at the last set-point")
            assert node.sdo[0x607A].raw == target, "60C1h:01 and 607Ah are one variable"
        finally:
            sync.stop()


def test_software_limit_emcy_0800h_through_the_emcy_consumer(nanotec):
    """§5.1 / §7.1: a target beyond 607Dh:02 is refused with EMCY 0800h and bit 11; the next
    valid target runs."""
    _, node = nanotec
    enable(node, "PROFILED POSITION")
    node.sdo[0x607D][2].raw = 10000
    node.sdo[0x607A].raw = 20000
    node.controlword = 0x1F
    emcy = node.emcy.wait(0x0800, timeout=2)
    assert emcy is not None, "EMCY 0800h (position limit)"
    assert emcy.register & 0x01
    node.controlword = 0x0F
    assert node.sdo[0x6041].raw & 0x0800, "bit 11 internal limit"
    time.sleep(0.2)
    assert abs(position(node)) <= 2, "the move does not run"
    pp_move(node, 4000)
    assert abs(position(node) - 4000) <= 2
    assert node.sdo[0x6041].raw & 0x0800 == 0, "cleared by the next valid position"


def test_one_network_moves_a_cmmp_as_and_a_nanotec_at_once(launch, connect, eds_files, tmp_path):
    # The CMMP-AS's DIP6/DIP7 set to the Nanotec's 1 Mbit/s: one bus, one rate.
    cfg = write_cell(tmp_path / "cell.toml",
                     [("cmmp-as", 1, {}, cmmp_switches(1)), ("nanotec-smci47s", NODE, {})])
    twin = launch(config=cfg)
    net = connect(twin)
    cmmp = node402(net, 1, eds_files["cmmp-as"], nanotec=False)
    nano = node402(net, NODE, eds_files["nanotec-smci47s"])
    enable(cmmp, "PROFILED POSITION")
    enable(nano, "PROFILED POSITION")
    cmmp.sdo[0x6081].raw = 600  # min⁻¹
    nano.sdo[0x6081].raw = 2000  # 1 rev/s
    cmmp.sdo[0x607A].raw = 10 * 65536  # 10 rev at 10 rev/s
    nano.sdo[0x607A].raw = 2000  # 1 rev at 1 rev/s
    t0 = time.monotonic()
    for node in (cmmp, nano):
        node.controlword = 0x1F
    for node in (cmmp, nano):
        wait_until(lambda: node.sdo[0x6041].raw & 0x1000, 1.0, what="set-point acknowledge")
        node.controlword = 0x0F
    time.sleep(0.5)
    both = (cmmp.sdo[0x6064].raw, position(nano))
    assert 0 < both[0] < 10 * 65536 and 0 < both[1] < 2000, f"both on their way: {both}"
    for node in (cmmp, nano):
        wait_until(lambda: node.sdo[0x6041].raw & 0x0400, 5.0, what="target reached")
    assert time.monotonic() - t0 < 4.0
    assert abs(cmmp.sdo[0x6064].raw - 10 * 65536) <= cmmp.sdo[0x6067].raw
    assert abs(position(nano) - 2000) <= 2


def drive_cli(twin, *args: str) -> str:
    r = run_cli("drive", *args, "--socketcand", twin.addr, "--channel", "vcan0")
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_drivetwin_drive_moves_a_nanotec_and_a_cmmp_as(launch, tmp_path):
    """`drivetwin drive` (the CLI master) on both drives of one cell: a Nanotec has no 606Ch,
    6077h, 6078h, no PV and no 6087h; the CMMP-AS keeps its PV and its actual values."""
    import json

    # The CMMP-AS's DIP6/DIP7 set to the Nanotec's 1 Mbit/s: one bus, one rate.
    cfg = write_cell(tmp_path / "cell.toml",
                     [("cmmp-as", 1, {}, cmmp_switches(1)), ("nanotec-smci47s", NODE, {})])
    twin = launch(config=cfg)
    for node in ("1", str(NODE)):
        assert drive_cli(twin, node, "enable").startswith("OPERATION ENABLED")
    out = drive_cli(twin, str(NODE), "move", "4000", "--velocity", "4000", "--wait")
    assert "target reached" in out and "velocity n/a (no 606Ch)" in out, out
    state = json.loads(drive_cli(twin, str(NODE), "state", "--json"))
    assert abs(state["position"] - 4000) <= 2 and state["current_permille"] is None, state
    r = run_cli("drive", str(NODE), "velocity", "1000", "--wait", "--socketcand", twin.addr)
    assert r.returncode == 0 and "velocity mode VL" in r.stderr, r.stderr
    b = json.loads(drive_cli(twin, str(NODE), "state", "--json"))
    assert b["mode"] == 2 and b["velocity_object"] == "6044h"
    assert_speed(lambda: json.loads(drive_cli(twin, str(NODE), "state", "--json"))["position"],
                 0.3, 900, 1100)
    drive_cli(twin, str(NODE), "velocity", "0", "--wait")
    # The CMMP-AS: PP, PV, 606Ch, 6077h, 6078h as before.
    out = drive_cli(twin, "1", "move", "655360", "--wait")
    assert "target reached" in out and " mode 1 " in out and "n/a" not in out, out
    out = drive_cli(twin, "1", "velocity", "600", "--wait")
    assert " mode 3 " in out and "n/a" not in out, out
    state = json.loads(drive_cli(twin, "1", "state", "--json"))
    assert state["velocity_object"] == "606Ch" and abs(state["velocity"] - 600) < 30, state
    drive_cli(twin, "1", "velocity", "0", "--wait")
