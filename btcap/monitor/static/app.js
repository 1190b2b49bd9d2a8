// btcap monitor page: applies the server's events to the picture and draws it.
// `apply` mirrors btcap/monitor/view.py (TeamView.apply): keep the two in step.
"use strict";

const MAX_RUNS = 2000, MAX_AUCTIONS = 200, MAX_MARKS = 500;
const ACTIVE = new Set(["running", "assigned", "unassigned"]);
const STATES = ["idle", "running", "succeeded", "failed", "error", "unassigned", "assigned",
  "paused", "shutdown", "skipped"];
const FILL = { idle: "#dfe3e8", running: "#f5b942", succeeded: "#4bb982", failed: "#e05a5a",
  error: "#9b2c4a", unassigned: "#b29cf7", assigned: "#5cc3ee", paused: "#f7e3a1",
  shutdown: "#f4f5f7", uninitialized: "#f4f5f7", skipped: "#e9ecef", gone: "#ffffff" };
// The timeline's capability colours: far from every state's fill above (darker, at least
// 80 apart in RGB), so that a bar is never read as a node state; the timeline has a
// legend of its own.
const PALETTE = ["#3a6ea5", "#a05195", "#6b6b2a", "#2a7a4a", "#665191", "#1d6b66", "#2f4b7c",
  "#355c3c"];
// Below this a fitted tree's text is too small to read: it scrolls instead.
const MIN_FIT = 0.8;

let S = null;            // the picture
let dirty = false;
let ws = null;
let down = false;        // the connection dropped (after a finished run it is no news)
const capColour = new Map();

function fromSnapshot(snap) {
  const runs = new Map(snap.runs.map((r) => [r.execution, r]));
  const auctions = new Map(snap.auctions.map((a) => [a.id, a]));
  // Robot names come from peers: a name like "constructor" must not find Object's own.
  const robots = Object.assign(Object.create(null), snap.robots);
  return { ...snap, robots, runs, auctions };
}
const own = (obj, key) => (Object.hasOwn(obj, key) ? obj[key] : undefined);

function robot(name) {
  if (!S.robots[name]) S.robots[name] = { status: "seen", trees: {} };
  return S.robots[name];
}

function trim(map, max) {
  while (map.size > max) map.delete(map.keys().next().value);
}

// Equal as JSON values (key order aside), as Python compares the decoded dicts.
function same(a, b) {
  if (a === b) return true;
  if (typeof a !== "object" || typeof b !== "object" || a === null || b === null) return false;
  if (Array.isArray(a) !== Array.isArray(b)) return false;
  const ka = Object.keys(a);
  return ka.length === Object.keys(b).length && ka.every((k) => Object.hasOwn(b, k) && same(a[k], b[k]));
}

// What two auctions of one node must share to be shown as one row (view.py, _SAME, _WON).
const SAME = ["capability", "auctioneer", "why", "winner"], WON = ["bids", "declined", "reasons"];
// Who bid, declined or was passed over, without what they asked (view.py, _who).
const who = (a) => [a.bids.map(([r]) => r).sort(), Object.keys(a.declined).sort(),
  Object.keys(a.reasons).sort()];
// Two closed auctions of one node that ended the same way (view.py, _alike).
function alike(a, b) {
  if (!SAME.every((f) => same(a[f], b[f]))) return false;
  return a.winner !== null ? WON.every((f) => same(a[f], b[f])) : same(who(a), who(b));
}
// A closed auction that ended as the last one for its node did joins that one's row (view.py, _fold).
function fold(row) {
  let last = null, before = false;
  for (const other of [...S.auctions.values()].reverse()) {
    if (other === row) before = true;
    else if (before && other.node === row.node) { last = other; break; }
  }
  if (!last || last.closed === null || !alike(last, row)) return;
  Object.assign(row, { count: last.count + 1, first: last.first });
  S.auctions.delete(last.id);
}

