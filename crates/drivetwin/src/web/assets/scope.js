// The console's scope: up to 8 traces of any drives' plant signals and objects on the cell's
// one clock, drawn with uPlot (embedded in the binary from the npm registry). Each unit has
// its own y axis; the time axis reads in s or ms. A trigger (level, edge, pre-trigger, single
// shot) freezes a window; two cursors read Δt and Δvalue; drag zooms, the wheel zooms and
// pans; the buffer exports as CSV and as a trace file (JSON, loadable again). Positions read
// in increments (the plant's encoder) or in the drive's user units: its position actual value
// 6064h as the drive reports it through its factor group (6093h position factor, 6092h feed
// constant …), with the unit its device file names. A trigger changed while the scope is
// paused is evaluated over the samples held.
//
// Samples come from the live WebSocket of each drive (/api/drives/N/samples): the cell loop
// samples the plant and the named objects at the chosen rate and the console batches them,
// so the scope costs the loop one bounded queue per drive, whatever the browser does.
"use strict";

(function () {
  const q = (sel) => document.querySelector(sel);
  const MAX_TRACES = 8;
  const KEEP_S = 60;
  const COLORS = ["#4fc3f7", "#aed581", "#ffb74d", "#e57373", "#ce93d8", "#fff176", "#4db6ac", "#f06292"];
  // The plant's signals as the WebSocket sends them, and how the scope shows them.
  const PLANT = {
    position: { name: "position", unit: (kind) => (kind === "stepper" ? "SI units" : "inc"), scale: 1 },
    velocity: { name: "velocity", unit: () => "rpm", scale: 1 },
    current: { name: "current", unit: () => "A", scale: 0.001 },
  };

  const scope = {
    traces: [],
    buffers: new Map(), // drive → samples, oldest first
    sockets: new Map(), // drive → WebSocket
    kinds: new Map(), // drive → "servo" | "stepper"
    page: null, // the drive whose page this is
    rate: 200,
    view: null, // the x range the user zoomed or panned to; null: follow the newest samples
    cursors: { a: null, b: null },
    plot: null,
    dirty: true,
    loaded: null, // a trace file opened in the page
    positionUnit: "inc", // "inc": the plant's encoder increments; "user": 6064h, the drive's user units
  };
  window.scope = scope;
  const cs = () => window.consoleState;

  // ------------------------------------------------------------------------------ traces

  const keyOf = (text) => {
    const m = /^([0-9a-f]{1,4})h?:([0-9a-f]{1,2})$/i.exec(text.trim());
    return m ? `${m[1].toUpperCase().padStart(4, "0")}:${m[2].toUpperCase().padStart(2, "0")}` : null;
  };

  function traceId(drive, signal) {
    return drive === scope.page ? signal : `d${drive}.${signal}`;
  }

  // A trace of a plant signal or an object (`60F4:00`); objects are described by the REST
  // API (their name and their unit from the device file).
  async function makeTrace(drive, signal, id) {
    const p = PLANT[signal];
    if (p) {
      const kind = await kindOf(drive);
      if (signal === "position" && scope.positionUnit === "user" && kind !== "stepper") {
        const t = await userPositionTrace(drive, id);
        if (t) return t;
      }
      const f = p.scale;
      return { id: id ?? traceId(drive, signal), drive, signal, label: `${drive}: ${p.name}`,
               unit: p.unit(kind), get: (s) => (s[signal] == null ? null : s[signal] * f) };
    }
    if (signal === "torque") return torqueTrace(drive, id);
    const key = keyOf(signal);
    if (!key) throw new Error(`${signal}: position, velocity, current, torque or an object index:sub in hex (6077:0)`);
    const [i, sub] = key.split(":");
    const o = await api("GET", `/api/drives/${drive}/objects/${i}/${parseInt(sub, 16).toString(16)}`);
    return { id: id ?? traceId(drive, key), drive, signal: key, object: true,
             label: `${drive}: ${o.name} (${i}h:${sub})`, unit: o.unit || "",
             get: (s) => (s.objects && s.objects[key] != null ? s.objects[key] : null) };
  }

  // A drive's torque in % of its rated torque: 6077h torque actual value, in thousandths of
  // the motor's rated torque 6076h (the CMMP-AS manual's torque objects, cmmp-as-3 §3.6; its
  // device file's unit "1/1000 rated torque"), shown divided by ten. A 6077h with another
  // unit is shown in that unit.
  async function torqueTrace(drive, id) {
    let o;
    try { o = await api("GET", `/api/drives/${drive}/objects/6077/0`); } catch (e) {
      throw new Error(`torque: drive ${drive} has no 6077h torque actual value`);
    }
    const key = "6077:00";
    const perMille = /^1\/1000 rated torque$/.test(o.unit || "");
    const f = perMille ? 0.1 : 1;
    return { id: id ?? traceId(drive, "torque"), drive, signal: key, object: true, plant: "torque",
             label: `${drive}: torque`, unit: perMille ? "% rated torque" : (o.unit || ""),
             get: (s) => (s.objects && s.objects[key] != null ? s.objects[key] * f : null) };
  }

  // A drive's position in its user units: 6064h position actual value, which the drive
  // converts from increments through its factor group (CiA 402 §6.2: 6093h position factor, or
  // 608Fh encoder resolution, 6091h gear ratio and 6092h feed constant), labelled with the unit
  // its device file gives 6064h. None when the device has no 6064h (it reads increments only).
  async function userPositionTrace(drive, id) {
    let o;
    try { o = await api("GET", `/api/drives/${drive}/objects/6064/0`); } catch (e) { return null; }
    const key = "6064:00";
    return { id: id ?? traceId(drive, "position"), drive, signal: key, object: true, plant: "position",
             label: `${drive}: position`, unit: o.unit || "user units", factor: await factorText(drive),
             get: (s) => (s.objects && s.objects[key] != null ? s.objects[key] : null) };
  }

  // The factor group's objects the drive has, as it reports them now ("6093h position factor
  // 65536/360").
  async function factorText(drive) {
    const parts = [];
    for (const [index, name] of [["6093", "position factor"], ["608F", "encoder resolution"],
                                 ["6091", "gear ratio"], ["6092", "feed constant"]]) {
      try {
        const [a, b] = await Promise.all([1, 2].map((sub) => api("GET", `/api/drives/${drive}/objects/${index}/${sub}`)));
        parts.push(`${index}h ${name} ${a.value}/${b.value}`);
      } catch (e) { /* not in this device's dictionary */ }
    }
    return parts.join(", ");
  }

  async function kindOf(drive) {
    if (!scope.kinds.has(drive)) {
      let kind = "servo";
      try { kind = (await api("GET", `/api/drives/${drive}/plant`)).kind || kind; } catch (e) { /* servo */ }
      scope.kinds.set(drive, kind);
    }
    return scope.kinds.get(drive);
  }

  async function addTrace(drive, signal, id) {
    const t = await makeTrace(drive, signal, id);
    const old = scope.traces.findIndex((x) => x.id === t.id);
    if (old < 0 && scope.traces.length >= MAX_TRACES) throw new Error(`at most ${MAX_TRACES} traces`);
    t.color = old >= 0 ? scope.traces[old].color : COLORS.find((c) => !scope.traces.some((x) => x.color === c));
    if (old >= 0) scope.traces[old] = t; else scope.traces.push(t);
    await tracesChanged([drive]);
    return t;
  }

  function removeTrace(id) {
    const t = scope.traces.find((x) => x.id === id);
    scope.traces = scope.traces.filter((x) => x.id !== id);
    if (t) tracesChanged(t.object ? [t.drive] : []);
  }

  // The streams follow the traces: one WebSocket per drive with its objects; a drive whose
  // objects changed is reconnected (its buffer is kept).
  async function tracesChanged(reconnect) {
    const drives = new Set(scope.traces.map((t) => t.drive));
    if (scope.page != null) drives.add(scope.page);
    for (const [d, ws] of scope.sockets) {
      if (!drives.has(d)) { scope.sockets.delete(d); ws.close(); scope.buffers.delete(d); }
    }
    for (const d of drives) {
      if (!scope.sockets.has(d) || reconnect.includes(d)) connect(d);
    }
    showTraces();
    buildPlot();
  }

  function objectsOf(drive) {
    return scope.traces.filter((t) => t.drive === drive && t.object).map((t) => t.signal);
  }

  function connect(drive) {
    const old = scope.sockets.get(drive);
    if (old) old.close();
    if (!scope.buffers.has(drive)) scope.buffers.set(drive, []);
    const objects = objectsOf(drive);
    const proto = location.protocol === "https:" ? "wss" : "ws";
    const ws = new WebSocket(`${proto}://${location.host}/api/drives/${drive}/samples?rate_hz=${scope.rate}&batch_ms=50`
                             + (objects.length ? `&objects=${objects.join(",")}` : ""));
    ws.onmessage = (ev) => { if (scope.sockets.get(drive) === ws) ingest(JSON.parse(ev.data)); };
    ws.onopen = () => { if (scope.sockets.get(drive) === ws) q("#connection").textContent = ""; };
    ws.onclose = () => { if (scope.sockets.get(drive) === ws) q("#connection").textContent = "samples stopped"; };
    scope.sockets.set(drive, ws);
  }

  function ingest(batch) {
    const c = cs();
    if (c.paused || scope.loaded) return;
    const s = scope.buffers.get(batch.drive);
    if (!s) return;
    const fe = batch.drive === scope.page ? "60F4:00" : null;
    const obj = batch.drive === scope.page ? scope.traces.find((t) => t.id === "object") : null;
    for (const p of batch.samples) {
      // The page's drive: 60F4h and the "also plot" object under their own names as well.
      if (fe && p.objects && p.objects[fe] != null) p.following_error = p.objects[fe];
      if (obj && p.objects && p.objects[obj.signal] != null) p.object = p.objects[obj.signal];
      s.push(p);
    }
    const last = s[s.length - 1];
    let cut = 0;
    while (cut < s.length && last.t - s[cut].t > KEEP_S) cut++;
    if (cut) s.splice(0, cut);
    // Written only when it changes: each write of the page's text costs a style, layout and
    // paint of the page, 20 times a second per tab.
    if (batch.drive === scope.page && batch.display != null) setText(q("#display"), batch.display);
    checkTrigger();
    scope.dirty = true;
  }

  // The page of `drive` opens: its position, velocity and current (a servo's), its following
  // error where it has 60F4h, on a fresh buffer.
  async function open(drive) {
    close();
    scope.page = drive;
    scope.loaded = null;
    scope.cursors = { a: null, b: null };
    scope.view = null;
    const c = cs();
    c.samples = [];
    scope.buffers.set(drive, c.samples);
    c.capture = null; c.pending = null; c.searchedTo = undefined; c.triggers = 0;
    const kind = await kindOf(drive);
    const signals = kind === "stepper" ? ["position"] : ["position", "velocity", "current"];
    const traces = [];
    for (const sig of signals) traces.push(await makeTrace(drive, sig));
    try { traces.push(await makeTrace(drive, "60F4:0", "following_error")); } catch (e) { /* no 60F4h */ }
    const extra = keyOf(q("#scope-object").value);
    if (extra) { try { traces.push(await makeTrace(drive, extra, "object")); } catch (e) { /* said on Sample */ } }
    if (scope.page !== drive) return;
    traces.forEach((t, i) => { t.color = COLORS[i]; });
    scope.traces = traces;
    await tracesChanged([drive]);
    showObjectName();
  }

  function close() {
    for (const ws of scope.sockets.values()) ws.close();
    scope.sockets.clear();
    scope.buffers.clear();
    scope.page = null;
  }

  function showObjectName() {
    const t = scope.traces.find((x) => x.id === "object");
    q("#object-name").textContent = t ? `object ${t.signal}` : "";
  }

  function showTraces() {
    const pos = scope.traces.find((t) => t.plant === "position" && t.drive === scope.page);
    q("#pos-factor").textContent = pos ? `${pos.unit}${pos.factor ? `: ${pos.factor}` : ""}` : "";
    const list = q("#trace-list");
    list.replaceChildren(...scope.traces.map((t) => {
      const b = el("button", { type: "button", class: "trace-remove", title: `remove ${t.label}` }, "×");
      b.addEventListener("click", () => removeTrace(t.id));
      const chip = el("span", { class: "trace-chip", "data-trace": t.id }, `${t.label} [${t.unit || "–"}] `, b);
      if (t.factor) chip.title = `6064h through the factor group: ${t.factor}`;
      chip.style.borderColor = t.color;
      return chip;
    }));
    const sel = q("#trig-signal"), was = sel.value;
    sel.replaceChildren(el("option", { value: "" }, "free running"),
      ...scope.traces.map((t) => el("option", { value: t.id }, t.label)));
    sel.value = scope.traces.some((t) => t.id === was) ? was : "";
    const drives = q("#trace-drive"), dwas = drives.value;
    drives.replaceChildren(...(cs().drives || []).map((d) => el("option", { value: String(d.index) }, `${d.index}: ${d.device}`)));
    drives.value = dwas || String(scope.page ?? 0);
    if (drives.value === "" && scope.page != null) drives.value = String(scope.page);
  }

  // ----------------------------------------------------------------------------- trigger

  function win() {
    const w = Number(q("#window").value);
    return w >= 0.05 && w <= KEEP_S ? w : 10;
  }

  // Looks for the trigger's crossing in the samples not yet searched; once the window after it
  // is full, the capture is taken (and in "single" the scope pauses). On a paused scope
  // (`held`) no sample will come: the held samples are all there is, and a crossing's window
  // is taken with what they hold after it.
  function checkTrigger(held = false) {
    const c = cs();
    const id = q("#trig-signal").value;
    const status = q("#trig-status");
    const trace = scope.traces.find((t) => t.id === id);
    if (!trace) { c.capture = null; setText(status, ""); return; }
    const s = scope.buffers.get(trace.drive) || [];
    const w = win();
    const pre = Math.min(Math.max(Number(q("#trig-pre").value) || 0, 0), 100) / 100;
    const level = Number(q("#trig-level").value), edge = q("#trig-edge").value;
    const last = s[s.length - 1];
    if (c.pending == null) {
      const from = c.searchedTo ?? -Infinity;
      // From the sample before the first one not yet searched.
      let start = s.length;
      while (start > 0 && s[start - 1].t > from) start--;
      let prev = null;
      for (let i = Math.max(start - 1, 0); i < s.length; i++) {
        const p = s[i], v = trace.get(p);
        if (v == null) continue;
        if (prev != null && p.t > from) {
          const up = prev < level && v >= level, down = prev > level && v <= level;
          if (edge === "rising" ? up : edge === "falling" ? down : up || down) { c.pending = p.t; break; }
        }
        prev = v;
      }
      c.searchedTo = last ? last.t : from;
    }
    if (c.pending != null) {
      const t0 = c.pending - pre * w, t1 = t0 + w;
      // Every drive's samples up to the window's end (one time base).
      const lasts = [...scope.buffers.values()].filter((b) => b.length).map((b) => b[b.length - 1].t);
      const newest = lasts.length ? Math.min(...lasts) : -Infinity;
      if (held || newest >= t1) {
        const byDrive = new Map([...scope.buffers].map(([d, b]) => [d, b.filter((p) => p.t >= t0 && p.t <= t1)]));
        c.capture = { t0, t1, at: c.pending, samples: byDrive.get(scope.page) || [], byDrive };
        c.triggers += 1;
        c.pending = null;
        c.searchedTo = t1;
        scope.view = null;
        status.textContent = `triggered at t = ${c.capture.at.toFixed(3)} s (${c.triggers})`;
        if (q("#trig-single").checked) setPaused(true);
      } else {
        setText(status, "triggered, filling the window…");
      }
    } else if (!c.capture) {
      setText(status, held ? "no crossing in the held samples" : "armed");
    }
  }

  // A trigger changed: live, it waits for the next crossing; paused, it searches the held
  // samples from the left edge of the range shown when zoomed or panned, else from the oldest.
  function rearm() {
    const c = cs();
    c.capture = null; c.pending = null;
    const held = Boolean(c.paused) && !scope.loaded;
    if (held) {
      c.searchedTo = scope.view ? scope.view.min : undefined;
    } else {
      const s = scope.buffers.get(scope.page) || [];
      c.searchedTo = s.length ? s[s.length - 1].t : undefined;
    }
    scope.view = null;
    checkTrigger(held);
    scope.dirty = true;
  }

  function setPaused(p) {
    cs().paused = p;
    q("#pause").textContent = p ? "Run" : "Pause";
    scope.dirty = true; // paused, the plot holds the whole buffer (liveFrom)
  }

  // -------------------------------------------------------------------------------- data

  // The samples shown: the trace file opened, the capture, or the whole buffer (from `from`
  // on the cell's clock, when given); as uPlot's aligned columns (the cell's clock, then one
  // column per trace).
  function columns(from = -Infinity) {
    if (scope.loaded) return scope.loaded.data;
    const c = cs();
    const src = c.capture && q("#trig-signal").value ? c.capture.byDrive : scope.buffers;
    const tables = [];
    const order = [];
    for (const [drive, all] of src) {
      const ts = scope.traces.filter((t) => t.drive === drive);
      const samples = from === -Infinity ? all : all.slice(firstAt(all, from));
      if (!ts.length || !samples.length) continue;
      tables.push([samples.map((p) => p.t), ...ts.map((t) => samples.map((p) => t.get(p)))]);
      order.push(...ts);
    }
    if (!tables.length) return [[], ...scope.traces.map(() => [])];
    const joined = tables.length === 1 ? tables[0] : uPlotLib().join(tables);
    // Back into the traces' order.
    return [joined[0], ...scope.traces.map((t) => joined[1 + order.indexOf(t)] || joined[0].map(() => null))];
  }

  // An element's text, written only when it differs (a write, even of the same text, makes
  // the browser lay out and paint the page again).
  function setText(e, text) {
    if (e.textContent !== text) e.textContent = text;
  }

  // The index of the first sample at or after `t` (the samples are in time order).
  function firstAt(samples, t) {
    let lo = 0, hi = samples.length;
    while (lo < hi) {
      const mid = (lo + hi) >> 1;
      if (samples[mid].t < t) lo = mid + 1; else hi = mid;
    }
    return lo;
  }

  // Where the plot's samples start while the scope runs free (live, following the newest
  // sample, no cursor set): its time window, so that a redraw costs the window's samples and
  // not the whole buffer's (KEEP_S at up to 1 kHz, per trace), most of what an open tab costs
  // the machine the cell runs on. Anything else (paused, zoomed or panned, a capture, a trace
  // file, a cursor to read) gets the whole buffer.
  function liveFrom() {
    const c = cs();
    if (scope.loaded || scope.view || c.paused || (c.capture && q("#trig-signal").value)) return -Infinity;
    if (scope.cursors.a != null || scope.cursors.b != null) return -Infinity;
    let t1 = -Infinity;
    for (const s of scope.buffers.values()) if (s.length) t1 = Math.max(t1, s[s.length - 1].t);
    return t1 - win();
  }

  function traceMeta() {
    return scope.loaded ? scope.loaded.traces : scope.traces;
  }

  function csv() {
    const d = columns();
    const head = ["t_s", ...traceMeta().map((t) => `"${t.label} [${t.unit}]"`)].join(",");
    const rows = d[0].map((t, i) => [t, ...d.slice(1).map((col) => (col[i] == null ? "" : col[i]))].join(","));
    return [head, ...rows].join("\n") + "\n";
  }

  // The trace file: the traces with their drives and units, the trigger, and the columns.
  function traceFile() {
    const c = cs();
    const d = columns();
    return JSON.stringify({
      format: "drivetwin-scope-trace", version: 1, clock: "cell clock, s", rate_hz: scope.rate,
      traces: traceMeta().map((t) => ({ drive: t.drive, signal: t.signal, label: t.label, unit: t.unit })),
      trigger: c.capture ? { at: c.capture.at, t0: c.capture.t0, t1: c.capture.t1, signal: q("#trig-signal").value,
                             level: Number(q("#trig-level").value), edge: q("#trig-edge").value } : null,
      t: d[0], values: d.slice(1),
    });
  }

  function openTraceFile(text) {
    const f = JSON.parse(text);
    if (f.format !== "drivetwin-scope-trace") throw new Error("not a drivetwin scope trace file");
    setPaused(true);
    scope.loaded = { traces: f.traces.map((t, i) => ({ ...t, id: `file${i}`, color: COLORS[i % COLORS.length] })),
                     data: [f.t, ...f.values] };
    scope.view = null;
    buildPlot();
  }

  function download(name, type, text) {
    const a = el("a", { href: URL.createObjectURL(new Blob([text], { type })), download: name });
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 1000);
  }

  // -------------------------------------------------------------------------------- plot

  const uPlotLib = () => window.uPlot;

  function origin() {
    const c = cs();
    if (scope.loaded) return 0;
    return c.capture && q("#trig-signal").value ? c.capture.at : 0;
  }

  // s or ms, as the span shown calls for.
  function timeUnit(u) {
    const x = u.scales.x;
    return x.max - x.min < 2 ? "ms" : "s";
  }

  function xLabel(u) {
    const unit = timeUnit(u);
    return origin() ? `t [${unit}] from the trigger` : `t [${unit}] on the cell's clock`;
  }

  function fmtT(u, v) {
    const span = u.scales.x.max - u.scales.x.min;
    const rel = v - origin();
    if (timeUnit(u) === "ms") return (rel * 1000).toFixed(span < 0.02 ? 2 : span < 0.2 ? 1 : 0);
    return rel.toFixed(span < 20 ? 2 : span < 200 ? 1 : 0);
  }

  function fmtV(v) {
    if (v == null) return "–";
    const a = Math.abs(v);
    return a !== 0 && (a < 0.01 || a >= 1e6) ? v.toExponential(3) : String(Number(v.toPrecision(6)));
  }

  function units() {
    return [...new Set(traceMeta().map((t) => t.unit))];
  }

  // The axes as drawn, for a reader of the page (and its tests): the time axis and one axis
  // per unit.
  scope.axes = () => (scope.plot ? scope.plot.axes.map((a, i) => ({
    label: typeof a.label === "function" ? a.label(scope.plot, i) : a.label, side: a.side })) : []);

  function buildPlot() {
    const box = q("#scope-plot");
    if (scope.plot) { scope.plot.destroy(); scope.plot = null; }
    const U = uPlotLib();
    if (!U) {
      box.replaceChildren(el("p", { class: "fault" }, window.uPlotMissing || "scope library not loaded"));
      return;
    }
    const us = units();
    // Ticks at round times from the origin (the trigger on a capture), not from the clock's 0.
    const xSplits = (u, i, min, max, incr) => {
      const o = origin(), out = [];
      for (let v = Math.ceil((min - o) / incr) * incr + o; v <= max + incr * 1e-6; v += incr) out.push(v);
      return out;
    };
    const axes = [{ scale: "x", label: xLabel, splits: xSplits, values: (u, splits) => splits.map((v) => fmtT(u, v)),
                    stroke: "#ccc", grid: { stroke: "#333" }, ticks: { stroke: "#444" } }];
    const scales = { x: { time: false } };
    us.forEach((unit, i) => {
      const key = `u:${unit}`;
      scales[key] = { auto: true };
      const color = traceMeta().find((t) => t.unit === unit).color;
      axes.push({ scale: key, label: unit || "value", side: i % 2 ? 1 : 3, stroke: color, size: 64,
                  grid: { show: i === 0, stroke: "#2a2a2a" }, ticks: { stroke: "#444" },
                  values: (u, splits) => splits.map(fmtV) });
    });
    const series = [{ label: "t", value: (u, v) => (v == null ? "–" : `${fmtT(u, v)} ${timeUnit(u)}`) },
      ...traceMeta().map((t) => ({ label: `${t.label} [${t.unit || "–"}]`, scale: `u:${t.unit}`, stroke: t.color,
                                   width: 1.5, spanGaps: true, points: { show: false }, value: (u, v) => fmtV(v) }))];
    box.replaceChildren();
    scope.plot = new U({
      width: Math.max(box.clientWidth, 400), height: 360, scales, axes, series,
      cursor: { drag: { x: true, y: false, setScale: true } },
      hooks: { draw: [drawMarks], setSelect: [onSelect] },
    }, columns(), box);
    scope.plot.ctx.canvas.id = "scope";
    bindPlot(scope.plot);
    scope.dirty = true;
  }

  // A zoom by dragging across the plot: the user's range, kept until Follow or a
  // double-click. (uPlot applies scales in a microtask, so its setScale hook cannot tell the
  // user's zoom from the scope's own.)
  function onSelect(u) {
    if (u.select.width > 2) {
      scope.view = { min: u.posToVal(u.select.left, "x"), max: u.posToVal(u.select.left + u.select.width, "x") };
      scope.dirty = true;
    }
  }

  function setX(min, max) {
    if (scope.plot && max > min) scope.plot.setScale("x", { min, max });
  }

  // Cursors (A solid, B dashed), the trigger's time and level.
  function drawMarks(u) {
    const g = u.ctx, top = u.bbox.top, h = u.bbox.height;
    g.save();
    const vline = (t, color, dash) => {
      if (t == null) return;
      const x = u.valToPos(t, "x", true);
      g.strokeStyle = color; g.setLineDash(dash); g.lineWidth = 1;
      g.beginPath(); g.moveTo(x, top); g.lineTo(x, top + h); g.stroke();
    };
    const c = cs();
    if (!scope.loaded && c.capture && q("#trig-signal").value) vline(c.capture.at, "#888", [4, 4]);
    const trace = !scope.loaded && scope.traces.find((t) => t.id === q("#trig-signal").value);
    if (trace) {
      const y = u.valToPos(Number(q("#trig-level").value), `u:${trace.unit}`, true);
      if (Number.isFinite(y)) {
        g.strokeStyle = trace.color; g.setLineDash([2, 6]);
        g.beginPath(); g.moveTo(u.bbox.left, y); g.lineTo(u.bbox.left + u.bbox.width, y); g.stroke();
      }
    }
    vline(scope.cursors.a, "#fff", []);
    vline(scope.cursors.b, "#ff0", [6, 3]);
    g.restore();
  }

  function bindPlot(u) {
    let down = null;
    u.over.addEventListener("mousedown", (e) => { down = e.clientX; });
    // A click (no drag) puts cursor A there, a shift-click cursor B; both snap to a sample.
    u.over.addEventListener("click", (e) => {
      if (down == null || Math.abs(e.clientX - down) > 3) return;
      const x = e.clientX - u.over.getBoundingClientRect().left;
      const t = snap(u, u.posToVal(x, "x"));
      if (t != null) setCursor(e.shiftKey ? "b" : "a", t);
    });
    u.over.addEventListener("dblclick", () => { scope.view = null; scope.dirty = true; });
    // The wheel zooms around the pointer; with shift (or sideways) it pans.
    u.over.addEventListener("wheel", (e) => {
      e.preventDefault();
      const { min, max } = u.scales.x;
      const span = max - min;
      if (e.shiftKey || Math.abs(e.deltaX) > Math.abs(e.deltaY)) {
        const d = (span * Math.sign(e.deltaX || e.deltaY)) / 10;
        scope.view = { min: min + d, max: max + d };
      } else {
        const at = u.posToVal(e.clientX - u.over.getBoundingClientRect().left, "x");
        const f = e.deltaY > 0 ? 1.25 : 0.8;
        scope.view = { min: at - (at - min) * f, max: at + (max - at) * f };
      }
      scope.dirty = true;
    }, { passive: false });
  }

  // The time of the sample nearest `t` of the first trace's drive (the drives sample at
  // their own instants on the one clock, so the joined columns hold each drive's times).
  function snap(u, t) {
    const col = u.data[1] || [];
    const i = nearest(u, col, u.valToIdx(t), t);
    return i == null ? null : u.data[0][i];
  }

  // The index of the non-empty value of `col` nearest in time to `t`, around index `i`.
  function nearest(u, col, i, t) {
    const x = u.data[0];
    let lo = i, hi = i;
    while (lo >= 0 && col[lo] == null) lo--;
    while (hi < x.length && col[hi] == null) hi++;
    if (lo < 0 && hi >= x.length) return null;
    if (lo < 0) return hi;
    if (hi >= x.length) return lo;
    return t - x[lo] <= x[hi] - t ? lo : hi;
  }

  function setCursor(which, t) {
    scope.cursors[which] = t;
    showCursors();
    if (scope.plot) scope.plot.redraw(false);
  }

  // The cursors' times, Δt, and each trace's value at both and its Δ.
  function showCursors() {
    const { a, b } = scope.cursors;
    const u = scope.plot;
    const body = q("#cursor-readout tbody");
    if (!u || (a == null && b == null)) {
      if (body.childElementCount) body.replaceChildren();
      setText(q("#cursor-dt"), "");
      return;
    }

    const dt = a != null && b != null ? b - a : null;
    q("#cursor-dt").textContent = dt == null ? "" : `Δt = ${(dt * 1000).toFixed(3)} ms`;
    q("#cursor-dt").dataset.seconds = dt == null ? "" : String(dt);
    body.replaceChildren(
      el("tr", {}, el("th", {}, "t"), el("td", {}, a == null ? "–" : `${fmtT(u, a)} ${timeUnit(u)}`),
        el("td", {}, b == null ? "–" : `${fmtT(u, b)} ${timeUnit(u)}`),
        el("td", { class: "dt" }, dt == null ? "–" : `${(dt * 1000).toFixed(3)} ms`)),
      ...traceMeta().map((t, k) => {
        const col = u.data[k + 1] || [];
        const at = (t) => {
          const i = t == null ? null : nearest(u, col, u.valToIdx(t), t);
          return i == null ? null : col[i];
        };
        const va = at(a), vb = at(b);
        return el("tr", { "data-trace": t.id }, el("th", {}, `${t.label} [${t.unit || "–"}]`),
          el("td", {}, fmtV(va)), el("td", {}, fmtV(vb)),
          el("td", { class: "dv" }, va == null || vb == null ? "–" : fmtV(vb - va)));
      }));
  }

  // At most 10 redraws a second, only when something changed: a frame is asked for only
  // then (a frame asked for at every refresh of the screen costs the tab's renderer even when
  // it draws nothing).
  let framePending = false;
  setInterval(() => {
    if (scope.dirty && !framePending) {
      framePending = true;
      requestAnimationFrame(frame);
    }
  }, 100);
  function frame() {
    framePending = false;
    const u = scope.plot;
    if (!u || !scope.dirty) return;
    scope.dirty = false;
    const data = columns(liveFrom());
    u.setData(data, false);
    const x = data[0];
    if (scope.view) {
      setX(scope.view.min, scope.view.max);
    } else if (scope.loaded || (cs().capture && q("#trig-signal").value)) {
      const c = cs();
      if (scope.loaded) setX(x[0], x[x.length - 1]); else setX(c.capture.t0, c.capture.t1);
    } else if (x.length) {
      const t1 = x[x.length - 1];
      setX(t1 - win(), t1);
    }
    showCursors();
  }

  // ------------------------------------------------------------------------------ wiring

  function on(sel, ev, f) { q(sel).addEventListener(ev, f); }

  on("#pause", "click", () => { setPaused(!cs().paused); });
  for (const id of ["#trig-signal", "#trig-level", "#trig-edge", "#trig-pre", "#window"]) on(id, "change", rearm);
  on("#scope-object-set", "click", async () => {
    const v = q("#scope-object").value.trim();
    if (v && !keyOf(v)) { say(`object ${v}: index:sub in hex, e.g. 6041:0`, true); return; }
    try {
      if (v) await addTrace(scope.page, v, "object"); else removeTrace("object");
      showObjectName();
      say(v ? `sampling ${v}` : "sampling the plant");
    } catch (e) { say(e.message, true); }
  });
  on("#trace-add", "click", async () => {
    const drive = Number(q("#trace-drive").value), signal = q("#trace-signal").value.trim();
    try {
      const t = await addTrace(drive, signal);
      say(`trace ${t.label} [${t.unit}]`);
    } catch (e) { say(e.message, true); }
  });
  on("#scope-rate", "change", () => {
    scope.rate = Number(q("#scope-rate").value) || 200;
    for (const b of scope.buffers.values()) b.length = 0;
    rearm();
    for (const d of scope.sockets.keys()) connect(d);
  });
  on("#scope-pos-unit", "change", async () => {
    scope.positionUnit = q("#scope-pos-unit").value === "user" ? "user" : "inc";
    try {
      for (const t of scope.traces.filter((x) => x.signal === "position" || x.plant === "position")) {
        await addTrace(t.drive, "position", t.id);
      }
      const pos = scope.traces.find((t) => t.plant === "position");
      say(scope.positionUnit === "user" && !pos ? "positions in increments: no drive with 6064h" : `positions in ${scope.positionUnit === "user" ? "user units" : "increments"}`);
    } catch (e) { say(e.message, true); }
  });
  on("#scope-follow", "click", () => { scope.view = null; scope.dirty = true; });
  on("#scope-left", "click", () => pan(-0.25));
  on("#scope-right", "click", () => pan(0.25));
  on("#scope-zoom-in", "click", () => zoom(0.5));
  on("#scope-zoom-out", "click", () => zoom(2));
  on("#cursor-clear", "click", () => { scope.cursors = { a: null, b: null }; showCursors(); if (scope.plot) scope.plot.redraw(false); });
  on("#export-csv", "click", () => download("scope.csv", "text/csv", csv()));
  on("#export-trace", "click", () => download("scope-trace.json", "application/json", traceFile()));
  on("#open-trace", "change", async (e) => {
    const f = e.target.files[0];
    if (!f) return;
    try { openTraceFile(await f.text()); say(`trace file ${f.name}`); } catch (err) { say(err.message, true); }
    e.target.value = "";
  });
  on("#close-trace", "click", () => { scope.loaded = null; buildPlot(); setPaused(false); });
  // The plot takes its box's width (the box is hidden until a drive's page opens).
  new ResizeObserver(() => {
    const w = q("#scope-plot").clientWidth;
    if (scope.plot && w > 0 && Math.abs(scope.plot.width - w) > 1) scope.plot.setSize({ width: w, height: 360 });
  }).observe(q("#scope-plot"));

  function pan(f) {
    const u = scope.plot;
    if (!u) return;
    const { min, max } = u.scales.x;
    scope.view = { min: min + (max - min) * f, max: max + (max - min) * f };
    scope.dirty = true;
  }
  function zoom(f) {
    const u = scope.plot;
    if (!u) return;
    const { min, max } = u.scales.x, mid = (min + max) / 2;
    scope.view = { min: mid - ((max - min) * f) / 2, max: mid + ((max - min) * f) / 2 };
    scope.dirty = true;
  }

  Object.assign(scope, { open, close, addTrace, removeTrace, setCursor, csv, traceFile, openTraceFile, columns, setPaused });
})();
