// The shapedb page: search by upload or stored shape, results grid, 3-D views, part
// matching, a store browser with label facets, and the evaluation view.
import { Viewer, snapshot } from "/static/viewer.js";

const $ = (sel) => document.querySelector(sel);
const state = { server: null, query: null, results: [], shapes: new Map(), browse: { offset: 0, label: null } };
window.shapedb = state; // for the browser tests

// ------------------------------------------------------------------ http
function authHeaders() {
  const t = sessionStorage.getItem("shapedb-token");
  return t ? { Authorization: `Bearer ${t}` } : {};
}

async function api(path, options = {}) {
  const res = await fetch(path, { ...options, headers: { ...authHeaders(), ...(options.headers || {}) } });
  const text = await res.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch (e) { data = { error: text }; }
  if (!res.ok) throw new Error((data && data.error) || `${res.status} ${res.statusText}`);
  return { data, res };
}

async function shapeData(id) {
  if (!state.shapes.has(id)) state.shapes.set(id, api(`/api/shapes/${id}`).then((r) => r.data));
  return state.shapes.get(id);
}

function status(text, error = false) {
  const el = $("#status");
  el.textContent = text;
  el.classList.toggle("error", error);
}

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v; else if (k.startsWith("on")) e.addEventListener(k.slice(2), v); else e.setAttribute(k, v);
  }
  for (const c of children) e.append(c);
  return e;
}

// ------------------------------------------------------------------ views
const queryView = new Viewer($("#query-view"), {
  onPick: (node, point) => matchPart(node, point),
  onMiss: () => status(state.query
    ? "no ball there — click on a ball to find similar parts"
    : "search first, then click a ball of the query to find similar parts"),
});
const shapeView = new Viewer($("#shape-view"));
state.queryView = queryView;
state.shapeView = shapeView;
for (const box of document.querySelectorAll(".toggles")) {
  const view = box.dataset.for === "query-view" ? queryView : shapeView;
  box.addEventListener("change", (e) => { if (e.target.dataset.layer) view.setLayer(e.target.dataset.layer, e.target.checked); });
}

// A thumbnail, with a placeholder (the shape's name, a spinner) until it has loaded; one
// still being drawn (a shape committed a moment ago) is asked for again a few times.
const THUMB_TRIES = 5; // over about 10 s
function picture(hit) {
  const pic = el("div", { class: "pic loading" },
    el("div", { class: "placeholder" }, el("span", { class: "spinner" }), el("span", {}, hit.name)));
  const src = `/api/shapes/${hit.id}/thumbnail.png`;
  const img = el("img", { src, alt: hit.name, loading: "lazy" });
  let tries = 1;
  img.addEventListener("load", () => pic.classList.remove("loading", "missing"));
  img.addEventListener("error", () => {
    if (tries >= THUMB_TRIES) { pic.classList.add("missing"); return; }
    setTimeout(() => { img.src = `${src}?try=${tries}`; tries++; }, 1000 * tries);
  });
  pic.append(img, el("canvas"));
  return pic;
}

function card(hit, onClick) {
  const c = el("div", { class: "card", "data-id": String(hit.id), onclick: onClick },
    picture(hit),
    el("div", { class: "name", title: hit.name }, hit.name),
    el("div", { class: "meta" }, el("span", {}, hit.label ?? "—"),
      el("span", {}, hit.similarity !== undefined ? hit.similarity.toFixed(3) : `#${hit.id}`)));
  if (hit.similarity !== undefined) {
    const bar = el("span");
    bar.style.width = `${Math.round(100 * hit.similarity)}%`;
    c.append(el("div", { class: "bar" }, bar));
  }
  c.append(el("div", { class: "part" }));
  return c;
}

async function openShape(id) {
  $("#shape-panel").hidden = false;
  $("#panel-title").textContent = `shape ${id}`;
  $("#panel-info").textContent = "loading…";
  const shape = await shapeData(id);
  $("#panel-title").textContent = `${shape.name} (${shape.label ?? "no label"})`;
  $("#panel-search").onclick = () => { $("#shape-panel").hidden = true; showTab("search"); searchStored(String(id)); };
  shapeView.resize();
  shapeView.show(shape, null);
  const match = state.matches && state.matches.get(id);
  if (match) shapeView.highlight(match.nodes);
  $("#panel-info").textContent =
    `#${shape.id} · ${shape.representation} · ${shape.n_balls} balls · ${shape.n_edges} contacts` +
    (match ? ` · matched part ${match.similarity.toFixed(3)} (red)` : "");
  const surface = (await api(`/api/shapes/${id}/surface`)).data;
  if (surface.kind !== "none" && state.openId === id) {
    shapeView.show(shape, surface);
    if (match) shapeView.highlight(match.nodes);
  }
}
$("#panel-close").onclick = () => { $("#shape-panel").hidden = true; state.openId = null; };
$("#shape-panel").addEventListener("click", (e) => { if (e.target.id === "shape-panel") $("#panel-close").click(); });

