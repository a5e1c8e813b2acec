// tutti studio: the page. Vanilla JS, no build step; served from the binary.
"use strict";

const TYPES = ["boolean", "int8", "int16", "int32", "int64", "unsigned int8", "unsigned int16",
  "unsigned int32", "unsigned int64", "float32", "float64", "bus"];
const token = new URLSearchParams(location.search).get("token");
const $ = (id) => document.getElementById(id);

// ---------------------------------------------------------------- requests

async function api(method, path, body) {
  const headers = { "content-type": "application/json" };
  if (token) headers["x-tutti-token"] = token;
  let resp;
  try {
    resp = await fetch("api/" + path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  } catch (e) {
    throw { error: "the studio is not reachable (" + e.message + ")", code: "network" };
  }
  const text = await resp.text();
  let json = null;
  try { json = JSON.parse(text); } catch (_) { /* not JSON: shown as text */ }
  if (!resp.ok) {
    throw json && json.error ? json : { error: text || resp.statusText, code: "http" };
  }
  return json;
}

function say(text, kind) {
  const m = $("message");
  m.textContent = text;
  m.className = kind || "";
}

function fail(e) {
  say(e && e.error ? e.error : String(e), "error");
}

// ---------------------------------------------------------------- editor state

const ed = {
  doc: { domains: [] }, // the Document being edited (null: the file is not valid DDF)
  path: "",
  version: null,        // version of the file as opened (null: a new file)
  checked: null,
  timer: null,
  seq: 0,               // answers of the server older than the latest request are dropped
};

function newDomain(n) {
  return { name: "domain" + n, synchronous: false, event: false, multiple_publish_allowed: true, states: false,
    connection: null, publish: [], subscribe: [] };
}

function newItem(list) {
  let n = list.length + 1;
  while (list.some((i) => i.name === "item" + n)) n++;
  return { name: "item" + n, type: "float64", length: "", default: "", items: [] };
}

// `d0.publish.i2.i0` -> the item object (or the domain for `d0`).
function lookup(field) {
  const parts = field.split(".");
  let node = ed.doc.domains[+parts[0].slice(1)];
  let list = null;
  for (const p of parts.slice(1)) {
    if (p === "publish" || p === "subscribe") list = node[p];
    else if (p[0] === "i") { node = list[+p.slice(1)]; list = node.items; }
  }
  return node;
}

function changed(structural) {
  if (structural) renderForm();
  clearTimeout(ed.timer);
  ed.timer = setTimeout(check, 120);
  $("state").textContent = "modified";
}

async function check() {
  if (!ed.doc) return;
  const seq = ++ed.seq;
  try {
    const c = await api("POST", "check", { document: ed.doc, path: ed.path || "new.ddf" });
    // Two checks can be under way at once, and their answers can come back in either
    // order: only the latest request's answer describes the document as it is now.
    if (seq !== ed.seq) return;
    ed.checked = c;
    showChecked(c, true);
  } catch (e) { fail(e); }
}

// ---------------------------------------------------------------- rendering

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else if (k === "checked") e.checked = v;
    else if (k === "value") e.value = v;
    else e.setAttribute(k, v);
  }
  for (const c of children) e.append(c);
  return e;
}

function moveIn(list, i, delta) {
  const j = i + delta;
  if (j < 0 || j >= list.length) return;
  [list[i], list[j]] = [list[j], list[i]];
  changed(true);
}

