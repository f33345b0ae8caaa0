// The drivetwin web console: the cell's drives, a drive's state and statusword bit by bit,
// its parameters with edit, enable / disable, and a scope of position, velocity and current
// fed by the live WebSocket. Plain script, no library.
"use strict";

const token = new URLSearchParams(location.search).get("token");
const WINDOW_S = 10;
const consoleState = { drive: null, drives: [], samples: [], paused: false, socket: null, jogging: false };
window.consoleState = consoleState;

const $ = (sel) => document.querySelector(sel);

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v; else e.setAttribute(k, v);
  }
  for (const c of children) e.append(c instanceof Node ? c : document.createTextNode(c ?? ""));
  return e;
}

async function api(method, path, body) {
  const headers = {};
  if (body !== undefined) headers["content-type"] = "application/json";
  if (token) headers["x-drivetwin-token"] = token;
  const r = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  const data = await r.json().catch(() => ({ error: `HTTP ${r.status}` }));
  if (!r.ok) {
    // A refusal carries the drive's reason and its manual's rule (`reason`).
    const e = new Error(data.error || `HTTP ${r.status}`);
    e.reason = data.reason ?? null;
    throw e;
  }
  return data;
}

// The reason a control was refused, shown next to it: the drive's reason and the manual's rule.
function showWhy(sel, e) {
  const w = $(sel);
  if (!e) { w.hidden = true; w.replaceChildren(); return; }
  w.replaceChildren(el("span", { class: "reason" }, e.reason ? e.reason.text : e.message));
  if (e.reason) w.append(el("br"), el("span", { class: "rule" }, e.reason.rule));
  w.dataset.kind = e.reason ? e.reason.kind : "";
  w.hidden = false;
}

function say(text, error = false) {
  const m = $("#message");
  m.textContent = text;
  m.className = error ? "error" : "";
}

// ---------------------------------------------------------------------------------- cell

async function loadCell() {
  try {
    consoleState.drives = await api("GET", "/api/drives");
    $("#connection").textContent = "";
  } catch (e) {
    $("#connection").textContent = `no answer: ${e.message}`;
    return;
  }
  const nav = $("#drives");
  nav.replaceChildren(...consoleState.drives.map((d) =>
    el("a", { href: `#drive/${d.index}`, class: "drive-link" + (d.index === consoleState.drive ? " current" : ""),
              "data-drive": String(d.index) }, `${d.index}: ${d.device}`)));
  // The state and active error of each drive, from its motion view (CiA 402 or FHPP alike).
  const views = await Promise.all(consoleState.drives.map((d) =>
    api("GET", `/api/drives/${d.index}/motion`).catch(() => null)));
  $("#cell-table tbody").replaceChildren(...consoleState.drives.map((d, i) => {
    const v = views[i];
    const state = v ? v.state : (d.state ?? "–");
    const err = v && v.active_error ? `${v.active_error.code} ${v.active_error.text}` : "";
    return el("tr", { "data-drive": String(d.index) },
      el("td", {}, String(d.index)), el("td", {}, el("a", { href: `#drive/${d.index}` }, d.device)), el("td", {}, d.product),
      el("td", {}, d.interface + (d.node != null ? ` node ${d.node}` : "")),
      el("td", { class: "state" + (state.startsWith("FAULT") ? " fault" : "") }, state),
      el("td", { class: "mono" }, (v && v.display) ?? d.display ?? ""),
      el("td", { class: "error fault" }, err));
  }));
}

// --------------------------------------------------------------------------------- drive

