"""Several drives on one time base: a CMMP-AS following a Kinco FD3, both CANopen nodes of one
cell, moved by a python-canopen master the way field code does it, and watched on the
console's scope in a real browser (headless Debian Chromium, Playwright).

The master moves the Kinco in profile position (its own move, KINCO-CW-01: 2Fh → 607Ah →
3Fh) and makes the CMMP-AS follow it: at each of its cycles it reads the Kinco's position
actual value (Pos_Actual 6063h, in its encoder's increments: the Kinco has no 6064h) and
writes it as the CMMP-AS's target 607Ah, a new set-point taken at once
(profile position, controlword bit 5 "change set immediately", bit 4 handshaked with
statusword bit 12, CiA 402 §6.2). The CMMP-AS's factor group (6093h position factor
65536/10000, manual §5.3) makes its position unit the Kinco's increment (10000 a turn), so the
follower's 6064h reads in the leader's units and the two traces compare on one scale.

The scope shows both positions on the cell's one clock, the leader's in increments (`inc`),
the follower's in its user units (`pos units`, its 6064h); its trigger catches
the leader's move; the two cursors, at the leader's and the follower's crossings of the
move's middle, read the follower's lag within one sample of the endpoint's own samples.

The screenshot goes to docs/console-scope-follow.png when DRIVETWIN_SCREENSHOTS=1.
"""

from __future__ import annotations

import os
import time

from canopen.profiles.p402 import BaseNode402

from conftest import SDO_TIMEOUT, wait_until
from scope_page import arm_trigger, click_at, sample_frames
from test_web_console import browser, console_url  # noqa: F401  (the fixture is used by name)
from test_web_pages import DOCS

RATE_HZ = 200  # the scope's default sampling
SAMPLE_S = 1.0 / RATE_HZ
MOVE = 50_000  # Kinco increments: 5 turns
DEC_PER_RPM = 512 * 10_000 / 1875  # the Kinco's velocity DEC of 1 rpm
DEC_PER_RPS2 = 65536 * 10_000 / 4_000_000  # the Kinco's acceleration DEC of 1 rps/s


def leader(net, eds: str) -> BaseNode402:
    """The Kinco FD3 (node 1), in profile position, enabled by 2Fh as its manual's example."""
    n = BaseNode402(1, eds)
    net.add_node(n)
    n.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    # The factory inputs own the controlword and the mode until the bus gets them.
    n.sdo[0x2010][3].raw = 0
    n.sdo[0x2010][5].raw = 0
    n.sdo[0x6060].raw = 1
    n.sdo[0x6081].raw = int(600 * DEC_PER_RPM)
    n.sdo[0x6083].raw = int(50 * DEC_PER_RPS2)
    n.sdo[0x6084].raw = int(50 * DEC_PER_RPS2)
    n.controlword = 0x06
    n.controlword = 0x2F
    wait_until(lambda: n.statusword & 0x6F == 0x27, 2.0, what="Kinco enabled by 2Fh")
    return n


def follower(net, eds: str) -> BaseNode402:
    """The CMMP-AS (node 2), in profile position with set-points taken at once, its position
    unit the Kinco's increment."""
    n = BaseNode402(2, eds)
    net.add_node(n)
    n.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    n.sdo[0x6093][1].raw = 65536
    n.sdo[0x6093][2].raw = 10_000
    n.sdo[0x6060].raw = 1
    n.sdo[0x6081].raw = 1200  # rpm: faster than the leader, so that it catches up
    n.sdo[0x6083].raw = 12_000  # rpm/s
    n.sdo[0x6084].raw = 12_000
    for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x2F, 0x27)):
        n.sdo[0x6040].raw = cw
        wait_until(lambda: n.sdo[0x6041].raw & 0x6F == want, 2.0, what=f"CMMP-AS statusword {want:#x}")
    return n


def new_set_point(n: BaseNode402, target: int) -> None:
    """607Ah := `target`, taken at once (controlword bit 5): bit 4 up until statusword bit 12
    acknowledges it, bit 4 down until bit 12 clears (CiA 402 §6.2, the set-point handshake)."""
    n.sdo[0x607A].raw = target
    n.sdo[0x6040].raw = 0x3F
    wait_until(lambda: n.sdo[0x6041].raw & 0x1000, 1.0, interval=0.0, what="set-point acknowledge")
    n.sdo[0x6040].raw = 0x2F
    wait_until(lambda: not n.sdo[0x6041].raw & 0x1000, 1.0, interval=0.0, what="acknowledge cleared")


def follow(lead: BaseNode402, foll: BaseNode402, target: int, timeout: float) -> list[float]:
    """The master's cycle until both are at `target`: the leader's 6063h becomes the
    follower's new set-point. Answers the cycles' durations."""
    cycles = []
    deadline = time.monotonic() + timeout
    while True:
        t = time.monotonic()
        p = lead.sdo[0x6063].raw
        new_set_point(foll, p)
        cycles.append(time.monotonic() - t)
        if abs(p - target) <= 20 and abs(foll.sdo[0x6064].raw - target) <= 20:
            return cycles
        assert t < deadline, f"the follower at {foll.sdo[0x6064].raw}, the leader at {p}, target {target}"


