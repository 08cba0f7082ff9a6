// The assetfield editor page: the bird's-eye view (composed ground plane + footprints), the
// 3D view (orbit camera renders), the library and category panels, undo / redo, the edit
// log and Save. Every change is an edit in the layout language sent to POST /api/edits;
// the server answers the new layout, and the page redraws from it.
"use strict";

const TOKEN = new URLSearchParams(location.search).get("token") || "";
const PREVIEW_SIDE = 128;
const SNAP_DEG = 15;
const SVG_NS = "http://www.w3.org/2000/svg";

const $ = (id) => document.getElementById(id);

const editor = {
  ready: false,
  layout: null,
  selected: null,
  chosenAsset: null,
  view: { azimuth: -60, elevation: 35, radius: null },
  // what the 3D view shows: the layout version and size of its last full render
  shown: { version: -1, width: 0, preview: true },
  renderSeq: 0,
  busy: 0,
};
window.editor = editor;

function api(path, opts = {}) {
  const headers = Object.assign({ "X-Assetfield-Token": TOKEN }, opts.headers || {});
  return fetch("/api/" + path, Object.assign({}, opts, { headers }));
}

function status(text, isError) {
  const s = $("status");
  s.textContent = text;
  s.className = isError ? "error" : "";
}

// the name people read (NameCategory), else the category's own
function categoryLabel(name) {
  const c = editor.layout && editor.layout.categories.find((k) => k.name === name);
  return c ? c.label : name;
}

// the server's colours, those of every picture the tool draws (compose's layout.png too)
function categoryColour(name) {
  return (editor.layout && editor.layout.category_colours[name]) || "#888888";
}

// ---- edits -------------------------------------------------------------------------