function itemRows(tbody, list, prefix, depth) {
  list.forEach((item, k) => {
    const id = prefix + ".i" + k;
    const type = el("select", { "data-field": id + ".type", onchange: (e) => {
      item.type = e.target.value;
      changed(item.type === "bus" || item.items.length > 0);
    } }, ...TYPES.map((t) => el("option", { value: t }, t)));
    type.value = TYPES.includes(item.type) ? item.type : "float64";
    if (!TYPES.includes(item.type)) { type.append(el("option", { value: item.type }, item.type)); type.value = item.type; }
    const bus = item.type === "bus";
    const row = el("tr", { "data-node": id },
      el("td", { style: "padding-left:" + (4 + depth * 18) + "px" },
        el("input", { "data-field": id, value: item.name, size: 14, oninput: (e) => { item.name = e.target.value; changed(false); } })),
      el("td", {}, type),
      el("td", {}, bus ? "" : el("input", { "data-field": id + ".length", value: item.length, size: 4, placeholder: "1",
        oninput: (e) => { item.length = e.target.value; changed(false); } })),
      el("td", {}, bus ? "" : el("input", { "data-field": id + ".default", value: item.default, size: 6,
        oninput: (e) => { item.default = e.target.value; changed(false); } })),
      el("td", {},
        el("button", { class: "small", title: "up", onclick: () => moveIn(list, k, -1) }, "↑"),
        el("button", { class: "small", title: "down", onclick: () => moveIn(list, k, 1) }, "↓"),
        el("button", { class: "small", title: "duplicate", onclick: () => {
          const copy = JSON.parse(JSON.stringify(item)); copy.name += "_copy"; list.splice(k + 1, 0, copy); changed(true);
        } }, "dup"),
        el("button", { class: "small", title: "delete", "data-action": "delete-item", onclick: () => { list.splice(k, 1); changed(true); } }, "✕"),
        bus ? el("button", { class: "small", "data-action": "add-member", onclick: () => { item.items.push(newItem(item.items)); changed(true); } }, "+ member") : ""));
    tbody.append(row);
    if (item.items.length) itemRows(tbody, item.items, id, depth + 1);
  });
}

function renderForm() {
  const form = $("form");
  form.replaceChildren();
  renderTree();
  if (!ed.doc) {
    form.append(el("p", {}, "This file is not a valid DDF: fix it in the XML and press Apply XML, or start a New one."));
    return;
  }
  if (ed.doc.domains.length === 0) form.append(el("p", {}, "No domain yet: add one with + domain."));
  ed.doc.domains.forEach((d, n) => {
    const id = "d" + n;
    const flag = (key, label) => el("label", {},
      el("input", { type: "checkbox", "data-field": id + "." + key, checked: d[key],
        onchange: (e) => { d[key] = e.target.checked; changed(false); } }), " " + label);
    const box = el("div", { class: "domain", "data-node": id },
      el("div", { class: "head" },
        el("label", {}, "domain ", el("input", { "data-field": id, value: d.name, size: 20,
          oninput: (e) => { d.name = e.target.value; changed(false); } })),
        flag("synchronous", "synchronous"),
        flag("event", "event-driven"),
        flag("multiple_publish_allowed", "multiplePublishAllowed"),
        flag("states", "states"),
        ...domainButtons(n, ["duplicate", "delete"])));
    for (const role of ["publish", "subscribe"]) {
      const tbody = el("tbody");
      itemRows(tbody, d[role], id + "." + role, 0);
      box.append(el("div", { class: "set", "data-node": id + "." + role },
        el("h3", { "data-field": id + "." + role }, role.toUpperCase() + " set ",
          el("button", { class: "small", id: "add-" + role + "-" + n, "data-action": "add-item",
            onclick: () => { d[role].push(newItem(d[role])); changed(true); } }, "+ item")),
        el("table", {}, el("thead", {}, el("tr", {}, el("th", {}, "name"), el("th", {}, "type"), el("th", {}, "length"),
          el("th", {}, "default"), el("th", {}, ""))), tbody)));
    }
    form.append(box);
  });
  markFields();
}

// Move up, move down, duplicate and delete domain `n`: in the forms and in the tree.
function domainButtons(n, labels) {
  const domains = ed.doc.domains;
  return [
    el("button", { class: "small", title: "up", onclick: () => moveIn(domains, n, -1) }, "↑"),
    el("button", { class: "small", title: "down", onclick: () => moveIn(domains, n, 1) }, "↓"),
    el("button", { class: "small", title: "duplicate", "data-action": "duplicate-domain", onclick: () => {
      const copy = JSON.parse(JSON.stringify(domains[n])); copy.name += "_copy"; domains.splice(n + 1, 0, copy); changed(true);
    } }, labels[0]),
    el("button", { class: "small", title: "delete", "data-action": "delete-domain", onclick: () => { domains.splice(n, 1); changed(true); } }, labels[1]),
  ];
}

