"""The console's scope in a real browser (headless Debian Chromium, Playwright) against
`drivetwin run --http` with a CMMP-AS and a Kinco FD3 on one bus: its axes carry their units,
a trigger captures a move made over REST, the two cursors read the move's duration within one
sample, and the CSV export holds the very samples the REST endpoint sent
(`/api/drives/N/samples`), of both drives on one time base.

The scope's screenshots go to docs/console-scope.png and docs/console-scope-user-units.png
when DRIVETWIN_SCREENSHOTS=1.
"""

from __future__ import annotations

import csv
import io
import json
import os
import urllib.request

from conftest import wait_until
from test_web_console import browser, console_url  # noqa: F401  (the fixture is used by name)
from scope_page import arm_trigger, click_at, open_two_drive_scope
from test_web_pages import DOCS

RATE_HZ = 200  # the scope's default sampling
SAMPLE_S = 1.0 / RATE_HZ


def post(url: str, body: dict | None = None) -> dict:
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method="POST",
                                 headers={"content-type": "application/json"})
    with urllib.request.urlopen(req, timeout=5) as r:
        return json.loads(r.read())


def get(url: str) -> dict:
    with urllib.request.urlopen(url, timeout=5) as r:
        return json.loads(r.read())


def test_scope_axes_trigger_cursors_and_csv_match_the_rest_samples(launch, browser, tmp_path):  # noqa: F811
    # Every sample batch the samples endpoint sends the page, by drive.
    url, page, frames = open_two_drive_scope(launch, browser, tmp_path)
    page.wait_for_selector("#status-bits tr[data-bit='6041h.6']")
    assert page.evaluate("typeof window.uPlot") == "function", "uPlot is built into the binary"
    page.wait_for_function("window.scope.plot && window.scope.traces.length >= 4")

    # A second drive's position on the same time base.
    page.select_option("#trace-drive", "1")
    page.fill("#trace-signal", "position")
    page.click("#trace-add")
    page.wait_for_selector("#trace-list [data-trace='d1.position']")

    # Axes with units: the time axis, and one per unit (increments, rpm, A, 60F4h's own unit).
    axes = page.evaluate("window.scope.axes()")
    labels = [a["label"] for a in axes]
    assert labels[0].startswith("t [s]") or labels[0].startswith("t [ms]"), labels
    for unit in ("inc", "rpm", "A", "pos units"):
        assert unit in labels, labels
    chips = page.text_content("#trace-list")
    assert "0: position [inc]" in chips and "0: velocity [rpm]" in chips and "1: position [inc]" in chips, chips

    # Trigger: velocity rising through 20 rpm, 20 % before, a 2 s window, single shot.
    arm_trigger(page, "velocity", 20, 20, 2)

    # The move, over REST: enable, then a relative move of 20000 increments.
    post(url + "api/drives/0/motion/enable")
    wait_until(lambda: get(url + "api/drives/0/motion")["state"] == "OPERATION ENABLED", 5.0, what="enabled")
    p_before = get(url + "api/drives/0/plant")["position"]
    post(url + "api/drives/0/motion/move", {"target": 20000, "relative": True})
    page.wait_for_function("window.consoleState.triggers === 1", timeout=10000)
    assert page.evaluate("window.consoleState.paused"), "single shot pauses the scope"
    cap = page.evaluate("(() => { const c = window.consoleState.capture; return {t0: c.t0, t1: c.t1, at: c.at}; })()")
    assert abs((cap["t1"] - cap["t0"]) - 2.0) < 1e-9 and abs((cap["at"] - cap["t0"]) - 0.4) < 1e-9, cap
    p_after = get(url + "api/drives/0/plant")["position"]
    target = p_before + 20000
    assert abs(p_after - target) <= 10, (p_before, p_after)

    # The move's duration from the endpoint's own samples: the first sample off the start
    # position to the first within 10 increments of the target (the drive settles there).
    s0 = sorted((p for p in frames[0] if cap["t0"] <= p["t"] <= cap["t1"]), key=lambda p: p["t"])
    start = next(p["t"] for p in s0 if p["position"] != p_before)
    end = next(p["t"] for p in s0 if abs(p["position"] - target) <= 10)
    assert end > start

    # Zoom onto the move: a drag across the plot narrows the time axis (to ms).
    page.locator("#scope-plot").scroll_into_view_if_needed()
    box = page.locator("#scope-plot .u-over").bounding_box()
    x0 = page.evaluate(f"window.scope.plot.valToPos({start - 0.03}, 'x')")
    x1 = page.evaluate(f"window.scope.plot.valToPos({end + 0.03}, 'x')")
    page.mouse.move(box["x"] + x0, box["y"] + 20)
    page.mouse.down()
    page.mouse.move(box["x"] + (x0 + x1) / 2, box["y"] + 20, steps=4)
    page.mouse.move(box["x"] + x1, box["y"] + 20, steps=4)
    page.mouse.up()
    page.wait_for_function("window.scope.view !== null && window.scope.plot.scales.x.max - window.scope.plot.scales.x.min < 0.5")
    page.wait_for_function("window.scope.axes()[0].label.startsWith('t [ms]')")

    # Cursor A at the start (a click), B at the end (a shift-click) on the plot.
    click_at(page, start, False)
    click_at(page, end, True)
    page.wait_for_function("document.querySelector('#cursor-dt').dataset.seconds")
    dt = float(page.get_attribute("#cursor-dt", "data-seconds"))
    assert abs(dt - (end - start)) <= SAMPLE_S + 1e-9, (dt, start, end)
    assert "ms" in page.text_content("#cursor-readout tbody tr:first-child td.dt")
    dpos = page.text_content("#cursor-readout tr[data-trace='position'] td.dv")
    assert abs(float(dpos) - 20000) <= 20000 * 0.05, dpos
    page.click("#scope-follow")
    page.wait_for_function("Math.abs(window.scope.plot.scales.x.max - window.scope.plot.scales.x.min - 2) < 1e-6")
    page.wait_for_timeout(300)
    if os.environ.get("DRIVETWIN_SCREENSHOTS") == "1":
        page.locator("#scope-panel").screenshot(path=str(DOCS / "console-scope.png"))

    # CSV: the capture's samples, each one as the samples endpoint sent it.
    with page.expect_download() as dl:
        page.click("#export-csv")
    text = open(dl.value.path(), encoding="utf-8").read()
    rows = list(csv.reader(io.StringIO(text)))
    head, body = rows[0], rows[1:]
    assert head[0] == "t_s"
    col = {name: i for i, name in enumerate(head)}
    assert "0: position [inc]" in col and "0: current [A]" in col and "1: position [inc]" in col, head
    by_t = {d: {p["t"]: p for p in frames[d]} for d in (0, 1)}
    # (a loaded machine's loop may skip a sample now and then; most of them are there)
    assert len(body) >= 2.0 * RATE_HZ * 0.5, len(body)
    # The drives sample at their own instants on the one clock: a row holds one drive's
    # values or both.
    rows_of = {0: 0, 1: 0}
    for r in body:
        t = float(r[0])
        assert cap["t0"] <= t <= cap["t1"]
        for d, name, f in ((0, "position", 1.0), (0, "velocity", 1.0), (0, "current", 0.001), (1, "position", 1.0)):
            cell_text = r[col[f"{d}: {name} [{'A' if name == 'current' else 'rpm' if name == 'velocity' else 'inc'}]"]]
            if cell_text == "":
                continue
            p = by_t[d].get(t)
            assert p is not None, (d, t)
            assert abs(float(cell_text) - p[name] * f) < 1e-9, (d, name, t, cell_text, p[name])
            rows_of[d] += name == "position"
    assert rows_of[0] == len(s0) and rows_of[1] > 0, (rows_of, len(s0), len(body))
    # The newest row of drive 0 (a row of the other drive alone leaves drive 0's cells empty).
    last0 = next(r[col["0: position [inc]"]] for r in reversed(body) if r[col["0: position [inc]"]] != "")
    assert abs(float(last0) - p_after) <= 2, "the drive at rest, as REST reads it"

    # The trace file carries the same columns and units, and opens again in the page.
    with page.expect_download() as dl:
        page.click("#export-trace")
    trace = json.loads(open(dl.value.path(), encoding="utf-8").read())
    assert trace["format"] == "drivetwin-scope-trace" and len(trace["t"]) == len(body)
    assert {t["unit"] for t in trace["traces"]} >= {"inc", "rpm", "A"}
    page.set_input_files("#open-trace", str(dl.value.path()))
    page.wait_for_function("window.scope.loaded !== null")
    assert page.evaluate("window.scope.csv()") == text