function apply(ev) {
  S.t = Math.max(S.t, ev.t);
  switch (ev.k) {
    case "robot": robot(ev.robot); break;
    case "tree": robot(ev.robot).trees[ev.tree] = { nodes: ev.nodes.map((n) => ({ ...n })) }; break;
    case "states": {
      const tree = robot(ev.robot).trees[ev.tree];
      if (tree) for (const n of tree.nodes) if (Object.hasOwn(ev.states, n.id)) n.state = ev.states[n.id];
      break;
    }
    case "team":
      robot(ev.robot).status = ev.change;
      S.marks.push({ t: ev.t, robot: ev.robot, change: ev.change });
      if (S.marks.length > MAX_MARKS) S.marks.splice(0, S.marks.length - MAX_MARKS);
      break;
    case "run":
      if (ev.phase === "start") {
        robot(ev.robot);
        S.runs.set(ev.execution, { execution: ev.execution, robot: ev.robot, origin: ev.origin,
          node: ev.node, capability: ev.capability, start: ev.t, end: null, result: null,
          why: null });
        trim(S.runs, MAX_RUNS);
      } else if (S.runs.has(ev.execution)) {
        Object.assign(S.runs.get(ev.execution), { end: ev.t, result: ev.result, why: ev.why ?? null });
      }
      break;
    case "auction":
      if (ev.phase === "open") {
        S.auctions.set(ev.id, { id: ev.id, auctioneer: ev.auctioneer, capability: ev.capability,
          node: ev.node, execution: ev.execution, candidates: ev.candidates, why: ev.why,
          opened: ev.t, closed: null, bids: [], declined: {}, reasons: {}, winner: null,
          count: 1, first: ev.t });
        trim(S.auctions, MAX_AUCTIONS);
      } else if (S.auctions.has(ev.id)) {
        const row = S.auctions.get(ev.id);
        Object.assign(row, { closed: ev.t, bids: ev.bids, declined: ev.declined,
          reasons: ev.reasons, winner: ev.winner });
        fold(row);
      }
      break;
    case "finished":
      S.finished = { t: ev.t, result: ev.result, summary: ev.summary };
      break;
    case "clock":
      if (S.replay) Object.assign(S.replay, { t: ev.t, playing: ev.playing, speed: ev.speed });
      break;
  }
}

// -- drawing helpers ----------------------------------------------------------------------
const SVGNS = "http://www.w3.org/2000/svg";
function el(tag, attrs = {}, ...kids) {
  const e = tag.startsWith("svg:") ? document.createElementNS(SVGNS, tag.slice(4))
    : document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === null || v === undefined || v === false) continue;
    if (k === "text") e.textContent = v; else e.setAttribute(k, v);
  }
  for (const k of kids) if (k) e.append(k);
  return e;
}
const fmt = (t) => (t >= 100 ? t.toFixed(0) : t.toFixed(1));
function colourOf(cap) {
  if (!capColour.has(cap)) capColour.set(cap, PALETTE[capColour.size % PALETTE.length]);
  return capColour.get(cap);
}
function fit(text, px, charPx = 6.2) {
  const n = Math.floor(px / charPx);
  return text.length <= n ? text : n > 2 ? text.slice(0, n - 1) + "…" : "";
}
function robotNames() {
  const names = Object.keys(S.robots);
  const lane = (n) => (Object.keys(S.robots[n].trees).some((t) => !t.endsWith("-host")) ? 1 : 0);
  return names.sort((a, b) => lane(a) - lane(b) || a.localeCompare(b));
}

// -- robots ---------------------------------------------------------------------------------
function drawTeam() {
  const box = document.getElementById("team");
  box.replaceChildren();
  for (const name of robotNames()) {
    const r = S.robots[name];
    const runs = [...S.runs.values()];
    const hosts = runs.filter((x) => x.robot === name && x.end === null);
    const mine = runs.filter((x) => x.origin === name && x.end === null);
    const done = runs.filter((x) => x.robot === name && x.result === "succeeded").length;
    const card = el("div", { class: `card ${r.status}`, "data-robot": name },
      el("h3", {}, el("span", { text: name }), el("span", { class: "badge", text: r.status })));
    const hosting = hosts.map((x) => `${x.capability} for ${x.origin}`).join(", ");
    const missions = Object.entries(r.trees).filter(([t]) => !t.endsWith("-host"));
    for (const [t, tree] of missions) {
      const root = tree.nodes.find((n) => n.parent === null);
      card.append(el("div", { class: "row" }, "mission ", el("b", { text: t }),
        ` · ${root ? root.state : "empty"}`));
    }
    if (!missions.length || hosting) {
      card.append(el("div", { class: "row" }, "runs ", el("b", { text: hosting || "nothing" })));
    }
    if (mine.length) {
      const where = mine.map((x) => `${x.capability} → ${x.robot}`).join(", ");
      card.append(el("div", { class: "row" }, "its capabilities: ", el("b", { text: where })));
    }
    const tally = done === 1 ? "1 run succeeded" : `${done || "no"} runs succeeded`;
    if (!missions.length) card.append(el("div", { class: "row", text: tally }));
    box.append(card);
  }
}