function treeItems(list, prefix) {
  const ul = el("ul");
  list.forEach((item, k) => {
    const id = prefix + ".i" + k;
    const li = el("li", {}, el("span", { "data-tree": id, onclick: () => goTo(id) }, item.name + (item.type === "bus" ? " (bus)" : "")));
    if (item.items.length) li.append(treeItems(item.items, id));
    ul.append(li);
  });
  return ul;
}

function renderTree() {
  const tree = $("tree");
  tree.replaceChildren();
  if (!ed.doc) return;
  ed.doc.domains.forEach((d, n) => {
    const id = "d" + n;
    const li = el("li", { "data-tree-domain": id }, el("span", { "data-tree": id, onclick: () => goTo(id) }, "▸ " + d.name),
      " ", ...domainButtons(n, ["dup", "✕"]));
    const sets = el("ul");
    for (const role of ["publish", "subscribe"]) {
      sets.append(el("li", {}, el("span", { "data-tree": id + "." + role, onclick: () => goTo(id + "." + role) }, role.toUpperCase()),
        treeItems(d[role], id + "." + role)));
    }
    li.append(sets);
    tree.append(li);
  });
}

function goTo(field) {
  const target = document.querySelector('[data-field="' + field + '"]');
  if (target) {
    target.scrollIntoView({ block: "center" });
    if (target.focus) target.focus();
  } else if (field) {
    say("that problem is in the XML only (line shown in the list)", "");
  }
}

function markFields() {
  document.querySelectorAll(".bad").forEach((e) => e.classList.remove("bad"));
  document.querySelectorAll(".fielddiag").forEach((e) => e.remove());
  const c = ed.checked;
  if (!c) return;
  for (const d of c.diagnostics) {
    if (!d.field) continue;
    const input = document.querySelector('[data-field="' + d.field + '"]');
    if (input) {
      input.classList.add("bad");
      input.title = d.message;
      // A domain's diagnostic goes on a line of its own below the domain's head, so that
      // the flags beside the name stay where they are when it comes and goes.
      const at = input.closest(".head") ? input.closest(".head > label") : input;
      at.insertAdjacentElement("afterend", el("div", { class: "fielddiag", "data-diag-for": d.field }, d.message));
    }
    const t = document.querySelector('[data-tree="' + d.field + '"]');
    if (t) t.classList.add("bad");
  }
}

function showChecked(c, fromForms) {
  if (!fromForms || document.activeElement !== $("xml")) $("xml").value = c.xml;
  const list = $("diags");
  list.replaceChildren();
  $("diag-count").textContent = c.diagnostics.length ? "(" + c.diagnostics.length + ")" : "(none)";
  for (const d of c.diagnostics) {
    list.append(el("li", { "data-diag": d.field || "", onclick: () => d.field ? goTo(d.field) : goToLine(d.line) },
      "line " + d.line + ":" + d.col + ": " + d.message));
  }
  $("save-anyway").hidden = true;
  renderTree();
  markFields();
  renderLayout(c.show);
}

function goToLine(line) {
  const ta = $("xml");
  const lines = ta.value.split("\n");
  let at = 0;
  for (let i = 0; i < line - 1 && i < lines.length; i++) at += lines[i].length + 1;
  ta.focus();
  ta.setSelectionRange(at, at + (lines[line - 1] || "").length);
}

function qosText(q) {
  if (!q) return "";
  return Object.entries(q).map(([k, v]) => k + "=" + (typeof v === "object" ? JSON.stringify(v) : v)).join(", ");
}

function renderLayout(show) {
  const box = $("layout");
  box.replaceChildren();
  if (!show) { box.append(el("p", {}, "(shown when the document is valid)")); return; }
  for (const d of show.domains) {
    box.append(el("h3", {}, d.name + "  (layout " + d.layout_hash + ")"));
    for (const s of d.sets) {
      const rows = s.items.map((l) => el("tr", {}, el("td", {}, l.path), el("td", {}, l.type + (l.length > 1 ? "[" + l.length + "]" : "")),
        el("td", {}, String(l.offset)), el("td", {}, String(l.size))));
      box.append(el("div", { class: "layout-set" },
        el("div", {}, s.role + ": " + s.size + " bytes, align " + s.align),
        el("table", {}, el("tr", {}, el("th", {}, "path"), el("th", {}, "type"), el("th", {}, "offset"), el("th", {}, "size")), ...rows),
        el("div", {}, "topic " + s.dds.topic + "  type " + s.dds.dds_type),
        el("div", {}, "writer QoS: " + qosText(s.writer_qos)),
        el("div", {}, "reader QoS: " + qosText(s.reader_qos))));
    }
  }
}