def test_positions_in_user_units_and_a_trigger_on_the_paused_buffer(launch, browser):  # noqa: F811
    """Positions in the drive's user units: 6093h position factor 65536/360 makes a CMMP-AS
    read in degrees of the motor shaft (manual §5.3), and the scope's position trace is 6064h as
    the drive reports it, on an axis labelled with the device file's unit. Paused after a
    move, a trigger set on the held samples finds the move's crossing among them."""
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0", "--bitrate", "instant"))
    url = console_url(twin)
    for sub, value in ((1, 65536), (2, 360)):
        req = urllib.request.Request(url + f"api/drives/0/objects/6093/{sub}", method="PUT",
                                     data=json.dumps({"value": str(value)}).encode(),
                                     headers={"content-type": "application/json"})
        with urllib.request.urlopen(req, timeout=5):
            pass
    page = browser.new_page()
    page.set_viewport_size({"width": 1400, "height": 1000})
    page.goto(url + "#drive/0")
    page.wait_for_function("window.scope.plot && window.scope.traces.length >= 4")
    assert "0: position [inc]" in page.text_content("#trace-list")

    page.select_option("#scope-pos-unit", "user")
    page.wait_for_function("(window.scope.traces.find((t) => t.id === 'position') || {}).signal === '6064:00'")
    chip = page.text_content("#trace-list [data-trace='position']")
    assert chip.startswith("0: position [pos units]"), chip
    labels = [a["label"] for a in page.evaluate("window.scope.axes()")]
    assert "pos units" in labels and "inc" not in labels, labels
    assert "6093h position factor 65536/360" in page.text_content("#pos-factor")

    # A quarter turn: 90 user units (degrees) = 16384 increments.
    p0 = int(get(url + "api/drives/0/objects/6064/0")["value"])
    post(url + "api/drives/0/motion/enable")
    wait_until(lambda: get(url + "api/drives/0/motion")["state"] == "OPERATION ENABLED", 5.0, what="enabled")
    inc0 = get(url + "api/drives/0/plant")["position"]
    post(url + "api/drives/0/motion/move", {"target": 90, "relative": True})
    target = p0 + 90
    wait_until(lambda: abs(int(get(url + "api/drives/0/objects/6064/0")["value"]) - target) <= 1, 10.0,
               what="6064h at the target")
    assert abs(get(url + "api/drives/0/plant")["position"] - inc0 - 16384) <= 200
    # The scope has the drive at rest at the target, in user units.
    page.wait_for_function(f"""(() => {{
        const s = window.scope.buffers.get(0);
        const p = s[s.length - 1];
        return p && p.objects && Math.abs(p.objects['6064:00'] - {target}) <= 1; }})()""", timeout=10000)

    page.click("#pause")
    held = page.evaluate("window.scope.buffers.get(0).map((p) => [p.t, p.objects ? p.objects['6064:00'] : null])")

    # The trigger, set on the paused scope: position rising through half the move.
    level = p0 + 45
    page.select_option("#trig-signal", "position")
    page.fill("#trig-level", str(level))
    page.fill("#trig-pre", "20")
    page.fill("#window", "2")
    page.dispatch_event("#window", "change")
    page.wait_for_function("window.consoleState.capture !== null", timeout=5000)
    cap = page.evaluate("(() => { const c = window.consoleState.capture; return {t0: c.t0, t1: c.t1, at: c.at}; })()")
    # The crossing among the held samples, found the way the trigger defines it.
    values = [(t, v) for t, v in held if v is not None]
    crossing = next(t for (_, a), (t, b) in zip(values, values[1:]) if a < level <= b)
    assert cap["at"] == crossing, (cap, crossing)
    assert abs((cap["at"] - cap["t0"]) - 0.4) < 1e-9 and abs((cap["t1"] - cap["t0"]) - 2.0) < 1e-9, cap
    assert page.text_content("#trig-status").startswith("triggered at t = ")
    assert page.evaluate("window.consoleState.paused"), "still paused"
    assert page.evaluate("window.scope.buffers.get(0).length") == len(held), "no sample taken while paused"
    # The plot shows the capture: the time axis counts from the trigger.
    page.wait_for_function("window.scope.axes()[0].label.endsWith('from the trigger')")
    if os.environ.get("DRIVETWIN_SCREENSHOTS") == "1":
        page.wait_for_timeout(300)
        page.locator("#scope-panel").screenshot(path=str(DOCS / "console-scope-user-units.png"))
    # The edge counts: falling through the same level, the forward move has no crossing among
    # the held samples; either edge finds the rising one again.
    page.select_option("#trig-edge", "falling")
    page.wait_for_function("document.querySelector('#trig-status').textContent === 'no crossing in the held samples'")
    assert page.evaluate("window.consoleState.capture") is None
    page.select_option("#trig-edge", "either")
    page.wait_for_function("window.consoleState.capture !== null")
    assert page.evaluate("window.consoleState.capture.at") == crossing