function ronString(s) {
  return '"' + String(s).replace(/\\/g, "\\\\").replace(/"/g, '\\"') + '"';
}

function num(x) {
  const v = Math.round(x * 1e5) / 1e5;
  return Number.isInteger(v) ? v.toFixed(1) : String(v);
}

async function sendEdits(text) {
  editor.busy++;
  status("applying...");
  try {
    const r = await api("edits", { method: "POST", body: text, headers: { "Content-Type": "text/plain" } });
    const body = await r.json();
    if (!r.ok) {
      const where = body.line ? ` (line ${body.line}, column ${body.col})` : "";
      $("edit-error").textContent = body.error + where;
      status("edit refused: " + body.error, true);
      return false;
    }
    $("edit-error").textContent = "";
    setLayout(body);
    status("applied");
    return true;
  } catch (e) {
    status("request failed: " + e, true);
    return false;
  } finally {
    editor.busy--;
  }
}

async function post(path, what) {
  editor.busy++;
  try {
    const r = await api(path, { method: "POST" });
    const body = await r.json();
    if (!r.ok) {
      status(what + " failed: " + body.error, true);
      return null;
    }
    return body;
  } finally {
    editor.busy--;
  }
}

async function recolour(category, from) {
  const q = `recolour?category=${encodeURIComponent(category)}&from=${encodeURIComponent(from)}`;
  const l = await post(q, "recolour");
  if (l) { setLayout(l); status(`${category} recoloured from ${from}`); }
}

async function undo() {
  const l = await post("undo", "undo");
  if (l) { setLayout(l); status("undone"); }
}

async function redo() {
  const l = await post("redo", "redo");
  if (l) { setLayout(l); status("redone"); }
}

async function save() {
  const r = await post("save", "save");
  if (r) {
    status("saved " + r.saved);
    if (editor.layout && editor.layout.version === r.version) {
      editor.layout.unsaved = false;
      $("unsaved").hidden = true;
    }
  }
}

// the edit box's example names an instance of the layout (the selected one, else the first)
let exampleEdit = "";
function refreshExample() {
  const box = $("edit-text");
  const insts = editor.layout ? editor.layout.instances : [];
  const key = editor.selected || (insts[0] && insts[0].key);
  if (!key || (box.value && box.value !== exampleEdit)) return;
  exampleEdit = `[Move(target: ${ronString(key)}, by: (0.5, 0.0))]`;
  box.value = exampleEdit;
}

// ---- layout and the bird's-eye view ------------------------------------------------

function setLayout(l) {
  // versions only grow: a late answer to an earlier request is stale
  if (editor.layout && l.version < editor.layout.version) return;
  const changed = !editor.layout || editor.layout.version !== l.version;
  editor.layout = l;
  if (editor.selected && !l.instances.some((i) => i.key === editor.selected)) editor.selected = null;
  $("undo").disabled = !l.can_undo;
  $("redo").disabled = !l.can_redo;
  $("edit-log").textContent = l.edits.trim() || "(no edits yet)";
  $("unsaved").hidden = !l.unsaved;
  refreshExample();
  drawFootprints();
  drawPanels();
  if (changed) {
    refreshBev();
    renderView();
  }
}

let bevSeq = 0;
function refreshBev() {
  const img = $("bev-img");
  const seq = ++bevSeq;
  fetchImage(`bev?footprints=false&v=${editor.layout.version}`).then((url) => {
    if (url && seq !== bevSeq) {
      URL.revokeObjectURL(url);
    } else if (url) {
      if (img.src.startsWith("blob:")) URL.revokeObjectURL(img.src);
      img.src = url;
    }
  });
}

async function fetchImage(path) {
  const r = await api(path);
  if (!r.ok) {
    let msg = r.status + "";
    try { msg = (await r.json()).error; } catch (_) { /* not JSON */ }
    status("image failed: " + msg, true);
    return null;
  }
  return URL.createObjectURL(await r.blob());
}

function toPixel(x, y) {
  const m = editor.layout.bev;
  return [(x - m.x0) / m.sx, (m.y0 - y) / m.sy];
}

function svgPoint(evt) {
  const svg = $("bev-svg");
  const pt = svg.createSVGPoint();
  pt.x = evt.clientX;
  pt.y = evt.clientY;
  return pt.matrixTransform(svg.getScreenCTM().inverse());
}

// world units per CSS pixel of the bird's-eye view as displayed (for tests and drags)
editor.unitsPerCssPixel = function () {
  const m = editor.layout.bev;
  const shown = $("bev-svg").getBoundingClientRect();
  return [m.sx * m.width / shown.width, m.sy * m.height / shown.height];
};

function drawFootprints() {
  const l = editor.layout;
  const svg = $("bev-svg");
  svg.setAttribute("viewBox", `0 0 ${l.bev.width} ${l.bev.height}`);
  svg.replaceChildren();
  const labels = [];
  for (const inst of l.instances) {
    const g = document.createElementNS(SVG_NS, "g");
    g.dataset.key = inst.key;
    const poly = document.createElementNS(SVG_NS, "polygon");
    poly.setAttribute("points", inst.footprint.map(([x, y]) => toPixel(x, y).join(",")).join(" "));
    poly.setAttribute("class", "fp" + (inst.key === editor.selected ? " selected" : ""));
    poly.setAttribute("stroke", categoryColour(inst.category));
    poly.setAttribute("fill", categoryColour(inst.category));
    poly.dataset.key = inst.key;
    const title = document.createElementNS(SVG_NS, "title");
    title.textContent = `${inst.key} (${inst.asset}, ${categoryLabel(inst.category)})`;
    poly.appendChild(title);
    g.appendChild(poly);
    const [px, py] = toPixel(inst.x, inst.y);
    const label = document.createElementNS(SVG_NS, "text");
    label.setAttribute("x", px);
    label.setAttribute("y", py);
    label.setAttribute("text-anchor", "middle");
    label.textContent = inst.key;
    label.dataset.key = inst.key;
    g.appendChild(label);
    labels.push(label);
    if (inst.key === editor.selected) {
      // the turning handle, in front of the instance (its local +X)
      const a = (inst.yaw_deg * Math.PI) / 180;
      const fp = inst.footprint;
      const reach = Math.max(...fp.map(([x, y]) => Math.hypot(x - inst.x, y - inst.y))) * 1.15;
      const [hx, hy] = toPixel(inst.x + reach * Math.cos(a), inst.y + reach * Math.sin(a));
      const handle = document.createElementNS(SVG_NS, "circle");
      handle.setAttribute("cx", hx);
      handle.setAttribute("cy", hy);
      handle.setAttribute("r", 7);
      handle.setAttribute("class", "handle");
      handle.dataset.handle = inst.key;
      g.appendChild(handle);
    }
    svg.appendChild(g);
  }
  // a label that would overprint one already shown is left out (the selected one first)
  labels.sort((a, b) => (b.dataset.key === editor.selected) - (a.dataset.key === editor.selected));
  const shown = [];
  for (const label of labels) {
    const r = label.getBBox();
    const hit = shown.some((o) => r.x < o.x + o.width && o.x < r.x + r.width && r.y < o.y + o.height && o.y < r.y + r.height);
    if (hit) label.remove();
    else shown.push(r);
  }
  const sel = l.instances.find((i) => i.key === editor.selected);
  $("selection").textContent = sel
    ? `${sel.key}: ${sel.asset} (${categoryLabel(sel.category)}) at (${sel.x.toFixed(3)}, ${sel.y.toFixed(3)}), yaw ${sel.yaw_deg.toFixed(1)}°, scale ${sel.scale.toFixed(2)}`
    : "nothing selected";
  $("use-asset").disabled = !(sel && editor.chosenAsset);
}

function select(key) {
  editor.selected = key;
  refreshExample();
  drawFootprints();
}

// dragging: a footprint moves, the handle turns
let drag = null;

function onPointerDown(evt) {
  if (evt.button !== 0) return;
  const target = evt.target;
  const p = svgPoint(evt);
  if (target.dataset && target.dataset.handle) {
    drag = { kind: "turn", key: target.dataset.handle, start: p };
  } else if (target.dataset && target.dataset.key) {
    const key = target.dataset.key;
    select(key); // redraws the footprints: take the new group
    const group = [...$("bev-svg").children].find((g) => g.dataset.key === key);
    drag = { kind: "move", key, start: p, group };
  } else {
    if (editor.chosenAsset) {
      insertAt(p);
    } else {
      select(null);
    }
    return;
  }
  $("bev-svg").setPointerCapture(evt.pointerId);
  evt.preventDefault();
}

function onPointerMove(evt) {
  if (!drag) return;
  const p = svgPoint(evt);
  if (drag.kind === "move" && drag.group) {
    drag.group.setAttribute("transform", `translate(${p.x - drag.start.x},${p.y - drag.start.y})`);
  }
  drag.last = p;
}

async function onPointerUp(evt) {
  if (!drag) return;
  const d = drag;
  drag = null;
  const p = svgPoint(evt);
  const m = editor.layout.bev;
  const inst = editor.layout.instances.find((i) => i.key === d.key);
  if (!inst) return;
  if (d.kind === "move") {
    const dx = (p.x - d.start.x) * m.sx;
    const dy = -(p.y - d.start.y) * m.sy;
    if (Math.abs(p.x - d.start.x) < 0.5 && Math.abs(p.y - d.start.y) < 0.5) {
      drawFootprints();
      return;
    }
    await sendEdits(`[Move(target: ${ronString(d.key)}, by: (${num(dx)}, ${num(dy)}))]`);
  } else {
    const [cx, cy] = toPixel(inst.x, inst.y);
    let yaw = (Math.atan2(-(p.y - cy) * m.sy, (p.x - cx) * m.sx) * 180) / Math.PI;
    if (evt.shiftKey) yaw = Math.round(yaw / SNAP_DEG) * SNAP_DEG;
    await sendEdits(`[Rotate(target: ${ronString(d.key)}, to: ${num(yaw)})]`);
  }
}

// a cancelled press (the pointer lost, a touch turned into a scroll) edits nothing
function onPointerCancel() {
  if (drag) {
    drag = null;
    drawFootprints();
  }
}

function insertAt(p) {
  const m = editor.layout.bev;
  const x = m.x0 + p.x * m.sx;
  const y = m.y0 - p.y * m.sy;
  sendEdits(`[Add(asset: ${ronString(editor.chosenAsset)}, at: (${num(x)}, ${num(y)}))]`);
}

function onKey(evt) {
  if (evt.target.tagName === "TEXTAREA" || evt.target.tagName === "INPUT" || evt.target.tagName === "SELECT") return;
  const ctrl = evt.ctrlKey || evt.metaKey;
  if (ctrl && evt.key.toLowerCase() === "z") { evt.preventDefault(); evt.shiftKey ? redo() : undo(); return; }
  if (ctrl && evt.key.toLowerCase() === "y") { evt.preventDefault(); redo(); return; }
  if (ctrl && evt.key.toLowerCase() === "s") { evt.preventDefault(); save(); return; }
  const duplicate = ctrl && !evt.altKey && evt.key.toLowerCase() === "d";
  if ((ctrl || evt.altKey) && !duplicate) return; // browser shortcuts (Ctrl-+ zooms the page)
  const key = editor.selected;
  if (!key) return;
  const inst = editor.layout.instances.find((i) => i.key === key);
  if (!inst) return;
  const t = ronString(key);
  if (duplicate) {
    evt.preventDefault();
    const w = Math.max(...inst.footprint.map(([x]) => x)) - Math.min(...inst.footprint.map(([x]) => x));
    sendEdits(`[Duplicate(target: ${t}, by: (${num(w * 1.1)}, 0.0))]`);
  } else if (evt.key === "Delete" || evt.key === "Backspace") {
    evt.preventDefault();
    sendEdits(`[Remove(${t})]`);
  } else if (evt.key === "q" || evt.key === "Q" || evt.key === "e" || evt.key === "E") {
    const sign = evt.key.toLowerCase() === "q" ? 1 : -1;
    if (evt.shiftKey) {
      const to = (Math.round(inst.yaw_deg / SNAP_DEG) + sign) * SNAP_DEG;
      sendEdits(`[Rotate(target: ${t}, to: ${num(to)})]`);
    } else {
      sendEdits(`[Rotate(target: ${t}, by: ${num(5 * sign)})]`);
    }
  } else if (evt.key === "+" || evt.key === "=") {
    sendEdits(`[Scale(target: ${t}, by: 1.1)]`);
  } else if (evt.key === "-") {
    sendEdits(`[Scale(target: ${t}, by: ${num(1 / 1.1)})]`);
  } else if (evt.key.startsWith("Arrow")) {
    evt.preventDefault();
    const step = 4 * Math.max(editor.layout.bev.sx, editor.layout.bev.sy) * (evt.shiftKey ? 5 : 1);
    const d = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, step], ArrowDown: [0, -step] }[evt.key];
    sendEdits(`[Move(target: ${t}, by: (${num(d[0])}, ${num(d[1])}))]`);
  } else if (evt.key === "Escape") {
    editor.chosenAsset = null;
    select(null);
    drawPanels();
  }
}

