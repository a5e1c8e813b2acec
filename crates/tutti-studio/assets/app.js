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
};

function newDomain(n) {
  return { name: "domain" + n, synchronous: false, multiple_publish_allowed: true, states: false,
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
  try {
    ed.checked = await api("POST", "check", { document: ed.doc, path: ed.path || "new.ddf" });
    showChecked(ed.checked, true);
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
        flag("multiple_publish_allowed", "multiplePublishAllowed"),
        flag("states", "states"),
        el("button", { class: "small", title: "up", onclick: () => moveIn(ed.doc.domains, n, -1) }, "↑"),
        el("button", { class: "small", title: "down", onclick: () => moveIn(ed.doc.domains, n, 1) }, "↓"),
        el("button", { class: "small", "data-action": "duplicate-domain", onclick: () => {
          const copy = JSON.parse(JSON.stringify(d)); copy.name += "_copy"; ed.doc.domains.splice(n + 1, 0, copy); changed(true);
        } }, "duplicate"),
        el("button", { class: "small", "data-action": "delete-domain", onclick: () => { ed.doc.domains.splice(n, 1); changed(true); } }, "delete")));
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
    const li = el("li", {}, el("span", { "data-tree": id, onclick: () => goTo(id) }, "▸ " + d.name));
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
      input.insertAdjacentElement("afterend", el("div", { class: "fielddiag", "data-diag-for": d.field }, d.message));
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
    refreshFiles();
    if (info.files.length) await openFile(info.files[0]);
  } catch (e) { fail(e); }
}

start();
