// The drivetwin web console: the cell's drives, a drive's state and statusword bit by bit,
// its parameters with edit, enable / disable, and a scope of position, velocity and current
// fed by the live WebSocket. Plain script, no library.
"use strict";

const token = new URLSearchParams(location.search).get("token");
const WINDOW_S = 10;
const consoleState = { drive: null, drives: [], samples: [], paused: false, socket: null };
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
  if (!r.ok) throw new Error(data.error || `HTTP ${r.status}`);
  return data;
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
  $("#cell-table tbody").replaceChildren(...consoleState.drives.map((d) => el("tr", {},
    el("td", {}, String(d.index)), el("td", {}, d.device), el("td", {}, d.product),
    el("td", {}, d.interface + (d.node != null ? ` node ${d.node}` : "")),
    el("td", { class: d.state === "FAULT" ? "fault" : "" }, d.state ?? "–"),
    el("td", { class: "mono" }, d.display ?? ""))));
}

// --------------------------------------------------------------------------------- drive

function showDrive(view) {
  $("#drive-title").textContent = `Drive ${view.index}: ${view.product} (${view.device}, ${view.profile})`;
  const state = $("#state");
  state.textContent = view.state ?? "no CiA 402 state";
  state.className = "state" + (view.state === "FAULT" ? " fault" : "");
  $("#statusword").textContent = view.statusword != null
    ? "6041h = 0x" + view.statusword.toString(16).toUpperCase().padStart(4, "0") : "";
  $("#display").textContent = view.display ?? "";
  $("#status-bits tbody").replaceChildren(...view.status_bits.map((b) =>
    el("tr", { class: b.set ? "bit-on" : "" }, el("td", {}, String(b.bit)), el("td", {}, b.set ? "1" : "0"),
       el("td", {}, b.name))));
  const cia402 = view.statusword != null;
  $("#enable").disabled = !cia402;
  $("#disable").disabled = !cia402;
}

// Every request for the drive's view takes a number; an answer that a later request has
// overtaken (a periodic refresh sent before Enable was clicked) is not shown.
let viewSeq = 0;

async function fetchView(method, path) {
  const seq = ++viewSeq;
  const view = await api(method, path);
  if (seq === viewSeq) showDrive(view);
  return view;
}

async function refreshDrive() {
  if (consoleState.drive === null) return;
  try {
    await fetchView("GET", `/api/drives/${consoleState.drive}`);
  } catch (e) {
    say(e.message, true);
  }
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
        say(`${o.index}:${o.sub} ${o.name}: ${e.message}`, true);
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

function connectSamples(drive) {
  if (consoleState.socket) consoleState.socket.close();
  consoleState.samples = [];
  const proto = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${proto}://${location.host}/api/drives/${drive}/samples?rate_hz=100&batch_ms=50`);
  ws.onmessage = (ev) => {
    if (consoleState.paused) return;
    const batch = JSON.parse(ev.data);
    const s = consoleState.samples;
    s.push(...batch.samples);
    const last = s[s.length - 1];
    while (s.length && last.t - s[0].t > WINDOW_S) s.shift();
    if (batch.display != null) $("#display").textContent = batch.display;
  };
  ws.onclose = () => { if (consoleState.socket === ws) $("#connection").textContent = "samples stopped"; };
  consoleState.socket = ws;
}

const TRACES = [["position", "#4fc3f7"], ["velocity", "#aed581"], ["current", "#ffb74d"]];

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
  const s = consoleState.samples;
  if (s.length >= 2) {
    const t1 = s[s.length - 1].t, t0 = t1 - WINDOW_S;
    for (const [name, color] of TRACES) {
      const vals = s.map((p) => p[name]).filter((v) => v != null);
      if (!vals.length) continue;
      let lo = Math.min(...vals), hi = Math.max(...vals);
      if (hi - lo < 1e-9) { lo -= 1; hi += 1; }
      g.strokeStyle = color;
      g.lineWidth = 1.5;
      g.beginPath();
      let first = true;
      for (const p of s) {
        if (p[name] == null) continue;
        const x = ((p.t - t0) / WINDOW_S) * w;
        const y = h - 8 - ((p[name] - lo) / (hi - lo)) * (h - 16);
        if (first) { g.moveTo(x, y); first = false; } else g.lineTo(x, y);
      }
      g.stroke();
      const v = s[s.length - 1][name];
      $(`#v-${name}`).textContent = v == null ? "–" : Number(v).toFixed(1);
    }
  }
  requestAnimationFrame(drawScope);
}

// -------------------------------------------------------------------------------- wiring

async function route() {
  const m = location.hash.match(/^#drive\/(\d+)$/);
  consoleState.drive = m ? Number(m[1]) : null;
  await loadCell();
  $("#drive").hidden = consoleState.drive === null;
  if (consoleState.drive === null) {
    if (consoleState.socket) consoleState.socket.close();
    consoleState.socket = null;
    return;
  }
  say("");
  await refreshDrive();
  connectSamples(consoleState.drive);
  await loadParams();
}

$("#enable").addEventListener("click", async () => {
  try {
    await fetchView("POST", `/api/drives/${consoleState.drive}/enable`);
    say("enabled");
  } catch (e) { say(e.message, true); }
});
$("#disable").addEventListener("click", async () => {
  try {
    await fetchView("POST", `/api/drives/${consoleState.drive}/disable`);
    say("disabled");
  } catch (e) { say(e.message, true); }
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
$("#pause").addEventListener("click", () => {
  consoleState.paused = !consoleState.paused;
  $("#pause").textContent = consoleState.paused ? "Run" : "Pause";
});
$("#filter").addEventListener("input", applyFilter);
window.addEventListener("hashchange", route);
setInterval(() => { refreshDrive(); refreshPlant(); loadCell(); }, 1000);
requestAnimationFrame(drawScope);
route();