// ---- panels ------------------------------------------------------------------------

function drawPanels() {
  const l = editor.layout;
  const pal = $("palette");
  pal.replaceChildren();
  for (const a of l.assets) {
    const li = document.createElement("li");
    li.dataset.asset = a.name;
    if (a.name === editor.chosenAsset) li.className = "chosen";
    const sw = document.createElement("span");
    sw.className = "swatch";
    sw.style.background = categoryColour(a.category);
    li.append(sw, `${a.name} `, Object.assign(document.createElement("small"), {
      textContent: a.kind === "category" ? `(${categoryLabel(a.name)}: category template)` : `(${categoryLabel(a.category)})`,
    }));
    li.onclick = () => {
      editor.chosenAsset = editor.chosenAsset === a.name ? null : a.name;
      drawPanels();
      drawFootprints();
      status(editor.chosenAsset ? `click on the ground plane to insert ${a.name} (Escape: stop)` : "");
    };
    pal.appendChild(li);
  }
  const cats = $("categories");
  cats.replaceChildren();
  for (const c of l.categories) {
    const li = document.createElement("li");
    li.dataset.category = c.name;
    const sw = document.createElement("span");
    sw.className = "swatch";
    sw.style.background = categoryColour(c.name);
    const count = l.instances.filter((i) => i.category === c.name).length;
    const pick = document.createElement("select");
    pick.title = "draw every instance of the category with this entry (ReplaceAsset)";
    for (const m of [c.name, ...c.members]) {
      const o = document.createElement("option");
      o.value = m;
      o.textContent = m === c.name ? `template ${c.template}` : m;
      pick.appendChild(o);
    }
    // the dropdowns show what the category's instances are drawn with now
    const used = [...new Set(l.instances.filter((i) => i.category === c.name).map((i) => i.asset))];
    if (used.length === 1 && [c.name, ...c.members].includes(used[0])) {
      pick.value = used[0];
    } else {
      // drawn with several entries (as mined: each object its own), or recoloured
      const o = Object.assign(document.createElement("option"), { value: "", textContent: used.length > 1 ? "each its own entry" : "recoloured" });
      pick.prepend(o);
      pick.value = "";
    }
    pick.onchange = () => {
      if (pick.value) sendEdits(`[ReplaceAsset(category: ${ronString(c.name)}, with: ${ronString(pick.value)})]`);
    };
    const tint = document.createElement("select");
    tint.title = "recolour the category: its template's geometry with this entry's colours";
    tint.appendChild(Object.assign(document.createElement("option"), { value: "", textContent: "recolour from..." }));
    for (const a of l.assets.filter((a) => a.kind === "entry")) {
      tint.appendChild(Object.assign(document.createElement("option"), { value: a.name, textContent: `${a.name} (${categoryLabel(a.category)})` }));
    }
    if (used.length === 1 && used[0].startsWith(c.name + "~")) {
      const from = used[0].slice(c.name.length + 1);
      if ([...tint.options].some((o) => o.value === from)) tint.value = from;
    }
    tint.onchange = () => {
      if (tint.value) recolour(c.name, tint.value);
    };
    const thumb = document.createElement("img");
    thumb.className = "thumb";
    thumb.alt = `${c.label}: its template seen from above`;
    loadThumbnail(c.name, thumb);
    const label = document.createElement("span");
    label.className = "label";
    label.textContent = c.label === c.name ? `${c.name} (${count})` : `${c.label} (${c.name}, ${count})`;
    const rn = document.createElement("button");
    rn.textContent = "Rename";
    rn.title = "give the category a name (NameCategory; saved with the layout)";
    rn.onclick = () => {
      const n = window.prompt(`Name for ${c.name}:`, c.label);
      if (n && n.trim() && n.trim() !== c.label) {
        sendEdits(`[NameCategory(category: ${ronString(c.name)}, name: ${ronString(n.trim())})]`);
      }
    };
    const rm = document.createElement("button");
    rm.textContent = "Remove";
    rm.title = "remove every instance of the category (RemoveCategory)";
    rm.onclick = () => sendEdits(`[RemoveCategory(${ronString(c.name)})]`);
    li.append(sw, thumb, label, pick, tint, rn, rm);
    cats.appendChild(li);
  }
}