// ---------------------------------------------------------------- files

async function refreshFiles() {
  try {
    const f = await api("GET", "files");
    $("files").replaceChildren(...f.files.map((p) => el("option", { value: p })));
  } catch (e) { fail(e); }
}

async function openFile(path) {
  ed.seq++; // a check of the document before it is stale
  try {
    const r = await api("GET", "open?path=" + encodeURIComponent(path));
    ed.path = r.path;
    ed.version = r.version;
    $("path").value = r.path;
    const c = r.checked;
    if (c.document) ed.doc = c.document;
    else if (c.xml.trim() === "") ed.doc = { domains: [] };
    else ed.doc = null;
    ed.checked = c;
    renderForm();
    showChecked(c, false);
    $("reload").hidden = true;
    $("state").textContent = "opened";
    $("run-file").textContent = r.path;
    say(c.valid ? "opened " + r.path : (ed.doc ? "opened " + r.path + " (empty: start with + domain)" :
      "opened " + r.path + ": it is not a valid DDF (" + c.diagnostics.length + " problem(s))"), c.valid || ed.doc ? "ok" : "error");
    if (ed.doc && !c.valid) check();
  } catch (e) { fail(e); }
}

async function save(force) {
  if (!ed.doc) { say("nothing to save: apply valid XML or start a new document first", "error"); return; }
  const path = $("path").value.trim();
  const same = path === ed.path;
  try {
    const r = await api("POST", "save", { path, document: ed.doc, version: same ? ed.version : null, force: !!force });
    ed.path = r.path;
    ed.version = r.version;
    $("state").textContent = "saved";
    $("save-anyway").hidden = true;
    $("run-file").textContent = r.path;
    say("saved " + r.path + (r.valid ? "" : " (with problems)"), "ok");
    refreshFiles();
  } catch (e) {
    fail(e);
    if (e.code === "changed") $("reload").hidden = false;
    if (e.code === "invalid") $("save-anyway").hidden = false;
  }
}

async function applyXml() {
  ed.seq++; // a check of the forms before it is stale
  try {
    const c = await api("POST", "parse", { xml: $("xml").value, path: ed.path || "new.ddf" });
    if (c.document) { ed.doc = c.document; renderForm(); }
    ed.checked = c;
    showChecked(c, false);
    say(c.valid ? "XML applied" : "the XML has problems: see the list", c.valid ? "ok" : "error");
  } catch (e) { fail(e); }
}

// ---------------------------------------------------------------- wiring

function showTab(name) {
  for (const t of document.querySelectorAll(".tab")) t.classList.toggle("active", t.dataset.tab === name);
  $("editor").hidden = name !== "editor";
  $("monitor").hidden = name !== "monitor";
  if (name === "monitor" && window.monitorShown) window.monitorShown();
}

async function start() {
  for (const t of document.querySelectorAll(".tab")) t.addEventListener("click", () => showTab(t.dataset.tab));
  $("open").addEventListener("click", () => openFile($("path").value.trim()));
  $("new").addEventListener("click", () => {
    ed.doc = { domains: [] }; ed.path = ""; ed.version = null; ed.checked = null;
    $("path").value = "new.ddf"; renderForm(); changed(false); say("new document", "ok");
  });
  $("save").addEventListener("click", () => save(false));
  $("save-anyway").addEventListener("click", () => save(true));
  $("reload").addEventListener("click", () => openFile(ed.path));
  $("apply-xml").addEventListener("click", applyXml);
  $("add-domain").addEventListener("click", () => {
    if (!ed.doc) ed.doc = { domains: [] };
    ed.doc.domains.push(newDomain(ed.doc.domains.length + 1)); changed(true);
  });
  renderForm();
  try {
    const info = await api("GET", "info");
    $("root").textContent = "root " + info.root + (info.read_only ? " (read-only)" : "");
    $("namespace").value = info.namespace;
    if (info.read_only) { $("save").hidden = true; $("save").dataset.off = "1"; }
    if (!info.run_control) $("run-bar").hidden = true;
    refreshFiles();
    if (info.files.length) await openFile(info.files[0]);
  } catch (e) { fail(e); }
}