function showDrive(view) {
  const d = consoleState.drives.find((x) => x.index === view.drive) || {};
  $("#drive-title").textContent = `Drive ${view.drive}: ${d.product ?? ""} (${d.device ?? ""}, ${view.profile})`;
  const state = $("#state");
  state.textContent = view.state;
  state.className = "state" + (view.state.startsWith("FAULT") ? " fault" : "");
  const hex = (v, n) => "0x" + v.toString(16).toUpperCase().padStart(n, "0");
  $("#statusword").textContent = view.profile === "cia402" ? `6041h = ${hex(view.word, 4)}`
    : `SCON = ${hex(view.word & 0xFF, 2)} SPOS = ${hex(view.word >> 8, 2)}`;
  $("#display").textContent = view.display ?? "";
  $("#web-server-link").hidden = view.profile !== "fhpp";
  $("#web-server").href = `/cmmo-st/${view.drive}` + (token ? `?token=${token}` : "");
  $("#active-error").textContent = view.active_error ? `${view.active_error.code} ${view.active_error.text}` : "none";
  $("#active-error").className = view.active_error ? "fault" : "muted";
  $("#device-control").textContent = view.device_control ? `device control: ${view.device_control}` : "";
  $("#status-bits tbody").replaceChildren(...view.bits.map((b) =>
    el("tr", { class: b.set ? "bit-on" : "", "data-bit": `${b.word}.${b.bit}` }, el("td", {}, b.word),
       el("td", {}, String(b.bit)), el("td", {}, b.set ? "1" : "0"), el("td", {}, b.name))));
  $("#history tbody").replaceChildren(...view.history.map((h, i) =>
    el("tr", {}, el("td", {}, String(i + 1)), el("td", { class: "mono" }, h.code), el("td", {}, h.text),
       el("td", {}, h.event ?? ""), el("td", {}, h.time_ms == null ? "" : String(h.time_ms)))));
}

// Every request for the drive's view takes a number; an answer that a later request has
// overtaken (a periodic refresh sent before Enable was clicked) is not shown.
let viewSeq = 0;

async function fetchView(method, path, body) {
  const seq = ++viewSeq;
  const view = await api(method, path, body);
  if (seq === viewSeq) showDrive(view);
  return view;
}

async function refreshDrive() {
  if (consoleState.drive === null) return;
  try {
    await fetchView("GET", `/api/drives/${consoleState.drive}/motion`);
  } catch (e) {
    say(e.message, true);
  }
  await refreshPanel();
}

// The Kinco LED panel (GET /api/drives/N/panel; a drive without one answers 404).
function showPanel(p) {
  $("#kinco-panel").hidden = !p;
  if (!p) return;
  $("#panel-digits").textContent = p.text;
  $("#panel-blink").textContent = p.blink === "steady" ? "" : `(blinking: ${p.blink})`;
}
async function refreshPanel() {
  const drive = consoleState.drive;
  if (drive === null) return;
  // Only the Kinco drives have one: no request (and no 404) for the others.
  const d = (consoleState.drives || []).find((x) => x.index === drive);
  if (!d || !d.vendor.toLowerCase().startsWith("kinco")) { showPanel(null); return; }
  let p = null;
  try { p = await api("GET", `/api/drives/${drive}/panel`); } catch (e) { p = null; }
  if (drive === consoleState.drive) showPanel(p);
}
async function panelKey(key, action) {
  try {
    showPanel(await api("POST", `/api/drives/${consoleState.drive}/panel/keys`, { key, action }));
  } catch (e) { say(e.message, true); }
}

function paramKey(o) {
  return `${o.index.replace(/^0x/i, "").toUpperCase()}:${o.sub.toString(16).toUpperCase().padStart(2, "0")}`;
}

function paramRow(o) {
  const value = el("td", { class: "value" }, o.value ?? (o.read_error ? "–" : ""));
  if (o.read_error) value.title = o.read_error;
  const cells = [
    el("td", { class: "mono" }, o.index), el("td", {}, String(o.sub)), el("td", {}, o.name),
    el("td", {}, o.type), el("td", {}, o.access), el("td", {}, o.unit),
    el("td", {}, o.min == null ? "" : String(o.min)), el("td", {}, o.max == null ? "" : String(o.max)), value,
  ];
  const edit = el("td");
  if (o.access === "rw" || o.access === "wo") {
    const input = el("input", { class: "edit", "aria-label": `new value of ${o.name}` });
    const button = el("button", { type: "button", class: "write" }, "Write");
    const write = async () => {
      try {
        const back = await api("PUT", `/api/drives/${consoleState.drive}/objects/${o.index}/${o.sub.toString(16)}`,
                               { value: input.value });
        value.textContent = back.value ?? "";
        say(`${o.index}:${o.sub} ${o.name} = ${back.value ?? input.value}`);
        input.value = "";
      } catch (e) {
        say(`${o.index}:${o.sub} ${o.name}: ${e.message}` + (e.reason ? ` (${e.reason.rule})` : ""), true);
      }
    };
    button.addEventListener("click", write);
    input.addEventListener("keydown", (ev) => { if (ev.key === "Enter") write(); });
    edit.append(input, " ", button);
  }
  cells.push(edit);
  return el("tr", { "data-key": paramKey(o) }, ...cells);
}