// a category's thumbnail, fetched once per page
const thumbnails = new Map();
function loadThumbnail(category, img) {
  if (!thumbnails.has(category)) thumbnails.set(category, fetchImage(`thumbnail?category=${encodeURIComponent(category)}`));
  thumbnails.get(category).then((url) => { if (url) img.src = url; });
}

// ---- the 3D view -------------------------------------------------------------------

function viewQuery(side) {
  const v = editor.view;
  let q = `render?width=${side}&height=${side}&azimuth=${num(v.azimuth)}&elevation=${num(v.elevation)}`;
  if (v.radius) q += `&radius=${num(v.radius)}`;
  return q;
}

function fullSide() {
  const w = $("view-box").getBoundingClientRect().width;
  return Math.max(PREVIEW_SIDE, Math.min(512, Math.round(w / 32) * 32 || 256));
}

// a coarse preview first, then full resolution; a newer request wins over older ones
async function renderView() {
  const seq = ++editor.renderSeq;
  const version = editor.layout.version;
  const img = $("view");
  for (const [side, preview] of [[PREVIEW_SIDE, true], [fullSide(), false]]) {
    const url = await fetchImage(viewQuery(side) + `&v=${version}`);
    if (seq !== editor.renderSeq) {
      if (url) URL.revokeObjectURL(url);
      return;
    }
    if (!url) continue; // a failed preview: still try full size
    await new Promise((resolve) => {
      img.onload = resolve;
      img.onerror = resolve;
      if (img.src.startsWith("blob:")) URL.revokeObjectURL(img.src);
      img.src = url;
    });
    editor.shown = { version, width: side, preview };
    img.dataset.version = version;
    img.dataset.preview = preview;
  }
}