start();

// ---------------------------------------------------------------- live monitor

const mon = {
  source: null,
  plotted: [],          // keys DOMAIN#ROLE#PATH
  series: {},           // "KEY[i]" -> [[t, v], ...]
  history: [],          // [t, {domain: connection count}]
  last: {},             // domain -> [t, step] for the step rate
  rates: {},
  window: 20,           // seconds shown
};
const COLORS = ["#2563eb", "#dc2626", "#16a34a", "#9333ea", "#ea580c", "#0891b2", "#4d7c0f", "#be185d"];

function follow() {
  if (mon.source) mon.source.close();
  const q = new URLSearchParams({ namespace: $("namespace").value.trim(), items: mon.plotted.join(",") });
  if (token) q.set("token", token);
  mon.source = new EventSource("api/monitor?" + q.toString());
  mon.source.onmessage = (e) => {
    let ev;
    try { ev = JSON.parse(e.data); } catch (_) { return; }
    $("live-state").textContent = "live, namespace " + ev.namespace;
    onEvent(ev);
  };
  mon.source.onerror = () => { $("live-state").textContent = "reconnecting…"; };
}

window.monitorShown = () => {
  if (!mon.source) follow();
  if (!$("run-bar").hidden) refreshCheckpoints();
};

function fmtNs(ns) {
  return ns >= 1e6 ? (ns / 1e6).toFixed(2) + " ms" : (ns / 1e3).toFixed(1) + " µs";
}

function onEvent(ev) {
  const box = $("domains");
  box.replaceChildren();
  if (ev.error) box.append(el("p", { class: "fielddiag" }, ev.error));
  if (!ev.domains.length) box.append(el("p", {}, "no live domain in namespace " + ev.namespace));
  const counts = {};
  for (const d of ev.domains) {
    if (d.error) { box.append(el("p", { class: "fielddiag" }, d.error)); continue; }
    counts[d.domain] = d.connection_count;
    const prev = mon.last[d.domain];
    if (prev && ev.t - prev[0] >= 0.5) {
      mon.rates[d.domain] = (d.steps - prev[1]) / (ev.t - prev[0]);
      mon.last[d.domain] = [ev.t, d.steps];
    } else if (!prev) mon.last[d.domain] = [ev.t, d.steps];
    const rate = mon.rates[d.domain] === undefined ? "…" : mon.rates[d.domain].toFixed(0);
    const rows = d.connections.map((c) => el("tr", { "data-pid": String(c.pid) },
      el("td", {}, String(c.pid)), el("td", {}, c.name), el("td", {}, c.observer ? "observer (" + c.dds_readers + " DDS readers)" : (c.writer ? "writer" : (c.sync_reader ? "sync reader" : "reader")) + (c.remote ? " via DDS" : "")),
      el("td", {}, ((ev.t * 1e9 - c.since_ns) / 1e9).toFixed(1) + " s" + (c.alive ? "" : " (dead, being removed)")),
      el("td", {}, d.owner_pid === c.pid ? "owner" : "")));
    box.append(el("div", { class: "live-domain" + (d.framework_alive ? "" : " stopped"), "data-domain": d.domain },
      el("strong", {}, d.domain), " ",
      (d.flags.event ? "event" : d.flags.synchronous ? "sync" : "async") + (d.flags.multiple_publish_allowed ? "" : ", exclusive") + (d.flags.states ? ", states" : ""),
      el("div", {}, "framework pid " + d.framework_pid + (d.framework_alive ? "" : " (stopped)") + "  step " + d.step +
        "  " + rate + " steps/s  overruns " + d.overruns + "  late last " + fmtNs(d.last_late_ns) + " max " + fmtNs(d.max_late_ns) +
        "  participants " + d.connection_count + "  DDS writers " + d.dds_writers + "  DDS readers " + d.dds_readers + (d.owner_pid ? "  owner pid " + d.owner_pid : "")),
      el("table", { class: "connections" }, el("tr", {}, el("th", {}, "pid"), el("th", {}, "name"), el("th", {}, "role"),
        el("th", {}, "since"), el("th", {}, "")), ...rows)));
  }
  mon.history.push([ev.t, counts]);
  while (mon.history.length && mon.history[0][0] < ev.t - 60) mon.history.shift();
  drawTimeline(ev.t);
  if (ev.catalog) fillCatalog(ev.catalog);
  for (const [key, v] of Object.entries(ev.values || {})) {
    if (!v.v) continue;
    v.v.forEach((x, i) => {
      const name = v.v.length > 1 ? key + "[" + i + "]" : key;
      (mon.series[name] = mon.series[name] || []).push([ev.t, x]);
    });
  }
  for (const s of Object.values(mon.series)) while (s.length && s[0][0] < ev.t - mon.window) s.shift();
  drawPlot(ev.t, ev.values || {});
  renderRuns(ev.runs || {});
}

