// The cell page: each drive's state, mode, position and velocity live with sparklines, its
// active error with the text of the drive's own diagnostic table, the buses' load and the wire
// faults in force.
//
// Position, velocity and the mode (6061h) come from each drive's live WebSocket
// (/api/drives/N/samples) at a low rate: the samples the cell loop already queues for the
// console, never a request of their own. State and error come from the motion view, the
// buses' load and the faults from the REST API, once a second while the page is shown.
//
// As on the drive's page (console.js: setText, replaceIfChanged, later), a text is written
// only when it changes, the rows are built again only when the drives change, and the live
// cells are drawn in a frame asked for only when a batch of samples came.
"use strict";

(function () {
  const SPARK_S = 10;          // seconds a sparkline shows
  const RATE_HZ = 20;          // samples per second asked of the cell loop
  const BATCH_MS = 250;        // one message per quarter second
  const W = 120, H = 26;       // sparkline size, px

  // CiA 402 §6.4.1 (6060h / 6061h): the modes of operation.
  const MODES = { 0: "no mode", 1: "PP", 2: "VL", 3: "PV", 4: "PT", 6: "HM", 7: "IP", 8: "CSP", 9: "CSV", 10: "CST" };

  const overview = {
    sockets: new Map(),   // drive → WebSocket
    samples: new Map(),   // drive → [{t, position, velocity, mode}]
    drives: [],
    shown: false,
  };
  window.overview = overview;

  const q = (sel) => document.querySelector(sel);
  function el(tag, attrs = {}, ...children) {
    const e = document.createElementNS(tag === "svg" || tag === "polyline" ? "http://www.w3.org/2000/svg" : "http://www.w3.org/1999/xhtml", tag);
    for (const [k, v] of Object.entries(attrs)) {
      if (k === "class") e.setAttribute("class", v); else e.setAttribute(k, v);
    }
    for (const c of children) e.append(c instanceof Node ? c : document.createTextNode(c ?? ""));
    return e;
  }

  function modeName(m) {
    if (m == null) return "–";
    if (MODES[m] != null) return `${MODES[m]} (${m})`;
    return m < 0 ? `vendor mode ${m}` : String(m);
  }

  function fmt(v, digits = 0) {
    return v == null ? "–" : Number(v).toFixed(digits);
  }

  // A sparkline: the last SPARK_S seconds of one signal as the points of an SVG polyline.
  function sparkPoints(points, key) {
    const pts = points.filter((p) => p[key] != null);
    if (pts.length < 2) return "";
    const t1 = pts[pts.length - 1].t, t0 = t1 - SPARK_S;
    let lo = Infinity, hi = -Infinity;
    for (const p of pts) { lo = Math.min(lo, p[key]); hi = Math.max(hi, p[key]); }
    if (hi - lo < 1e-9) { hi += 1; lo -= 1; }
    const xy = pts.map((p) => `${((p.t - t0) / SPARK_S * W).toFixed(1)},${(H - 2 - (p[key] - lo) / (hi - lo) * (H - 4)).toFixed(1)}`);
    return xy.join(" ");
  }

  function sparkline(key) {
    return el("svg", { class: "spark", width: String(W), height: String(H), viewBox: `0 0 ${W} ${H}`, "data-signal": key },
      el("polyline", { points: "", fill: "none", "stroke-width": "1.5" }));
  }

  // A live cell: its number and its sparkline, made once with the row.
  function liveCell(key) {
    return el("td", { class: key }, el("span", { class: "num" }, "–"), " ", sparkline(key));
  }

  function connect(d) {
    const proto = location.protocol === "https:" ? "wss" : "ws";
    const objects = d.profile === "cia402" ? "&objects=6061:0" : "";
    const ws = new WebSocket(`${proto}://${location.host}/api/drives/${d.index}/samples?rate_hz=${RATE_HZ}&batch_ms=${BATCH_MS}${objects}`);
    ws.onmessage = (ev) => {
      if (overview.sockets.get(d.index) !== ws) return;
      const batch = JSON.parse(ev.data);
      const s = overview.samples.get(d.index) || [];
      for (const p of batch.samples) {
        s.push({ t: p.t, position: p.position, velocity: p.velocity,
                 mode: p.objects && p.objects["6061:00"] != null ? p.objects["6061:00"] : null });
      }
      const last = s[s.length - 1];
      let cut = 0;
      while (cut < s.length && last.t - s[cut].t > SPARK_S) cut++;
      if (cut) s.splice(0, cut);
      overview.samples.set(d.index, s);
      if (batch.samples.length) later(`overview ${d.index}`, () => drawLive(d.index));
    };
    overview.sockets.set(d.index, ws);
  }

  // The live cells of one drive's row: mode, position and velocity with their sparklines.
  function drawLive(index) {
    const row = q(`#cell-table tr[data-drive='${index}']`);
    const s = overview.samples.get(index);
    if (!overview.shown || !row || !s || !s.length) return;
    const last = s[s.length - 1];
    const d = overview.drives.find((x) => x.index === index) || {};
    const posUnit = d.profile === "fhpp" ? "SI" : "inc";
    setText(row.querySelector("td.mode"), d.profile === "cia402" ? modeName(last.mode) : "–");
    setText(row.querySelector("td.position .num"), `${fmt(last.position, d.profile === "fhpp" ? 4 : 0)} ${posUnit}`);
    setText(row.querySelector("td.velocity .num"), last.velocity == null ? "–" : `${fmt(last.velocity, 0)} rpm`);
    for (const key of ["position", "velocity"]) {
      const line = row.querySelector(`td.${key} polyline`);
      const points = sparkPoints(s, key);
      if (line.getAttribute("points") !== points) line.setAttribute("points", points);
    }
  }

  // The table's rows: one per drive, built again only when the drives change; its state,
  // display and error from the motion view, written where they changed.
  function drawRows(drives, views) {
    const body = q("#cell-table tbody");
    const built = drives.map((d) => [d.index, d.device, d.product, d.interface, d.node]);
    replaceIfChanged(body, JSON.stringify(built), () => drives.map((d) =>
      el("tr", { "data-drive": String(d.index) },
        el("td", {}, String(d.index)), el("td", {}, el("a", { href: `#drive/${d.index}` }, d.device)), el("td", {}, d.product),
        el("td", {}, d.interface + (d.node != null ? ` node ${d.node}` : "")),
        el("td", { class: "state" }, "–"), el("td", { class: "mode" }, "–"), liveCell("position"), liveCell("velocity"),
        el("td", { class: "mono display" }, ""), el("td", { class: "error fault" }, ""))));
    drives.forEach((d, i) => {
      const row = body.children[i];
      const v = views[i];
      const state = v ? v.state : (d.state ?? "–");
      const cell = row.querySelector("td.state");
      setText(cell, state);
      setClass(cell, "state" + (state.startsWith("FAULT") ? " fault" : ""));
      setText(row.querySelector("td.display"), (v && v.display) ?? d.display ?? "");
      setText(row.querySelector("td.error"), v && v.active_error ? `${v.active_error.code} ${v.active_error.text}` : "");
      drawLive(d.index);
    });
  }

  function faultText(f) {
    const what = f.fault + (f.share != null ? ` ${Math.round(f.share * 100)} %` : "")
      + (f.delay_ms != null ? ` ${f.delay_ms} ms` : "");
    const where = f.node != null ? `node ${f.node}` : f.reach;
    const cob = f.cob_id != null ? ` COB-ID ${f.cob_id.toString(16).toUpperCase()}h` : "";
    const left = f.frames_left != null ? `, ${f.frames_left} frames left` : "";
    const until = f.until_s != null ? `, until ${f.until_s.toFixed(1)} s` : "";
    return `${what} on ${where}${cob}${left}${until}`;
  }

  // The buses with their load, and every fault in force on a front end of the cell: its
  // buses, the Modbus servers of its Modbus drives (in cell order) and its EtherCAT chain.
  async function drawWire(api, drives) {
    const buses = await api("GET", "/api/buses").catch(() => []);
    const loads = buses.map((b) => [b.index, `bus ${b.index}: ` + (b.bitrate == null ? "instant"
      : `${b.bitrate / 1000} kbit/s, load ${fmt(b.load_percent, 1)} %`)
      + (b.late ? `, ${b.late} late` : "") + (b.dropped ? `, ${b.dropped} dropped` : "")]);
    replaceIfChanged(q("#bus-load"), JSON.stringify(loads), () => (loads.length
      ? loads.map(([index, text]) => el("span", { class: "bus", "data-bus": String(index) }, text))
      : [el("span", { class: "muted" }, "no CAN bus")]));
    const fronts = buses.map((b) => ["bus", b.index]);
    drives.filter((d) => d.interface === "modbus-tcp").forEach((d, k) => fronts.push(["modbus", k]));
    if (drives.some((d) => d.interface === "ethercat")) fronts.push(["ethercat", 0]);
    const lists = await Promise.all(fronts.map(([kind, n]) =>
      api("GET", `/api/wire/${kind}/${n}/faults`).then((f) => f.map((x) => [kind, n, x])).catch(() => [])));
    const faults = lists.flat().map(([kind, n, f]) => [`${kind}/${n}`, String(f.id), `${kind} ${n}: ${faultText(f)}`]);
    replaceIfChanged(q("#wire-faults"), JSON.stringify(faults), () => (faults.length
      ? faults.map(([front, id, text]) => el("li", { class: "fault", "data-front": front, "data-fault": id }, text))
      : [el("li", { class: "muted" }, "none")]));
  }

  // Called by the console each second while the cell page is shown.
  overview.refresh = async function (api, drives) {
    overview.drives = drives;
    overview.shown = true;
    for (const [i, ws] of overview.sockets) {
      if (!drives.some((d) => d.index === i)) { ws.close(); overview.sockets.delete(i); }
    }
    for (const d of drives) if (!overview.sockets.has(d.index)) connect(d);
    const views = await Promise.all(drives.map((d) =>
      api("GET", `/api/drives/${d.index}/motion`).catch(() => null)));
    if (!overview.shown) return;
    drawRows(drives, views);
    await drawWire(api, drives);
  };

  // The page of a drive is shown: no samples for the overview.
  overview.close = function () {
    overview.shown = false;
    for (const ws of overview.sockets.values()) ws.close();
    overview.sockets.clear();
    overview.samples.clear();
  };
})();