let orbit = null;
function onViewDown(evt) {
  if (evt.button !== 0) return;
  orbit = { x: evt.clientX, y: evt.clientY, az: editor.view.azimuth, el: editor.view.elevation };
  $("view").setPointerCapture(evt.pointerId);
  evt.preventDefault();
}
function onViewMove(evt) {
  if (!orbit) return;
  editor.view.azimuth = orbit.az - (evt.clientX - orbit.x) * 0.5;
  editor.view.elevation = Math.max(5, Math.min(85, orbit.el + (evt.clientY - orbit.y) * 0.3));
}
function onViewUp() {
  if (!orbit) return;
  // (also on pointercancel: render where the orbit got to)
  orbit = null;
  renderView();
}
let wheelTimer = null;
function onWheel(evt) {
  evt.preventDefault();
  const e = editor.layout.extent;
  const base = editor.view.radius || Math.hypot(e[2] - e[0], e[3] - e[1]) * 1.6;
  const diag = Math.hypot(e[2] - e[0], e[3] - e[1]);
  editor.view.radius = Math.min(20 * diag, Math.max(0.05 * base, base * Math.exp(evt.deltaY * 0.001)));
  clearTimeout(wheelTimer);
  wheelTimer = setTimeout(renderView, 120);
}

// ---- start ---------------------------------------------------------------------------