// -- timeline -------------------------------------------------------------------------------
function drawTimeline() {
  const box = document.getElementById("timeline");
  const names = robotNames().filter((n) => !isOperator(n));
  const width = Math.max(500, box.clientWidth || 900);
  const laneH = 24, top = 18, left = 78, right = 10;
  const runs = [...S.runs.values()];
  const t0 = Math.min(S.t, ...runs.map((r) => r.start), ...S.marks.map((m) => m.t));
  const t1 = Math.max(S.t, t0 + 1);
  const x = (t) => left + ((t - t0) / (t1 - t0)) * (width - left - right);
  const svg = el("svg:svg", { width, height: top + laneH * Math.max(1, names.length) + 4 });
  const step = niceStep((t1 - t0) / 8);
  for (let t = Math.ceil(t0 / step) * step; t <= t1; t += step) {
    svg.append(el("svg:line", { x1: x(t), x2: x(t), y1: top - 4, y2: top + laneH * names.length,
      class: "grid" }));
    svg.append(el("svg:text", { x: x(t), y: 11, class: "axis", "text-anchor": "middle",
      text: `${fmt(t)} s` }));
  }
  names.forEach((name, i) => {
    const y = top + i * laneH;
    const g = el("svg:g", { class: "lane", "data-robot": name });
    g.append(el("svg:rect", { x: left, y: y + 1, width: width - left - right, height: laneH - 2,
      class: "lane-bg" }));
    g.append(el("svg:text", { x: 4, y: y + laneH / 2 + 4, class: "lane-label", text: name }));
    for (const r of runs.filter((r) => r.robot === name)) {
      const a = x(r.start), b = x(r.end ?? S.t), w = Math.max(2, b - a);
      const bad = r.result && r.result !== "succeeded";
      const bar = el("svg:rect", { x: a, y: y + 4, width: w, height: laneH - 8, rx: 2,
        fill: colourOf(r.capability), class: bad ? "bar bad" : "bar", "data-capability": r.capability });
      bar.append(el("svg:title", { text: `${r.capability} for ${r.origin} (${r.node})\n` +
        `${fmt(r.start)}–${r.end === null ? "now" : fmt(r.end)} s: ${r.result ?? "running"}` +
        (r.why ? `\n${r.why}` : "") }));
      g.append(bar);
      const label = fit(r.capability, w - 4);
      if (label) g.append(el("svg:text", { x: a + 3, y: y + laneH / 2 + 3.5, class: "bar-label",
        text: label }));
    }
    for (const m of S.marks.filter((m) => m.robot === name)) {
      const sym = { joined: "▲", failed: "✕", left: "▽" }[m.change] ?? "•";
      const fill = { joined: "#1f8f5a", failed: "#c0392b", left: "#6b7785" }[m.change];
      g.append(el("svg:text", { x: x(m.t), y: y + laneH / 2 + 4, "text-anchor": "middle",
        fill, "font-size": 12, text: sym }, el("svg:title", { text: `${name} ${m.change} at ${fmt(m.t)} s` })));
    }
    svg.append(g);
  });
  svg.append(el("svg:line", { x1: x(S.t), x2: x(S.t), y1: top - 4,
    y2: top + laneH * names.length, class: "now" }));
  const caps = [...new Set(runs.map((r) => r.capability))];
  const key = el("div", { class: "legend caps" }, ...caps.map((c) => {
    const swatch = el("i");
    swatch.style.background = colourOf(c);
    return el("span", { "data-capability": c }, swatch, c);
  }));
  box.replaceChildren(svg, key);
}
function niceStep(raw) {
  const p = 10 ** Math.floor(Math.log10(Math.max(raw, 1e-6)));
  return [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw) ?? 10 * p;
}
function isOperator(name) {
  const r = S.robots[name];
  const hosts = [...S.runs.values()].some((x) => x.robot === name);
  return !hosts && Object.keys(r.trees).some((t) => !t.endsWith("-host"));
}