// ------------------------------------------------------------------ search
function showResults(hits, title) {
  state.results = hits;
  state.matches = null;
  $("#results-title").textContent = title;
  const grid = $("#results");
  grid.replaceChildren(...hits.map((h) => card(h, () => { state.openId = h.id; openShape(h.id); })));
  if (!hits.length) grid.append(el("p", { class: "muted" }, "No shapes found."));
}

async function searchStored(idOrName) {
  status(`searching for ${idOrName}…`);
  try {
    const { data } = await api(`/api/search?id=${encodeURIComponent(idOrName)}&k=12`);
    const shape = await shapeData(/^\d+$/.test(idOrName) ? Number(idOrName) : idOrName);
    state.query = { ref: shape.id, name: shape.name, shape };
    queryView.show(shape, null);
    showResults(data, `Nearest to ${shape.name}`);
    status(`${data.length} results · click a ball of the query to match its part`);
    api(`/api/shapes/${shape.id}/surface`).then(({ data: s }) => {
      if (s.kind !== "none" && state.query && state.query.ref === shape.id) queryView.show(shape, s);
    });
  } catch (e) { status(e.message, true); }
}

async function searchFile(file) {
  status(`decomposing ${file.name}…`);
  const form = new FormData();
  form.append("file", file);
  try {
    const t0 = performance.now();
    const { data, res } = await api("/api/search?k=12", { method: "POST", body: form });
    const key = res.headers.get("X-Query");
    const q = (await api(`/api/queries/${key}`)).data;
    state.query = { ref: `upload:${key}`, name: file.name, shape: q };
    queryView.show(q, q.surface);
    showResults(data, `Nearest to ${file.name}`);
    status(`${data.length} results in ${((performance.now() - t0) / 1000).toFixed(1)} s · click a ball of the query to match its part`);
  } catch (e) { status(e.message, true); }
}

async function matchPart(node, point) {
  if (!state.query || !state.results.length) return;
  const body = { query: state.query.ref, targets: state.results.map((h) => h.id), hops: Number($("#hops").value) };
  if (node !== null) body.node = node; else body.point = point;
  status("matching the part…");
  try {
    const { data } = await api("/api/match", {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
    });
    queryView.highlight(data.query_nodes);
    state.matches = new Map(data.matches.map((m) => [m.id, m]));
    for (const c of document.querySelectorAll("#results .card")) {
      const id = Number(c.dataset.id);
      const m = state.matches.get(id);
      c.classList.remove("matched");
      c.querySelector(".part").textContent = "";
      if (!m) continue;
      const shape = await shapeData(id);
      if (snapshot(c.querySelector("canvas"), shape, m.nodes)) c.classList.add("matched");
      c.querySelector(".part").textContent = `part ${m.similarity.toFixed(3)} · ${m.nodes.length} balls`;
    }
    status(`part of ${data.query_nodes.length} balls matched in ${data.matches.length} results (red)`);
  } catch (e) { status(e.message, true); }
}

const drop = $("#drop");
drop.addEventListener("dragover", (e) => { e.preventDefault(); drop.classList.add("over"); });
drop.addEventListener("dragleave", () => drop.classList.remove("over"));
drop.addEventListener("drop", (e) => {
  e.preventDefault();
  drop.classList.remove("over");
  if (e.dataTransfer.files.length) searchFile(e.dataTransfer.files[0]);
});
$("#file").addEventListener("change", (e) => { if (e.target.files.length) searchFile(e.target.files[0]); });
$("#pick").addEventListener("submit", (e) => { e.preventDefault(); const v = $("#pick-name").value.trim(); if (v) searchStored(v); });

// ------------------------------------------------------------------ browse
async function loadFacets() {
  const { data } = await api("/api/info");
  const list = $("#facets");
  const item = (name, count, label) => {
    const li = el("li", { onclick: () => { state.browse = { offset: 0, label }; loadBrowse(); loadFacets(); } },
      el("span", {}, name), el("span", { class: "muted" }, String(count)));
    if (state.browse.label === label) li.classList.add("active");
    return li;
  };
  list.replaceChildren(item("all", data.shapes, null),
    ...Object.entries(data.labels).map(([l, n]) => item(l, n, l)));
}

async function loadBrowse() {
  const { offset, label } = state.browse;
  const q = `/api/shapes?offset=${offset}&limit=48` + (label !== null ? `&label=${encodeURIComponent(label)}` : "");
  const { data } = await api(q);
  $("#browse-grid").replaceChildren(...data.shapes.map((s) => card(s, () => { state.openId = s.id; openShape(s.id); })));
  $("#page-info").textContent = data.total ? `${offset + 1}–${Math.min(offset + 48, data.total)} of ${data.total}` : "empty";
  $("#prev").disabled = offset === 0;
  $("#next").disabled = offset + 48 >= data.total;
}
$("#prev").onclick = () => { state.browse.offset = Math.max(0, state.browse.offset - 48); loadBrowse(); };
$("#next").onclick = () => { state.browse.offset += 48; loadBrowse(); };