def test_eight_traces_torque_in_percent_of_rated_torque_and_the_pan_and_zoom_buttons(launch, browser, tmp_path):  # noqa: F811
    """Eight traces of two drives on one time base, among them the CMMP-AS's torque: 6077h in
    ‰ of the rated torque 6076h (cmmp-as-3 §3.6), drawn in % on an axis of its own; a ninth
    trace is refused. The torque the scope holds is the endpoint's 6077h over ten at each
    sample of a move. Paused, the zoom and pan buttons and the wheel move the time axis by
    their steps, and Follow comes back to the newest samples."""
    url, page, frames = open_two_drive_scope(launch, browser, tmp_path)
    page.wait_for_function("window.scope.plot && window.scope.traces.length === 4")

    def add(drive: int, signal: str) -> None:
        page.select_option("#trace-drive", str(drive))
        page.fill("#trace-signal", signal)
        page.click("#trace-add")

    add(0, "torque")
    page.wait_for_selector("#trace-list [data-trace='torque']")
    for drive, signal, trace_id in ((1, "position", "d1.position"), (1, "velocity", "d1.velocity"),
                                    (1, "6041:0", "d1.6041:00")):
        add(drive, signal)
        page.wait_for_selector(f"#trace-list [data-trace='{trace_id}']")
    assert page.evaluate("window.scope.traces.length") == 8
    chips = page.text_content("#trace-list")
    assert "0: torque [% rated torque]" in chips, chips
    labels = [a["label"] for a in page.evaluate("window.scope.axes()")]
    assert "% rated torque" in labels, labels

    # The ninth is refused, and the eight stay.
    add(1, "current")
    page.wait_for_function("document.querySelector('#message').textContent === 'at most 8 traces'")
    assert page.get_attribute("#message", "class") == "error"
    assert page.evaluate("window.scope.traces.length") == 8

    # A move of the CMMP-AS: its torque rises while it accelerates.
    post(url + "api/drives/0/motion/enable")
    wait_until(lambda: get(url + "api/drives/0/motion")["state"] == "OPERATION ENABLED", 5.0, what="enabled")
    post(url + "api/drives/0/motion/move", {"target": 20000, "relative": True})
    page.wait_for_function("window.scope.buffers.get(0).some((p) => p.objects && p.objects['6077:00'])",
                           timeout=10000)
    page.wait_for_timeout(500)
    page.click("#pause")
    # Paused, the page takes no sample; the frames still arriving are handed to this test while
    # it waits in the browser.
    page.wait_for_timeout(500)
    torque = page.evaluate("""(() => {
        const s = window.scope, t = s.traces.find((x) => x.signal === '6077:00');
        return s.buffers.get(0).map((p) => [p.t, t.get(p)]); })()""")
    by_t = {p["t"]: p for p in frames[0]}
    checked = 0
    for t, value in torque:
        sent = (by_t[t].get("objects") or {}).get("6077:00")
        if value is None:
            assert sent is None, (t, sent)
            continue
        assert abs(value - sent / 10) < 1e-9, (t, value, sent)
        checked += value != 0
    assert checked > 0, "a torque other than 0 in the scope"
    # Drive 1's traces are on the same clock: its samples sit between drive 0's first and last.
    t0 = page.evaluate("window.scope.buffers.get(0).map((p) => p.t)")
    t1 = page.evaluate("window.scope.buffers.get(1).map((p) => p.t)")
    assert t1 and t0[0] - 0.1 <= t1[-1] <= t0[-1] + 0.1, (t0[0], t0[-1], t1[-1])

    # Zoom in, pan left, the wheel zooms out, Follow: the time axis moves by the buttons' steps.
    def span() -> tuple[float, float]:
        return tuple(page.evaluate("[window.scope.plot.scales.x.min, window.scope.plot.scales.x.max]"))

    lo, hi = span()
    page.click("#scope-zoom-in")
    width = "window.scope.plot.scales.x.max - window.scope.plot.scales.x.min"
    page.wait_for_function(f"Math.abs({width} - {(hi - lo) / 2}) < 1e-6")
    lo, hi = span()
    page.click("#scope-left")
    page.wait_for_function(f"Math.abs(window.scope.plot.scales.x.min - {lo - (hi - lo) / 4}) < 1e-6")
    lo, hi = span()
    box = page.locator("#scope-plot .u-over").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.wheel(0, 100)
    page.wait_for_function(f"Math.abs({width} - {(hi - lo) * 1.25}) < 1e-6")
    page.click("#scope-follow")
    page.wait_for_function("window.scope.view === null")
