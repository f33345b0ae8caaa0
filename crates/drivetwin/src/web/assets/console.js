// The drivetwin web console: the cell's drives (overview.js), a drive's state and statusword
// bit by bit, its parameters with edit, export and import (parameters.js), enable / disable,
// and a scope of position, velocity and current (scope.js, on uPlot) fed by the live WebSocket.
//
// The page is refreshed once a second, but a text is written only when it changes and a
// frame is asked for only when there is something to draw: each write, even of the same
// text, makes the browser lay out and paint the page again, and a tab left open on a drive at
// rest should cost the machine its cell runs on nothing.
"use strict";

const token = new URLSearchParams(location.search).get("token");
const consoleState = { drive: null, drives: [], samples: [], paused: false, jogging: false };
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

// An element's text, class and hidden flag, written only when they differ.
function setText(e, text) {
  if (e.textContent !== text) e.textContent = text;
}
function setClass(e, name) {
  if (e.className !== name) e.className = name;
}
function setHidden(e, hidden) {
  if (e.hidden !== hidden) e.hidden = hidden;
}

// A container's children, built again only when what they show (`key`) changed.
const shownKeys = new WeakMap();
function replaceIfChanged(e, key, build) {
  if (shownKeys.get(e) === key) return;
  shownKeys.set(e, key);
  e.replaceChildren(...build());
}

// Drawing in the next frame, asked for only when something is to be drawn: `later(key, f)`
// runs `f` in the next animation frame, once however often it was asked for with `key` (the
// last `f` given wins).
const drawQueue = new Map();
let drawFrame = false;
function later(key, f) {
  drawQueue.set(key, f);
  if (drawFrame) return;
  drawFrame = true;
  requestAnimationFrame(() => {
    drawFrame = false;
    const due = [...drawQueue.values()];
    drawQueue.clear();
    for (const g of due) g();
  });
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
  setText(m, text);
  setClass(m, error ? "error" : "");
}

// ---------------------------------------------------------------------------------- cell

async function loadCell() {
  try {
    consoleState.drives = await api("GET", "/api/drives");
    setText($("#connection"), "");
  } catch (e) {
    setText($("#connection"), `no answer: ${e.message}`);
    return;
  }
  const links = consoleState.drives.map((d) => [d.index, d.device]);
  replaceIfChanged($("#drives"), JSON.stringify([links, consoleState.drive]), () => links.map(([index, device]) =>
    el("a", { href: `#drive/${index}`, class: "drive-link" + (index === consoleState.drive ? " current" : ""),
              "data-drive": String(index) }, `${index}: ${device}`)));
  // The overview (overview.js) while the cell page is shown.
  if (consoleState.drive === null) await window.overview.refresh(api, consoleState.drives);
}

// --------------------------------------------------------------------------------- drive

// The drive's view is drawn in the next frame, and only when it differs from the one shown
// (a drive at rest answers the same view each second).
let viewShown = null;
function showDrive(view) {
  const d = consoleState.drives.find((x) => x.index === view.drive) || {};
  const title = `Drive ${view.drive}: ${d.product ?? ""} (${d.device ?? ""}, ${view.profile})`;
  const key = JSON.stringify([title, view, token]);
  if (key === viewShown) return;
  viewShown = key;
  later("view", () => drawDrive(view, title));
}

function drawDrive(view, title) {
  setText($("#drive-title"), title);
  const state = $("#state");
  setText(state, view.state);
  setClass(state, "state" + (view.state.startsWith("FAULT") ? " fault" : ""));
  const hex = (v, n) => "0x" + v.toString(16).toUpperCase().padStart(n, "0");
  setText($("#statusword"), view.profile === "cia402" ? `6041h = ${hex(view.word, 4)}`
    : `SCON = ${hex(view.word & 0xFF, 2)} SPOS = ${hex(view.word >> 8, 2)}`);
  // A drive without a display (null) shows none.
  setText($("#display"), view.display ?? "");
  setHidden($("#display-shown"), view.display == null);
  setHidden($("#web-server-link"), view.profile !== "fhpp");
  const server = `/cmmo-st/${view.drive}` + (token ? `?token=${token}` : "");
  if ($("#web-server").getAttribute("href") !== server) $("#web-server").setAttribute("href", server);
  setText($("#active-error"), view.active_error ? `${view.active_error.code} ${view.active_error.text}` : "none");
  setClass($("#active-error"), view.active_error ? "fault" : "muted");
  setText($("#device-control"), view.device_control ? `device control: ${view.device_control}` : "");
  replaceIfChanged($("#status-bits tbody"), JSON.stringify(view.bits), () => view.bits.map((b) =>
    el("tr", { class: b.set ? "bit-on" : "", "data-bit": `${b.word}.${b.bit}` }, el("td", {}, b.word),
       el("td", {}, String(b.bit)), el("td", {}, b.set ? "1" : "0"), el("td", {}, b.name))));
  replaceIfChanged($("#history tbody"), JSON.stringify(view.history), () => view.history.map((h, i) =>
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
  setHidden($("#kinco-panel"), !p);
  if (!p) return;
  setText($("#panel-digits"), p.text);
  setText($("#panel-blink"), p.blink === "steady" ? "" : `(blinking: ${p.blink})`);
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

// -------------------------------------------------------------------------------- wiring

async function route() {
  const m = location.hash.match(/^#drive\/(\d+)$/);
  consoleState.drive = m ? Number(m[1]) : null;
  $("#drive").hidden = consoleState.drive === null;
  if (consoleState.drive === null) {
    window.scope.close();
    await loadCell();
    return;
  }
  window.overview.close();
  say("");
  showWhy("#enable-why", null);
  showWhy("#motion-why", null);
  // The drive's state first, then the cell (whose links show the page is ready).
  try { consoleState.drives = await api("GET", "/api/drives"); } catch (e) { /* loadCell says */ }
  await refreshDrive();
  await loadCell();
  await window.scope.open(consoleState.drive);
  await window.parameters.load(consoleState.drive);
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
  setText($("#din"), p.digital_inputs == null ? "–" : "0x" + p.digital_inputs.toString(16).toUpperCase().padStart(8, "0"));
}
async function refreshPlant() {
  if (consoleState.drive === null) return;
  try { showPlant(await api("GET", `/api/drives/${consoleState.drive}/plant`)); } catch (e) { /* shown by the view */ }
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
$("#home").addEventListener("click", () => motion("home", undefined, "homing started"));
$("#move").addEventListener("click", () => motion("move",
  { target: Number($("#move-target").value) || 0, relative: $("#move-relative").checked },
  `moving to ${$("#move-target").value}`));
window.addEventListener("hashchange", route);
setInterval(() => { refreshDrive(); refreshPlant(); loadCell(); }, 1000);
route();