function fillCatalog(catalog) {
  const sel = $("plot-item");
  const keep = sel.value;
  sel.replaceChildren(...catalog.map((c) => {
    const key = c.domain + "#" + c.role + "#" + c.path;
    return el("option", { value: key }, c.domain + " " + c.role + " " + c.path + (c.length > 1 ? "[" + c.length + "]" : ""));
  }));
  if (keep && catalog.some((c) => c.domain + "#" + c.role + "#" + c.path === keep)) sel.value = keep;
}

function axes(ctx, w, h) {
  ctx.clearRect(0, 0, w, h);
  ctx.strokeStyle = "#d8dde5";
  ctx.strokeRect(40, 10, w - 50, h - 30);
}

function drawLines(canvas, lines, t1, span) {
  const ctx = canvas.getContext("2d");
  const w = canvas.width, h = canvas.height;
  axes(ctx, w, h);
  let lo = Infinity, hi = -Infinity;
  for (const l of lines) for (const [, v] of l.points) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (!isFinite(lo)) return;
  if (hi - lo < 1e-12) { lo -= 1; hi += 1; }
  const x = (t) => 40 + (w - 50) * (1 - (t1 - t) / span);
  const y = (v) => 10 + (h - 30) * (1 - (v - lo) / (hi - lo));
  ctx.fillStyle = "#5b6678";
  ctx.font = "11px sans-serif";
  ctx.fillText(hi.toPrecision(4), 2, 18);
  ctx.fillText(lo.toPrecision(4), 2, h - 22);
  ctx.fillText("-" + span + " s", 40, h - 6);
  ctx.fillText("now", w - 30, h - 6);
  lines.forEach((l, i) => {
    ctx.strokeStyle = COLORS[i % COLORS.length];
    ctx.beginPath();
    l.points.forEach(([t, v], k) => (k ? ctx.lineTo(x(t), y(v)) : ctx.moveTo(x(t), y(v))));
    ctx.stroke();
  });
}

function drawTimeline(t) {
  const names = [...new Set(mon.history.flatMap(([, c]) => Object.keys(c)))].sort();
  drawLines($("timeline"), names.map((n) => ({ points: mon.history.map(([tt, c]) => [tt, c[n] || 0]) })), t, 60);
}