def crossing(samples: list[dict], level: float, value) -> float:
    """The time of the first sample whose `value` is at or above `level`."""
    return next(p["t"] for p in samples if value(p) is not None and value(p) >= level)


def test_a_cmmp_as_following_a_kinco_on_one_time_base(launch, connect, eds_files, browser, tmp_path):  # noqa: F811
    cell = tmp_path / "cell.toml"
    cell.write_text('[[drive]]\ndevice = "kinco-fd3"\nnode = 1\n\n[[drive]]\ndevice = "cmmp-as"\nnode = 2\n')
    twin = launch(config=cell, extra=("--http", "127.0.0.1:0", "--bitrate", "instant"))
    url = console_url(twin)
    net = connect(twin)
    lead = leader(net, str(eds_files["kinco-fd3"]))
    foll = follower(net, str(eds_files["cmmp-as"]))
    p0 = lead.sdo[0x6063].raw
    assert abs(foll.sdo[0x6064].raw - p0) < 10_000, "both near their zero"

    page = browser.new_page()
    page.set_viewport_size({"width": 1400, "height": 1000})
    frames = sample_frames(page)
    page.goto(url + "#drive/0")
    page.wait_for_function("window.scope && window.scope.plot && window.scope.traces.length >= 3")
    # The leader's position actual value 6063h in place of its motor encoder's increments, and
    # the follower's 6064h in its user units beside it; the leader's current makes room.
    page.select_option("#scope-pos-unit", "user")
    for trace in ("position", "current"):
        page.click(f"#trace-list [data-trace='{trace}'] .trace-remove")
        page.wait_for_selector(f"#trace-list [data-trace='{trace}']", state="detached")
    for drive, signal, trace in ((0, "6063:0", "6063:00"), (1, "position", "d1.position")):
        page.select_option("#trace-drive", str(drive))
        page.fill("#trace-signal", signal)
        page.click("#trace-add")
        page.wait_for_selector(f"#trace-list [data-trace='{trace}']")
    chips = page.text_content("#trace-list")
    lead_chip = page.text_content("#trace-list [data-trace='6063:00']")
    foll_chip = page.text_content("#trace-list [data-trace='d1.position']")
    assert lead_chip.startswith("0: pos_actual (6063h:00) [inc]"), chips
    assert foll_chip.startswith("1: position [pos units]"), chips
    labels = [a["label"] for a in page.evaluate("window.scope.axes()")]
    assert labels[0].startswith("t [s]") or labels[0].startswith("t [ms]"), labels
    assert "inc" in labels and "pos units" in labels and "rpm" in labels, labels

    # Trigger: the leader's position rising through the move's middle, single shot.
    mid = p0 + MOVE / 2
    arm_trigger(page, "6063:00", mid, 30, 3)

    # The master: the leader moves 5 turns, the follower follows it.
    new_set_point(lead, p0 + MOVE)
    cycles = follow(lead, foll, p0 + MOVE, 10.0)
    page.wait_for_function("window.consoleState.triggers === 1", timeout=10000)
    assert page.evaluate("window.consoleState.paused"), "single shot pauses the scope"

    # The lag from the endpoint's own samples: each drive's crossing of the middle.
    def crossing_of(drive: int, key: str) -> float:
        samples = sorted(frames[drive], key=lambda p: p["t"])
        return crossing(samples, mid, lambda p: (p.get("objects") or {}).get(key))
    t_lead, t_foll = crossing_of(0, "6063:00"), crossing_of(1, "6064:00")
    lag = t_foll - t_lead
    assert 0 < lag < 1.0, (t_lead, t_foll, cycles[:5])

    # The cursors at the two crossings: Δt is the lag, within one sample. Zoomed in with the
    # wheel around them first, as one reads a short lag, so that a pixel is a tenth of a sample.
    page.locator("#scope-plot").scroll_into_view_if_needed()
    box = page.locator("#scope-plot .u-over").bounding_box()
    width = "window.scope.plot.scales.x.max - window.scope.plot.scales.x.min"
    at = (t_lead + t_foll) / 2
    while page.evaluate(width) > max(box["width"] * SAMPLE_S / 10, 4 * lag):
        before = page.evaluate(width)
        x = page.evaluate(f"window.scope.plot.valToPos({at}, 'x')")
        page.mouse.move(box["x"] + x, box["y"] + box["height"] / 2)
        page.mouse.wheel(0, -100)
        page.wait_for_function(f"{width} < {before} - 1e-9")
    click_at(page, t_lead, False)
    click_at(page, t_foll, True)
    page.wait_for_function("document.querySelector('#cursor-dt').dataset.seconds")
    dt = float(page.get_attribute("#cursor-dt", "data-seconds"))
    assert abs(dt - lag) <= SAMPLE_S + 1e-9, (dt, lag)
    # At cursor A the follower is behind the leader by what it has yet to go.
    a_lead = float(page.text_content("#cursor-readout tr[data-trace='6063:00'] td:nth-child(2)"))
    a_foll = float(page.text_content("#cursor-readout tr[data-trace='d1.position'] td:nth-child(2)"))
    assert a_foll < a_lead, (a_foll, a_lead)
    if os.environ.get("DRIVETWIN_SCREENSHOTS") == "1":
        page.wait_for_timeout(300)
        page.locator("#scope-panel").screenshot(path=str(DOCS / "console-scope-follow.png"))