async function start() {
  const svg = $("bev-svg");
  svg.addEventListener("pointerdown", onPointerDown);
  svg.addEventListener("pointermove", onPointerMove);
  svg.addEventListener("pointerup", onPointerUp);
  svg.addEventListener("pointercancel", onPointerCancel);
  const view = $("view");
  view.addEventListener("pointerdown", onViewDown);
  view.addEventListener("pointermove", onViewMove);
  view.addEventListener("pointerup", onViewUp);
  view.addEventListener("pointercancel", onViewUp);
  view.addEventListener("wheel", onWheel, { passive: false });
  document.addEventListener("keydown", onKey);
  window.addEventListener("beforeunload", (evt) => {
    if (editor.layout && editor.layout.unsaved) {
      evt.preventDefault();
      evt.returnValue = "";
    }
  });
  $("undo").onclick = undo;
  $("redo").onclick = redo;
  $("save").onclick = save;
  $("apply-text").onclick = () => sendEdits($("edit-text").value);
  $("use-asset").onclick = () => {
    if (editor.selected && editor.chosenAsset) {
      sendEdits(`[Override(target: ${ronString(editor.selected)}, asset: ${ronString(editor.chosenAsset)})]`);
    }
  };
  const r = await api("layout");
  if (!r.ok) {
    status(r.status === 403 ? "the token is missing or wrong: open the URL `assetfield edit` printed" : "cannot load the layout", true);
    return;
  }
  setLayout(await r.json());
  status(`${editor.layout.instances.length} instances; Save writes ${editor.layout.save_path}`);
  editor.ready = true;
}

start();