function drawPlot(t, values) {
  const names = Object.keys(mon.series).sort();
  drawLines($("plot"), names.map((n) => ({ points: mon.series[n] })), t, mon.window);
  const legend = $("plot-legend");
  legend.replaceChildren(...names.map((n, i) => {
    const s = mon.series[n];
    const last = s.length ? s[s.length - 1][1] : NaN;
    return el("span", { "data-series": n, "data-value": String(last), style: "color:" + COLORS[i % COLORS.length] },
      n.replace(/#/g, " ") + " = " + (isNaN(last) ? "…" : last.toPrecision(6)));
  }));
  for (const [key, v] of Object.entries(values)) {
    if (v.error) legend.append(el("span", { class: "fielddiag" }, key.replace(/#/g, " ") + ": " + v.error));
  }
}

function renderRuns(runs) {
  const lines = [];
  for (const [kind, r] of Object.entries(runs)) {
    lines.push("== " + kind + " " + r.path + " (pid " + r.pid + ", namespace " + r.namespace + "): " +
      (r.running ? "running " + r.seconds.toFixed(0) + " s" : "exited " + r.exit));
    lines.push(...r.log);
  }
  const text = lines.join("\n");
  const pre = $("logs");
  if (pre.textContent !== text) { pre.textContent = text; pre.scrollTop = pre.scrollHeight; }
}

async function runStart(kind) {
  const path = ed.path || $("path").value.trim();
  if (!path) { say("open or save a DDF in the editor first: run control starts the DDF open there", "error"); return; }
  try {
    const r = await api("POST", "run/start", { kind, path, step: $("run-step").value.trim(),
      duration: $("run-duration").value.trim(), namespace: $("namespace").value.trim() });
    say("started tutti " + r.kind + " on " + r.path + " (pid " + r.pid + ", namespace " + r.namespace + ")", "ok");
  } catch (e) { fail(e); }
}

async function runStop(kind) {
  try {
    const r = await api("POST", "run/stop", { kind });
    say("stopped tutti " + r.kind + (r.exit ? " (" + r.exit + ")" : ""), "ok");
  } catch (e) { fail(e); }
}

$("follow").addEventListener("click", () => { mon.series = {}; mon.history = []; mon.last = {}; mon.rates = {}; follow(); });
$("plot-add").addEventListener("click", () => {
  const key = $("plot-item").value;
  if (key && !mon.plotted.includes(key)) { mon.plotted.push(key); follow(); }
});
$("plot-clear").addEventListener("click", () => { mon.plotted = []; mon.series = {}; follow(); });
$("start-host").addEventListener("click", () => runStart("host"));
$("stop-host").addEventListener("click", () => runStop("host"));
function showRunState(r) {
  const state = $("run-state");
  state.dataset.state = r.state;
  state.dataset.step = String(r.step);
  state.textContent = r.state + ", step " + r.step + ", t = " + r.sim_time.toFixed(3) + " s";
  return state.textContent;
}

async function runControl(op) {
  const n = parseInt($("step-count").value, 10);
  try {
    const r = await api("POST", "run/control", op === "step" ? { op, n } : { op });
    say("framework " + op + ": " + showRunState(r), "ok");
  } catch (e) { fail(e); }
}

// The checkpoint files under the root, offered by the checkpoint field.
async function refreshCheckpoints() {
  try {
    const r = await api("GET", "run/checkpoints");
    $("checkpoints").replaceChildren(...r.checkpoints.map((p) => el("option", { value: p })));
  } catch (e) { fail(e); }
}

// Save (op "save") or restore ("restore") a checkpoint of the framework: the file named in
// the field; the result (the file, or the run's reason for refusing) beside the buttons.
async function runCheckpoint(op) {
  const path = $("checkpoint-path").value.trim();
  const result = $("checkpoint-result");
  result.dataset.result = "";
  try {
    const r = await api("POST", "run/control",
      op === "save" ? { op, path, skip_stateless: $("skip-stateless").checked } : { op, path });
    $("checkpoint-path").value = r.checkpoint;
    result.dataset.result = "ok";
    result.dataset.file = r.checkpoint;
    result.title = "";
    result.textContent = (op === "save" ? "saved " : "restored ") + r.checkpoint;
    say("checkpoint " + (op === "save" ? "saved to " : "restored from ") + r.checkpoint + ": " + showRunState(r), "ok");
    refreshCheckpoints();
  } catch (e) {
    result.dataset.result = "error";
    result.dataset.file = "";
    result.textContent = (op === "save" ? "not saved" : "not restored") + " (see the message above)";
    result.title = e && e.error ? e.error : String(e);
    fail(e);
  }
}

$("pause-host").addEventListener("click", () => runControl("pause"));
$("step-host").addEventListener("click", () => runControl("step"));
$("reset-host").addEventListener("click", () => runControl("reset"));
$("resume-host").addEventListener("click", () => runControl("resume"));
$("save-checkpoint").addEventListener("click", () => runCheckpoint("save"));
$("restore-checkpoint").addEventListener("click", () => runCheckpoint("restore"));
$("start-gateway").addEventListener("click", () => runStart("gateway"));
$("stop-gateway").addEventListener("click", () => runStop("gateway"));
