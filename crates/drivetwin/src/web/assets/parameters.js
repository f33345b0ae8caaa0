// The parameter table of a drive's page: every entry of its dictionary with group, unit,
// range, default, value and a mark where the value differs from the default; filters by
// index, name and group; export of the parameter set as a DCF (CiA 306) and import of one
// (GET / PUT /api/drives/N/parameters/dcf). Uses the console's api(), el() and say().
"use strict";

(function () {
  const parameters = { rows: [], drive: null };
  window.parameters = parameters;
  const q = (sel) => document.querySelector(sel);
  const token = new URLSearchParams(location.search).get("token");

  function key(o) {
    return `${o.index.replace(/^0x/i, "").toUpperCase()}:${o.sub.toString(16).toUpperCase().padStart(2, "0")}`;
  }

  function showDiffers(tr, o) {
    const d = tr.querySelector("td.differs");
    const differs = o.differs === true;
    tr.classList.toggle("differs", differs);
    tr.dataset.differs = differs ? "1" : "0";
    d.textContent = differs ? "≠" : "";
    d.title = differs ? `differs from the default ${o.default}` : "";
  }

  function row(o) {
    const value = el("td", { class: "value" }, o.value ?? (o.read_error ? "–" : ""));
    if (o.read_error) value.title = o.read_error;
    const tr = el("tr", { "data-key": key(o), "data-group": o.group },
      el("td", { class: "mono" }, o.index), el("td", {}, String(o.sub)), el("td", { class: "name" }, o.name),
      el("td", {}, o.group), el("td", {}, o.type), el("td", {}, o.access), el("td", {}, o.unit),
      el("td", {}, o.min == null ? "" : String(o.min)), el("td", {}, o.max == null ? "" : String(o.max)),
      el("td", { class: "default" }, o.default ?? ""), value, el("td", { class: "differs" }));
    showDiffers(tr, o);
    const edit = el("td");
    if (o.access === "rw" || o.access === "wo") {
      const input = el("input", { class: "edit", "aria-label": `new value of ${o.name}` });
      const button = el("button", { type: "button", class: "write" }, "Write");
      const write = async () => {
        try {
          const back = await api("PUT", `/api/drives/${parameters.drive}/objects/${o.index}/${o.sub.toString(16)}`,
                                 { value: input.value });
          value.textContent = back.value ?? "";
          o.value = back.value;
          o.differs = o.default == null || back.value == null ? null : back.value !== o.default;
          showDiffers(tr, o);
          say(`${o.index}:${o.sub} ${o.name} = ${back.value ?? input.value}`);
          input.value = "";
          filter();
        } catch (e) {
          say(`${o.index}:${o.sub} ${o.name}: ${e.message}` + (e.reason ? ` (${e.reason.rule})` : ""), true);
        }
      };
      button.addEventListener("click", write);
      input.addEventListener("keydown", (ev) => { if (ev.key === "Enter") write(); });
      edit.append(input, " ", button);
    }
    tr.append(edit);
    return tr;
  }

  // Index (`60`, `6083`, `1018:01`, `0x6083`), name (or the object's name), group, and
  // "differs only".
  function filter() {
    let index = q("#filter-index").value.trim().toUpperCase().replace(/^0X/, "").replace(/H$/, "");
    if (index.includes(":")) {
      const [i, s] = index.split(":");
      index = `${i.padStart(4, "0")}:${s === "" ? "" : s.padStart(2, "0")}`;
    }
    const name = q("#filter").value.trim().toLowerCase();
    const group = q("#filter-group").value;
    const differs = q("#filter-differs").checked;
    let shown = 0;
    for (const [tr, o] of parameters.rows) {
      const hide = (index !== "" && !key(o).startsWith(index))
        || (name !== "" && !(o.name.toLowerCase().includes(name) || o.object.toLowerCase().includes(name)
                             || key(o).toLowerCase().includes(name)))
        || (group !== "" && o.group !== group)
        || (differs && o.differs !== true);
      tr.hidden = hide;
      if (!hide) shown++;
    }
    q("#params-count").textContent = `${shown} of ${parameters.rows.length}`;
  }
  parameters.filter = filter;

  parameters.load = async function (drive) {
    parameters.drive = drive;
    const body = q("#params tbody");
    body.replaceChildren(el("tr", {}, el("td", { colspan: "13" }, "reading…")));
    try {
      const list = await api("GET", `/api/drives/${drive}/parameters`);
      if (drive !== parameters.drive) return;
      parameters.rows = list.map((o) => [row(o), o]);
      body.replaceChildren(...parameters.rows.map(([tr]) => tr));
      filter();
    } catch (e) {
      body.replaceChildren(el("tr", {}, el("td", { colspan: "13" }, e.message)));
    }
  };

  function report(text, error) {
    const m = q("#params-message");
    m.replaceChildren(text);
    m.className = error ? "error" : "";
  }

  // Export: the DCF as the drive has it now, downloaded under the name the server gives.
  async function exportDcf() {
    const headers = token ? { "x-drivetwin-token": token } : {};
    const r = await fetch(`/api/drives/${parameters.drive}/parameters/dcf`, { headers });
    if (!r.ok) { report(`export: HTTP ${r.status}`, true); return; }
    const name = (r.headers.get("content-disposition") || "").match(/filename="([^"]+)"/);
    const blob = new Blob([await r.text()], { type: "text/plain" });
    const a = el("a", { href: URL.createObjectURL(blob), download: name ? name[1] : `drive${parameters.drive}.dcf` });
    document.body.append(a);
    a.click();
    a.remove();
    report(`exported ${name ? name[1] : "the DCF"}`);
  }

  // Import: the file goes to the drive whole; the answer lists what was written, or every
  // value refused with its index and reason (then nothing was written).
  async function importDcf(file) {
    const headers = { "content-type": "text/plain" };
    if (token) headers["x-drivetwin-token"] = token;
    const r = await fetch(`/api/drives/${parameters.drive}/parameters/dcf`,
                          { method: "PUT", headers, body: await file.text() });
    const data = await r.json().catch(() => ({ error: `HTTP ${r.status}` }));
    if (r.ok) {
      report(`imported ${file.name}: ${data.written.length} written`
             + (data.written.length ? ` (${data.written.join(", ")})` : "")
             + `, ${data.unchanged} unchanged, ${data.skipped} not parameters`);
    } else {
      const m = q("#params-message");
      m.className = "error";
      m.replaceChildren(`${file.name}: ${data.error}`,
        el("ul", {}, ...(data.refused || []).map((x) =>
          el("li", { "data-refused": `${x.index.replace(/^0x/i, "")}:${x.sub.toString(16).toUpperCase().padStart(2, "0")}` },
             `[${x.section}] ${x.index}:${x.sub} = ${x.value}: ${x.reason}` + (x.abort_code ? ` (${x.abort_code})` : "")))));
    }
    await parameters.load(parameters.drive);
  }

  for (const id of ["#filter-index", "#filter", "#filter-group", "#filter-differs"]) {
    q(id).addEventListener("input", filter);
    q(id).addEventListener("change", filter);
  }
  q("#params-export").addEventListener("click", () => exportDcf().catch((e) => report(e.message, true)));
  q("#params-import").addEventListener("change", (ev) => {
    const f = ev.target.files[0];
    ev.target.value = "";
    if (f) importDcf(f).catch((e) => report(e.message, true));
  });
})();
