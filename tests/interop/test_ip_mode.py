"""Interpolated position mode (6060h = 7) of the CMMP-AS over CANopen, driven by
python-canopen, with a python-can SYNC producer setting the grid (60C2h commissioned to 10 ms,
the longest the manual allows, so that a Python master keeps it on a loaded machine; the SYNC
goes out on its own socketcand connection, because python-can's socketcand client holds its
sends while its reader waits, which bunches a periodic SYNC sent beside SDO traffic into
bursts every 50 ms, off any grid). The drive synchronises
(6061h −1 → 7), follows the set-points written to 60C1h:01 with ip_mode_active (statusword
bit 12), and reports EMCY 8781h (34-1) when SYNC stops while it interpolates."""

import time

import can
import pytest

from conftest import Realtime, add_node, realtime_prefix, wait_until, write_cell

PERIOD = 0.010


class SyncProducer:
    """SYNC (080h, no data) every PERIOD from its own bus connection."""

    def __init__(self, bus):
        self.bus = bus
        self.task = None

    def start(self):
        msg = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
        self.task = self.bus.send_periodic(msg, PERIOD)

    def stop(self):
        if self.task is not None:
            self.task.stop()
            self.task = None


@pytest.fixture
def ip_drive(launch, connect, raw_bus, eds_files, tmp_path):
    """The twin and this process (with the SYNC producer's thread) at real-time priority where
    allowed: a SYNC grid has to be kept, as by a real master."""
    cfg = write_cell(tmp_path / "cell.toml",
                     [("cmmp-as", 1, {"1017:00": 1000, "6510:F0": 0x80, "60C2:01": 10})])
    with Realtime():
        twin = launch(config=cfg, prefix=realtime_prefix())
        net = connect(twin)
        node = add_node(net, 1, eds_files["cmmp-as"])
        sync = SyncProducer(raw_bus(twin))
        yield sync, node
        sync.stop()


def test_ip_mode_follows_sync_paced_set_points_and_reports_a_lost_sync(ip_drive):
    sync, node = ip_drive
    assert node.sdo[0x60C2][1].raw == 10 and node.sdo[0x60C2][2].raw == -3, "10 ms"
    assert node.sdo[0x60C0].raw == -2, "linear interpolation without buffer"
    node.sdo[0x60C4][6].raw = 1  # unlock 60C1h
    node.nmt.state = "OPERATIONAL"
    node.sdo[0x6060].raw = 7
    time.sleep(0.05)
    assert node.sdo[0x6061].raw == -1, "no SYNC yet: not synchronised"
    sync.start()
    wait_until(lambda: node.sdo[0x6061].raw == 7, 5, what="6061h = 7 once on the SYNC grid")

    for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)):
        node.sdo[0x6040].raw = cw
        wait_until(lambda: node.sdo[0x6041].raw & 0x6F == want, 3, what=f"statusword {want:#x}")
    start = node.sdo[0x6064].raw
    node.sdo[0x60C1][1].raw = start
    node.sdo[0x6040].raw = 0x1F  # enable_ip_mode
    wait_until(lambda: node.sdo[0x6041].raw & 0x1000, 3, what="ip_mode_active (bit 12)")

    # 1.5 s of set-points, 1500 position units further every 10 ms.
    target = start
    t0 = time.monotonic()
    for k in range(150):
        target += 1500
        node.sdo[0x60C1][1].raw = target
        delay = t0 + (k + 1) * PERIOD - time.monotonic()
        if delay > 0:
            time.sleep(delay)
    deadline = time.monotonic() + 2
    while abs(node.sdo[0x6064].raw - target) >= 500:
        if time.monotonic() > deadline:
            pytest.fail(f"the axis is not at the last set-point {target}: at "
                        f"{node.sdo[0x6064].raw}, demand {node.sdo[0x6062].raw}, statusword "
                        f"{node.sdo[0x6041].raw:#06x}, 6061h {node.sdo[0x6061].raw}")
        time.sleep(0.02)
    sw = node.sdo[0x6041].raw
    assert sw & 0x3000 == 0x1000, f"interpolating, no following error: {sw:#06x}"
    assert node.sdo[0x6064].raw - start > 150 * 1500 - 500

    # SYNC stops while interpolating: error 34-1, EMCY 8781h; 6061h back to −1.
    sync.stop()
    emcy = node.emcy.wait(0x8781, timeout=3)
    assert emcy is not None, "EMCY 8781h (fieldbus synchronisation error)"
    assert node.sdo[0x6061].raw == -1
    wait_until(lambda: node.sdo[0x6041].raw & 0x4F == 0x08, 3, what="FAULT")