// -- trees ----------------------------------------------------------------------------------
const NODE_W = 118, NODE_H = 32, GAP_X = 10, GAP_Y = 22;
function layout(nodes) {
  const kids = new Map(nodes.map((n) => [n.id, []]));
  const roots = [];
  for (const n of nodes) (n.parent !== null && kids.has(n.parent) ? kids.get(n.parent) : roots).push(n);
  const pos = new Map();
  let next = 0, depth = 0;
  const place = (n, d) => {
    depth = Math.max(depth, d);
    const ch = kids.get(n.id);
    if (!ch.length) { pos.set(n.id, { x: next++, d }); return; }
    ch.forEach((c) => place(c, d + 1));
    pos.set(n.id, { x: (pos.get(ch[0].id).x + pos.get(ch[ch.length - 1].id).x) / 2, d });
  };
  roots.forEach((r) => place(r, 0));
  return { pos, kids, cols: Math.max(next, 1), rows: depth + 1 };
}
// What a node is drawn as. A robot that left or failed is gone, with all it hosted; a
// slot hosting nothing is idle: it stays "running" (ticked, waiting for work) all its life.
function shown(n, gone, kids) {
  if (gone) return "gone";
  if (n.type === "RemoteCapabilitySlot" && n.state === "running" && !kids.has(n.id)) return "idle";
  return n.state;
}
// A tree wider than its panel is drawn to fit (the default, but never below MIN_FIT: a
// wider one scrolls) or at 100 % with a scroll bar.
function drawTree(robotName, treeName, tree) {
  const { pos, kids, cols, rows } = layout(tree.nodes);
  const w = cols * (NODE_W + GAP_X) + GAP_X, h = rows * (NODE_H + GAP_Y) + 6;
  const room = Math.max(300, document.getElementById("trees").clientWidth - 4);
  const k = w > room && document.getElementById("fit").checked ? Math.max(MIN_FIT, room / w) : 1;
  const status = S.robots[robotName].status;
  const gone = treeName.endsWith("-host") && (status === "left" || status === "failed");
  const parents = new Set([...kids].filter(([, ch]) => ch.length).map(([id]) => id));
  const svg = el("svg:svg", { width: w * k, height: h * k, viewBox: `0 0 ${w} ${h}`,
    "data-tree": treeName, "data-zoom": k.toFixed(3), "data-wide": w > room ? "yes" : null });
  const at = (id) => { const p = pos.get(id); return { x: GAP_X + p.x * (NODE_W + GAP_X), y: 4 + p.d * (NODE_H + GAP_Y) }; };
  const byId = new Map(tree.nodes.map((n) => [n.id, n]));
  const running = new Map();
  for (const r of S.runs.values()) if (r.end === null) running.set(r.node, r.robot);
  for (const n of tree.nodes) {
    if (n.parent === null || !byId.has(n.parent)) continue;
    const a = at(n.parent), b = at(n.id);
    const active = !gone && ACTIVE.has(n.state) && ACTIVE.has(byId.get(n.parent).state);
    const my = (a.y + NODE_H + b.y) / 2;
    svg.append(el("svg:path", { class: active ? "edge active" : "edge",
      d: `M${a.x + NODE_W / 2},${a.y + NODE_H} V${my} H${b.x + NODE_W / 2} V${b.y}` }));
  }
  for (const n of tree.nodes) {
    const p = at(n.id);
    const state = shown(n, gone, parents);
    const cls = `node${n.cap ? " cap" : ""}${ACTIVE.has(state) ? " active" : ""}`;
    const g = el("svg:g", { class: cls, "data-state": state, "data-node": n.id,
      transform: `translate(${p.x},${p.y})` });
    const dashed = state === "shutdown" || state === "uninitialized" || state === "gone";
    g.append(el("svg:rect", { width: NODE_W, height: NODE_H, rx: n.cap ? 9 : 3,
      fill: FILL[state] ?? FILL.idle, "stroke-dasharray": dashed ? "3 2" : null }));
    const where = n.cap ? running.get(`${robotName}:${n.id}`) : null;
    const said = gone ? `robot ${status}` : state;
    g.append(el("svg:text", { x: 6, y: 13, class: "name", text: fit(n.name, NODE_W - 10, 6.4) }));
    g.append(el("svg:text", { x: 6, y: 26, class: "type",
      text: fit(where ? `${n.type} → ${where}` : `${n.type} · ${said}`, NODE_W - 10, 5.2) }));
    const last = state !== n.state ? ` (${gone ? "last seen" : "ticked, hosting nothing"}: ${n.state})` : "";
    g.append(el("svg:title", { text: `${n.id}\n${n.type}: ${said}${last}${where ? ` on ${where}` : ""}` }));
    svg.append(g);
  }
  return svg;
}
function drawTrees() {
  const box = document.getElementById("trees");
  const scroll = new Map([...box.querySelectorAll(".tree-scroll")].map((d) => [d.dataset.key, d.scrollLeft]));
  box.replaceChildren();
  const blocks = [];
  let wide = false;
  for (const name of robotNames().reverse()) {
    for (const [t, tree] of Object.entries(S.robots[name].trees)) {
      const host = t.endsWith("-host");
      const key = `${name}/${t}`;
      const svg = drawTree(name, t, tree);
      const k = +svg.dataset.zoom;
      wide ||= svg.dataset.wide === "yes";
      const div = el("div", { class: "tree-scroll", "data-key": key }, svg);
      const gone = host && (S.robots[name].status === "left" || S.robots[name].status === "failed");
      blocks.push([host, el("div", { class: `tree-block ${host ? "host" : "mission"}${gone ? " gone" : ""}`,
        "data-robot": name }, el("h3", {}, `${name} `, el("small", { text: t }),
        k < 1 ? el("small", { class: "zoomed", text: ` · ${Math.round(k * 100)} %` }) : null,
        gone ? el("small", { class: "gone", text: ` · ${S.robots[name].status}` }) : null), div)]);
      requestAnimationFrame(() => { div.scrollLeft = scroll.get(key) ?? 0; });
    }
  }
  blocks.sort((a, b) => a[0] - b[0]).forEach(([, b]) => box.append(b));
  document.getElementById("zoom").hidden = !wide;
}