async function loadParams() {
  const body = $("#params tbody");
  body.replaceChildren(el("tr", {}, el("td", { colspan: "10" }, "reading…")));
  try {
    const objects = await api("GET", `/api/drives/${consoleState.drive}/objects`);
    body.replaceChildren(...objects.map(paramRow));
    applyFilter();
  } catch (e) {
    body.replaceChildren(el("tr", {}, el("td", { colspan: "10" }, e.message)));
  }
}

function applyFilter() {
  const f = $("#filter").value.trim().toLowerCase();
  for (const tr of $("#params tbody").rows) {
    tr.hidden = f !== "" && !tr.textContent.toLowerCase().includes(f);
  }
}

// --------------------------------------------------------------------------------- scope

// The scope keeps the last minute of samples; a trigger (a level crossed by a chosen signal,
// rising or falling) freezes one window around the crossing, `pre-trigger` percent of it
// before. Free running, it shows the last window.
const KEEP_S = 60;

async function connectSamples(drive) {
  const old = consoleState.socket;
  consoleState.socket = null;
  if (old) old.close();
  consoleState.samples = [];
  consoleState.capture = null;
  consoleState.triggers = 0;
  // 60F4h following error actual value, where the drive has it, sampled with the plant.
  const named = [];
  try { await api("GET", `/api/drives/${drive}/objects/60F4/0`); named.push("60F4:0"); } catch (e) { /* none */ }
  // One more object of the user's choice, plotted as "object" (read on the loop with every sample).
  const extra = $("#scope-object").value.trim();
  consoleState.objectKey = null;
  if (/^[0-9a-f]{1,4}:[0-9a-f]{1,2}$/i.test(extra)) {
    const [i, sub] = extra.split(":");
    consoleState.objectKey = `${i.toUpperCase().padStart(4, "0")}:${sub.toUpperCase().padStart(2, "0")}`;
    named.push(extra);
  }
  $("#object-name").textContent = consoleState.objectKey ? `object ${consoleState.objectKey}` : "";
  const objects = named.length ? `&objects=${named.join(",")}` : "";
  const proto = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${proto}://${location.host}/api/drives/${drive}/samples?rate_hz=200&batch_ms=50${objects}`);
  ws.onmessage = (ev) => {
    if (consoleState.paused) return;
    const batch = JSON.parse(ev.data);
    const s = consoleState.samples;
    for (const p of batch.samples) {
      if (p.objects && p.objects["60F4:00"] != null) p.following_error = p.objects["60F4:00"];
      if (p.objects && consoleState.objectKey && p.objects[consoleState.objectKey] != null) p.object = p.objects[consoleState.objectKey];
      s.push(p);
    }
    const last = s[s.length - 1];
    while (s.length && last.t - s[0].t > KEEP_S) s.shift();
    if (batch.display != null) $("#display").textContent = batch.display;
    checkTrigger();
  };
  ws.onopen = () => { if (consoleState.socket === ws) $("#connection").textContent = ""; };
  ws.onclose = () => { if (consoleState.socket === ws) $("#connection").textContent = "samples stopped"; };
  consoleState.socket = ws;
}

function scopeWindow() {
  const w = Number($("#window").value);
  return w >= 0.5 && w <= 60 ? w : 10;
}

// Looks for the trigger's crossing in the samples not yet searched; once the window after it
// is full, the capture is taken (and in "single" the scope pauses).
function checkTrigger() {
  const signal = $("#trig-signal").value;
  const status = $("#trig-status");
  if (!signal) { consoleState.capture = null; status.textContent = ""; return; }
  const s = consoleState.samples, win = scopeWindow();
  const pre = Math.min(Math.max(Number($("#trig-pre").value) || 0, 0), 90) / 100;
  const level = Number($("#trig-level").value), rising = $("#trig-edge").value === "rising";
  const last = s[s.length - 1];
  if (consoleState.pending == null) {
    let prev = null;
    const from = consoleState.searchedTo ?? -Infinity;
    for (const p of s) {
      const v = p[signal];
      if (v == null) continue;
      if (prev != null && p.t > from) {
        const crossed = rising ? prev < level && v >= level : prev > level && v <= level;
        if (crossed) { consoleState.pending = p.t; break; }
      }
      prev = v;
    }
    consoleState.searchedTo = last ? last.t : from;
  }
  if (consoleState.pending != null) {
    const t0 = consoleState.pending - pre * win, t1 = t0 + win;
    if (last && last.t >= t1) {
      consoleState.capture = { t0, t1, at: consoleState.pending, samples: s.filter((p) => p.t >= t0 && p.t <= t1) };
      consoleState.triggers += 1;
      consoleState.pending = null;
      consoleState.searchedTo = t1;
      status.textContent = `triggered at t = ${consoleState.capture.at.toFixed(3)} s (${consoleState.triggers})`;
      if ($("#trig-single").checked) setPaused(true);
    } else {
      status.textContent = "triggered, filling the window…";
    }
  } else if (!consoleState.capture) {
    status.textContent = "armed";
  }
}

