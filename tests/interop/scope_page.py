"""What the browser tests do on the console's scope (Playwright page of `#drive/N`): keep the
sample batches the `/samples` endpoint sends the page, arm the trigger, and put a cursor at a
time of the cell's clock with a click (A) or a shift-click (B) on the plot."""

from __future__ import annotations

import json


def sample_frames(page) -> dict[int, list[dict]]:
    """Every sample the page's WebSockets receive from now on, by drive (the endpoint's own
    samples, to compare the scope's with)."""
    frames: dict[int, list[dict]] = {0: [], 1: []}

    def keep(payload) -> None:
        batch = json.loads(payload)
        frames.setdefault(batch["drive"], []).extend(batch["samples"])

    def on_socket(ws) -> None:
        if "/samples" in ws.url:
            ws.on("framereceived", keep)
    page.on("websocket", on_socket)
    return frames


def arm_trigger(page, signal: str, level: float, pre_percent: float, window_s: float) -> None:
    """A single-shot trigger on trace `signal` through `level`, armed."""
    page.select_option("#trig-signal", signal)
    page.fill("#trig-level", str(level))
    page.fill("#trig-pre", str(pre_percent))
    page.fill("#window", str(window_s))
    page.dispatch_event("#window", "change")
    page.check("#trig-single")
    page.wait_for_function("document.querySelector('#trig-status').textContent === 'armed'")


def click_at(page, t: float, shift: bool) -> None:
    """A click on the plot at time `t` (cursor A), with shift cursor B: where `t` is once the
    page has drawn what an earlier click or zoom asked for (a redraw waits for a frame)."""
    page.evaluate("new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)))")
    x = page.evaluate(f"window.scope.plot.valToPos({t}, 'x')")
    box = page.locator("#scope-plot .u-over").bounding_box()
    page.mouse.move(box["x"] + x, box["y"] + box["height"] / 2)
    if shift:
        page.keyboard.down("Shift")
    page.mouse.down()
    page.mouse.up()
    if shift:
        page.keyboard.up("Shift")


def assert_the_scope_moves(page) -> None:
    """The drive's page, its drive moving forwards at more than 100 rpm: the scope's newest
    position grows and its plot is drawn again."""
    page.wait_for_function(
        "(() => { const s = window.consoleState.samples;"
        " return s.length > 20 && s[s.length - 1].velocity > 100; })()", timeout=5000)
    first = page.evaluate("document.querySelector('#scope').toDataURL()")
    p0 = page.evaluate("window.consoleState.samples.at(-1).position")
    page.wait_for_timeout(400)
    second = page.evaluate("document.querySelector('#scope').toDataURL()")
    p1 = page.evaluate("window.consoleState.samples.at(-1).position")
    assert p1 > p0, (p0, p1)
    assert first != second, "the trace is redrawn as the drive moves"


def open_two_drive_scope(launch, browser, tmp_path):
    """A CMMP-AS (drive 0) and a Kinco FD3 (drive 1) on one instant bus, drive 0's page open
    at 1400 × 1000: (console URL, page, the endpoint's samples by drive)."""
    from test_web_console import console_url
    cell = tmp_path / "cell.toml"
    cell.write_text('[[drive]]\ndevice = "cmmp-as"\nnode = 1\n\n[[drive]]\ndevice = "kinco-fd3"\nnode = 2\n')
    twin = launch(config=cell, extra=("--http", "127.0.0.1:0", "--bitrate", "instant"))
    url = console_url(twin)
    page = browser.new_page()
    page.set_viewport_size({"width": 1400, "height": 1000})
    frames = sample_frames(page)
    page.goto(url + "#drive/0")
    return url, page, frames