$("#ingest-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  const files = $("#ingest-files").files;
  if (!files.length) return;
  const form = new FormData();
  for (const f of files) form.append("file", f);
  const label = $("#ingest-label").value.trim();
  if (label) form.append("label", label);
  const bar = $("#ingest-progress");
  const say = (t) => { $("#ingest-status").textContent = t; };
  try {
    let { data: job } = await api("/api/ingest", { method: "POST", body: form });
    bar.hidden = false;
    while (job.state === "running") {
      bar.max = job.total || 1; bar.value = job.done;
      say(`ingesting ${job.done}/${job.total}…`);
      await new Promise((r) => setTimeout(r, 500));
      job = (await api(`/api/ingest/${job.job}`)).data;
    }
    bar.value = bar.max;
    say(job.state === "done"
      ? `ingested ${job.report.ingested}, skipped ${job.report.skipped}, failed ${job.report.failed.length}`
      : `failed: ${job.error}`);
    refreshSummary(); loadFacets(); loadBrowse();
  } catch (err) { say(err.message); }
});

// ------------------------------------------------------------------ evaluate
$("#run-eval").onclick = async () => {
  $("#eval-status").textContent = "evaluating…";
  try {
    const { data } = await api("/api/eval");
    $("#eval-status").textContent = `${data.queries} queries`;
    drawCurve(data.recall, data.precision);
    $("#eval-summary").replaceChildren(...["nn", "first_tier", "second_tier", "e_measure", "dcg"].map(
      (k) => el("div", {}, `${k.replace("_", " ")}: ${data[k].toFixed(3)}`)));
    const cols = ["queries", "nn", "first_tier", "second_tier", "e_measure", "dcg"];
    $("#eval-table").replaceChildren(
      el("tr", {}, el("th", {}, "class"), ...cols.map((c) => el("th", {}, c.replace("_", " ")))),
      ...Object.entries(data.per_class).map(([name, row]) => el("tr", {}, el("td", {}, name),
        ...cols.map((c) => el("td", {}, c === "queries" ? String(row[c]) : Number(row[c]).toFixed(3))))));
  } catch (e) { $("#eval-status").textContent = e.message; }
};

function drawCurve(recall, precision) {
  const svg = $("#pr-curve");
  const W = 360, H = 280, L = 40, B = 30, T = 10, R = 10;
  const x = (r) => L + r * (W - L - R), y = (p) => H - B - p * (H - B - T);
  const pts = recall.map((r, i) => `${x(r).toFixed(1)},${y(precision[i]).toFixed(1)}`).join(" ");
  let grid = "";
  for (let t = 0; t <= 1.0001; t += 0.25) {
    grid += `<line x1="${x(t)}" y1="${y(0)}" x2="${x(t)}" y2="${y(1)}" stroke="#eee"/>` +
      `<line x1="${x(0)}" y1="${y(t)}" x2="${x(1)}" y2="${y(t)}" stroke="#eee"/>` +
      `<text x="${x(t)}" y="${H - 12}" font-size="10" text-anchor="middle">${t}</text>` +
      `<text x="${L - 6}" y="${y(t) + 3}" font-size="10" text-anchor="end">${t}</text>`;
  }
  svg.innerHTML = grid +
    `<polyline points="${pts}" fill="none" stroke="#1f77b4" stroke-width="2"/>` +
    `<text x="${(L + W) / 2}" y="${H}" font-size="11" text-anchor="middle">recall</text>` +
    `<text x="10" y="${H / 2}" font-size="11" transform="rotate(-90 10 ${H / 2})" text-anchor="middle">precision</text>`;
}

// ------------------------------------------------------------------ start
function showTab(name) {
  for (const b of document.querySelectorAll(".tab")) b.classList.toggle("active", b.dataset.tab === name);
  for (const p of document.querySelectorAll(".tab-page")) p.hidden = p.id !== `tab-${name}`;
  if (name === "browse") { loadFacets(); loadBrowse(); }
  if (name === "search") queryView.resize();
}
for (const b of document.querySelectorAll(".tab")) b.onclick = () => showTab(b.dataset.tab);

async function refreshSummary() {
  const { data } = await api("/api/server");
  state.server = data;
  $("#store-summary").textContent = `${data.shapes} shapes · version ${data.version}`;
  $("#formats").textContent = data.formats.map((f) => f.replace(".", "")).join(" · ");
  $("#token-box").hidden = !data.token_required;
}

$("#token").value = sessionStorage.getItem("shapedb-token") || "";
$("#token").addEventListener("change", (e) => sessionStorage.setItem("shapedb-token", e.target.value));

(async () => {
  try {
    await refreshSummary();
    const { data } = await api("/api/shapes?limit=1000");
    $("#shape-names").replaceChildren(...data.shapes.map((s) => el("option", { value: s.name })));
    state.ready = true;
  } catch (e) { status(e.message, true); }
})();