const TRACES = [["position", "#4fc3f7"], ["velocity", "#aed581"], ["current", "#ffb74d"], ["following_error", "#e57373"],
                ["object", "#ce93d8"]];

function drawScope() {
  const canvas = $("#scope");
  const g = canvas.getContext("2d");
  const w = canvas.width, h = canvas.height;
  g.fillStyle = "#111";
  g.fillRect(0, 0, w, h);
  g.strokeStyle = "#333";
  g.lineWidth = 1;
  for (let i = 1; i < 10; i++) {
    g.beginPath(); g.moveTo((w * i) / 10, 0); g.lineTo((w * i) / 10, h); g.stroke();
  }
  const win = scopeWindow();
  let s = consoleState.samples, t0, t1;
  if ($("#trig-signal").value && consoleState.capture) {
    ({ t0, t1 } = consoleState.capture);
    s = consoleState.capture.samples;
    const x = ((consoleState.capture.at - t0) / win) * w;
    g.strokeStyle = "#888"; g.setLineDash([4, 4]);
    g.beginPath(); g.moveTo(x, 0); g.lineTo(x, h); g.stroke(); g.setLineDash([]);
  } else if (s.length) {
    t1 = s[s.length - 1].t; t0 = t1 - win;
    s = s.filter((p) => p.t >= t0);
  }
  if (s.length >= 2) {
    for (const [name, color] of TRACES) {
      const vals = s.map((p) => p[name]).filter((v) => v != null);
      if (!vals.length) continue;
      let lo = Math.min(...vals), hi = Math.max(...vals);
      if (name === $("#trig-signal").value) {
        const level = Number($("#trig-level").value);
        lo = Math.min(lo, level); hi = Math.max(hi, level);
      }
      if (hi - lo < 1e-9) { lo -= 1; hi += 1; }
      const y = (v) => h - 8 - ((v - lo) / (hi - lo)) * (h - 16);
      g.strokeStyle = color;
      g.lineWidth = 1.5;
      g.beginPath();
      let first = true;
      for (const p of s) {
        if (p[name] == null) continue;
        const x = ((p.t - t0) / win) * w;
        if (first) { g.moveTo(x, y(p[name])); first = false; } else g.lineTo(x, y(p[name]));
      }
      g.stroke();
      if (name === $("#trig-signal").value) {
        g.strokeStyle = color; g.setLineDash([2, 6]);
        g.beginPath(); g.moveTo(0, y(Number($("#trig-level").value))); g.lineTo(w, y(Number($("#trig-level").value))); g.stroke();
        g.setLineDash([]);
      }
      const v = vals[vals.length - 1];
      $(`#v-${name}`).textContent = v == null ? "–" : Number(v).toFixed(1);
    }
  }
  requestAnimationFrame(drawScope);
}

function setPaused(p) {
  consoleState.paused = p;
  $("#pause").textContent = p ? "Run" : "Pause";
}

// -------------------------------------------------------------------------------- wiring