// -- auctions -------------------------------------------------------------------------------
// A re-evaluation that kept the work where it was: nothing changed (hidden when filtered).
const kept = (a) => a.why.startsWith("re-evaluation") && a.closed !== null && !a.winner;
function drawAuctions() {
  const box = document.getElementById("auctions");
  const all = [...S.auctions.values()].reverse();
  const informative = document.getElementById("informative").checked;
  const shownRows = informative ? all.filter((a) => !kept(a)) : all;
  const hidden = all.length - shownRows.length;
  const note = document.getElementById("hidden");
  note.textContent = hidden ? `${hidden} hidden` : "";
  note.title = hidden ? `${hidden} ${hidden === 1 ? "row" : "rows"} of re-evaluations that kept the work where it was` : "";
  const list = shownRows.slice(0, 14);
  if (!list.length) {
    box.replaceChildren(el("div", { class: "empty",
      text: all.length ? "no informative auctions yet" : "no auctions yet" }));
    return;
  }
  const table = el("table", {}, el("tr", {}, ...["t [s]", "capability", "why", "bids"].map((h) => el("th", { text: h }))));
  for (const a of list) {
    const bids = el("td");
    for (const [r, cost] of a.bids) {
      const why = own(a.reasons, r);
      const refused = why && why.includes("award");  // declined or missed the award
      bids.append(el("span", { class: r === a.winner ? "bid win" : why ? "bid no" : "bid",
        title: why ?? null, text: `${r} ${cost.toFixed(1)}${refused ? " ✗" : ""}` }));
    }
    for (const [r, why] of Object.entries(a.declined)) {  // would not bid
      bids.append(el("span", { class: "bid no", title: why, text: `${r} declined` }));
    }
    const stays = kept(a);
    if (a.closed === null) bids.append(el("span", { class: "why", text: "open…" }));
    else if (stays) bids.append(el("span", { class: "why", text: "stays" }));
    else if (!a.winner) bids.append(el("span", { class: "why re", text: "nobody took it" }));
    const re = a.why !== "first request" && !a.why.startsWith("new run");
    const many = a.count > 1;  // identical auctions of one node, folded (view.py)
    const span = many ? `${a.count} identical auctions from ${fmt(a.first)} s to ${fmt(a.opened)} s` : null;
    table.append(el("tr", { "data-auction": a.id, "data-count": a.count, class: stays ? "kept" : null },
      el("td", { class: "num", title: span, text: many ? `${fmt(a.first)}–${fmt(a.opened)}` : fmt(a.opened) }),
      el("td", { title: `${a.id} · ${a.node}` }, el("b", { text: a.capability }), el("br"),
        el("span", { class: "why", text: a.node.split("/").slice(-2).join("/") })),
      el("td", { class: re ? "why re" : "why" },
        many ? el("span", { class: "count", title: span, text: `×${a.count}` }) : null, a.why), bids));
  }
  box.replaceChildren(table);
}