async function route() {
  const m = location.hash.match(/^#drive\/(\d+)$/);
  consoleState.drive = m ? Number(m[1]) : null;
  $("#drive").hidden = consoleState.drive === null;
  if (consoleState.drive === null) {
    const old = consoleState.socket;
    consoleState.socket = null;
    if (old) old.close();
    await loadCell();
    return;
  }
  say("");
  showWhy("#enable-why", null);
  showWhy("#motion-why", null);
  // The drive's state first, then the cell (whose links show the page is ready).
  try { consoleState.drives = await api("GET", "/api/drives"); } catch (e) { /* loadCell says */ }
  await refreshDrive();
  await loadCell();
  await connectSamples(consoleState.drive);
  await loadParams();
}

$("#enable").addEventListener("click", async () => {
  try {
    await fetchView("POST", `/api/drives/${consoleState.drive}/motion/enable`);
    showWhy("#enable-why", null);
    say("enabled");
  } catch (e) { say(e.message, true); showWhy("#enable-why", e); }
});
$("#disable").addEventListener("click", async () => {
  try {
    await fetchView("POST", `/api/drives/${consoleState.drive}/motion/disable`);
    showWhy("#enable-why", null);
    say("disabled");
  } catch (e) { say(e.message, true); showWhy("#enable-why", e); }
});
$("#set-load").addEventListener("click", async () => {
  try {
    const p = await api("PUT", `/api/drives/${consoleState.drive}/load`, { torque_nm: Number($("#load").value) });
    say(`load torque ${Number($("#load").value)} N·m`);
    showPlant(p);
  } catch (e) { say(e.message, true); }
});
$("#set-inputs").addEventListener("click", async () => {
  const mask = Number($("#din-mask").value || 0), levels = Number($("#din-levels").value || 0);
  try {
    showPlant(await api("PUT", `/api/drives/${consoleState.drive}/inputs`, { mask, levels }));
    say(`inputs forced: mask 0x${mask.toString(16)} levels 0x${levels.toString(16)}`);
  } catch (e) { say(e.message, true); }
});
function showPlant(p) {
  $("#din").textContent = p.digital_inputs == null ? "–" : "0x" + p.digital_inputs.toString(16).toUpperCase().padStart(8, "0");
}
async function refreshPlant() {
  if (consoleState.drive === null) return;
  try { showPlant(await api("GET", `/api/drives/${consoleState.drive}/plant`)); } catch (e) { /* shown by the view */ }
}
$("#pause").addEventListener("click", () => setPaused(!consoleState.paused));
for (const id of ["#trig-signal", "#trig-level", "#trig-edge", "#trig-pre", "#window"]) {
  $(id).addEventListener("change", () => {
    consoleState.capture = null; consoleState.pending = null;
    const s = consoleState.samples;
    consoleState.searchedTo = s.length ? s[s.length - 1].t : undefined;
    checkTrigger();
  });
}

// Motion: jog while the button is held; home; move to a target.
async function motion(path, body, text) {
  try {
    await fetchView("POST", `/api/drives/${consoleState.drive}/motion/${path}`, body);
    showWhy("#motion-why", null);
    say(text);
  } catch (e) { say(e.message, true); showWhy("#motion-why", e); }
}
for (const [id, dir] of [["#jog-pos", 1], ["#jog-neg", -1]]) {
  const b = $(id);
  b.addEventListener("pointerdown", () => (consoleState.jogging = true) && motion("jog", { direction: dir, velocity: Number($("#jog-speed").value) || 0 },
                                                  `jogging ${dir > 0 ? "+" : "−"}`));
  for (const ev of ["pointerup", "pointerleave"]) {
    b.addEventListener(ev, () => { if (consoleState.jogging) { consoleState.jogging = false; motion("jog", { direction: 0 }, "jog stopped"); } });
  }
}
// A panel key goes down on press and up on release: a held key is a long press, ▲ / ▼ held in
// F006 jog the motor.
for (const b of document.querySelectorAll(".panel-key")) {
  b.addEventListener("pointerdown", () => { b.dataset.down = "1"; panelKey(b.dataset.key, "press"); });
  for (const ev of ["pointerup", "pointerleave"]) {
    b.addEventListener(ev, () => { if (b.dataset.down) { delete b.dataset.down; panelKey(b.dataset.key, "release"); } });
  }
}
$("#scope-object-set").addEventListener("click", async () => {
  const v = $("#scope-object").value.trim();
  if (v && !/^[0-9a-f]{1,4}:[0-9a-f]{1,2}$/i.test(v)) { say(`object ${v}: index:sub in hex, e.g. 6041:0`, true); return; }
  await connectSamples(consoleState.drive);
  say(v ? `sampling ${v}` : "sampling the plant");
});
$("#home").addEventListener("click", () => motion("home", undefined, "homing started"));
$("#move").addEventListener("click", () => motion("move",
  { target: Number($("#move-target").value) || 0, relative: $("#move-relative").checked },
  `moving to ${$("#move-target").value}`));
$("#filter").addEventListener("input", applyFilter);
window.addEventListener("hashchange", route);
setInterval(() => { refreshDrive(); refreshPlant(); loadCell(); }, 1000);
requestAnimationFrame(drawScope);
route();