// -- header and replay controls -----------------------------------------------------------------
function drawHeader() {
  document.getElementById("title").textContent = S.title || "";
  const mode = document.getElementById("mode");
  const fin = S.finished;
  const state = fin ? "finished" : down ? "disconnected" : S.mode;
  mode.textContent = state;
  mode.className = `mode ${fin ? "finished" : down ? "down" : S.mode}`;
  mode.title = fin && down ? "the monitor has closed; the page keeps the final picture" : "";
  const atEnd = S.replay && S.replay.t >= S.replay.end;
  const summary = document.getElementById("summary");
  summary.textContent = fin ? fin.summary : atEnd ? "end of the recording (no result in it)" : "";
  summary.className = `summary ${fin ? fin.result : ""}`;
  summary.hidden = !summary.textContent;
  document.getElementById("clock").textContent = `t = ${fmt(S.t)} s`;
  const rp = document.getElementById("replay");
  rp.hidden = S.mode !== "replay";
  if (S.replay) {
    const seek = document.getElementById("seek");
    seek.min = S.replay.start; seek.max = S.replay.end;
    if (document.activeElement !== seek) seek.value = S.replay.t;
    document.getElementById("play").textContent = S.replay.playing ? "pause" : "play";
    const sp = document.getElementById("speed");
    const opts = [1, 2, 5, 10, 20, 50, 100, S.replay.speed].filter((v, i, a) => a.indexOf(v) === i).sort((a, b) => a - b);
    if (sp.options.length !== opts.length) sp.replaceChildren(...opts.map((v) => el("option", { value: v, text: `${+v.toFixed(1)}×` })));
    sp.value = S.replay.speed;
  }
}

function render() {
  dirty = false;
  if (!S) return;
  drawHeader(); drawTeam(); drawTimeline(); drawTrees(); drawAuctions();
}
function schedule() { if (!dirty) { dirty = true; requestAnimationFrame(render); } }

function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  ws = new WebSocket(`${proto}://${location.host}/ws`);
  ws.onmessage = (m) => {
    const msg = JSON.parse(m.data);
    if (msg.type === "snapshot") { S = fromSnapshot(msg.state); down = false; }
    else if (msg.type === "events" && S) msg.events.forEach(apply);
    schedule();
  };
  ws.onclose = () => {
    // The page keeps its picture. After a finished run the monitor closing is expected:
    // the header keeps saying how it ended; only an unexpected drop says disconnected.
    // Either way it tries again (the next run of `btcap run --compare` serves here too).
    down = true;
    if (S) schedule();
    else {
      const mode = document.getElementById("mode");
      mode.textContent = "disconnected"; mode.className = "mode down";
    }
    setTimeout(connect, 2000);
  };
}
function send(msg) { if (ws && ws.readyState === 1) ws.send(JSON.stringify(msg)); }

document.getElementById("play").onclick = () => send({ op: S && S.replay && S.replay.playing ? "pause" : "play" });
document.getElementById("seek").onchange = (e) => send({ op: "seek", t: +e.target.value });
document.getElementById("speed").onchange = (e) => send({ op: "speed", speed: +e.target.value });
document.getElementById("fit").onchange = schedule;
document.getElementById("informative").onchange = schedule;
document.getElementById("legend").append(...[...STATES.slice(0, 8), "gone"].map((s) => {
  const swatch = el("i", { class: s === "gone" ? "gone" : null,
    title: s === "gone" ? "a robot that left or failed: its slot and what it hosted" : null });
  swatch.style.background = FILL[s];
  return el("span", { "data-state": s }, swatch, s === "gone" ? "gone (left, failed)" : s);
}));
window.addEventListener("resize", schedule);
connect();
