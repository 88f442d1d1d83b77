// cnctwin live dashboard: reads the server-sent events of /api/stream (about 10 per second)
// and draws them; control commands go to /api/control with the access token.
"use strict";

const MAX_POINTS = 2400;      // samples kept per plot trace (30 s at 80 cycles/s)
const MAX_TIMELINE = 500;     // timeline rows kept
const live = {                // read by the tests and the benchmark
  messages: 0, draws: 0, plotMs: 0, stockMs: 0, arrivals: [], snapshot: null, info: null, timeline: [], stockUpdates: 0,
  rateHz() {
    const a = this.arrivals;
    return a.length < 2 ? 0 : (a.length - 1) / ((a[a.length - 1] - a[0]) / 1000);
  },
  // updates while the machine ran: their count and first and last arrival (ms)
  run: { count: 0, first: 0, last: 0 },
  runRateHz() {
    const r = this.run;
    return r.count < 2 ? 0 : (r.count - 1) / ((r.last - r.first) / 1000);
  },
};
window.cnctwinLive = live;

const $ = (id) => document.getElementById(id);
const fmt = (v, digits = 1) => (v === null || v === undefined || Number.isNaN(v))
  ? "-" : Number(v).toFixed(digits);

// ------------------------------------------------------------------ token
const params = new URLSearchParams(location.search);
if (params.has("token")) {
  sessionStorage.setItem("cnctwin_token", params.get("token"));
  params.delete("token");
  const rest = params.toString();
  history.replaceState(null, "", location.pathname + (rest ? "?" + rest : ""));
}

// ------------------------------------------------------------------ plots
const LAYOUT = {
  margin: { l: 48, r: 10, t: 6, b: 28 }, paper_bgcolor: "rgba(0,0,0,0)",
  plot_bgcolor: "rgba(0,0,0,0)", font: { color: "#dde6ee", size: 11 },
  xaxis: { title: { text: "machine time (s)" }, gridcolor: "#2b3947", zeroline: false },
  yaxis: { gridcolor: "#2b3947", zeroline: false },
  legend: { orientation: "h", x: 0, y: 1.12 }, showlegend: true,
};
const CONFIG = { displaylogo: false, responsive: true };
const line = (name, color, extra = {}) => ({
  x: [], y: [], name, mode: "lines", line: { color, width: 1.5 }, type: "scatter", ...extra,
});
// each plot: its traces and the series each trace shows
const PLOTS = {
  "plot-force": {
    y: "force (N)",
    traces: [
      ["force_band_low_n", line("band low", "rgba(88,166,255,0.3)", { showlegend: false, type: "scatter" })],
      ["force_band_high_n", line("band", "rgba(88,166,255,0.3)", { fill: "tonexty", fillcolor: "rgba(88,166,255,0.18)", type: "scatter" })],
      ["force_predicted_n", line("predicted", "#58a6ff")],
      ["force_measured_n", line("measured", "#f0883e")],
    ],
  },
  "plot-power": {
    y: "power (W)",
    traces: [
      ["spindle_power_w", line("measured", "#f0883e")],
      ["power_predicted_w", line("predicted", "#58a6ff")],
    ],
  },
  "plot-mrr": {
    y: "MRR (mm³/s)",
    traces: [["mrr_mm3_s", line("MRR", "#a371f7")]],
  },
  "plot-override": {
    y: "override (%)",
    traces: [
      ["feed_override_pct", line("feed", "#3fb950")],
      ["spindle_override_pct", line("spindle", "#d29922")],
    ],
  },
  "plot-form": {
    y: "form error (µm)",
    traces: [
      ["form_error_tolerance_um", line("tolerance", "#f85149", { line: { color: "#f85149", dash: "dash", width: 1 } })],
      ["form_error_um", line("predicted", "#58a6ff")],
    ],
  },
};

function columns(series, name) {
  // x (machine time) and y of one series, leaving out samples without a time
  const t = series.t_s || [], v = series[name] || [];
  const x = [], y = [];
  for (let i = 0; i < t.length; i++) {
    if (t[i] === null) continue;
    x.push(t[i]); y.push(v[i] === undefined ? null : v[i]);
  }
  return [x, y];
}

function drawPlots(series) {
  for (const [id, plot] of Object.entries(PLOTS)) {
    const traces = plot.traces.map(([name, trace]) => {
      const [x, y] = columns(series, name);
      return { ...trace, x: x.slice(-MAX_POINTS), y: y.slice(-MAX_POINTS) };
    });
    const layout = { ...LAYOUT, yaxis: { ...LAYOUT.yaxis, title: { text: plot.y } } };
    Plotly.react(id, traces, layout, CONFIG);
  }
}

function extendPlots(series) {
  if (!series.t_s || series.t_s.length === 0) return;
  for (const [id, plot] of Object.entries(PLOTS)) {
    const xs = [], ys = [];
    for (const [name] of plot.traces) {
      const [x, y] = columns(series, name);
      xs.push(x); ys.push(y);
    }
    Plotly.extendTraces(id, { x: xs, y: ys }, plot.traces.map((_, i) => i), MAX_POINTS);
  }
}

// ------------------------------------------------------------------ panels
function setText(id, text) {
  const el = $(id);
  if (el && el.textContent !== text) el.textContent = text;
}

function showSnapshot(s) {
  live.snapshot = s;
  const m = s.measured || {}, p = s.predicted || {};
  const conn = $("conn");
  if (s.connected === undefined) {
    conn.textContent = "waiting for the twin"; conn.className = "badge warn";
  } else if (s.connected) {
    conn.textContent = "machine connected"; conn.className = "badge ok";
  } else {
    conn.textContent = "machine lost"; conn.className = "badge bad";
  }
  setText("v-run_state", s.run_state || "-");
  setText("v-cycle", s.cycles === undefined ? "-" : String(s.cycles));
  setText("v-timing", s.cycle_p50_ms === undefined ? "-"
    : `${fmt(s.cycle_p50_ms, 2)} / ${fmt(s.cycle_p99_ms, 2)} ms`);
  setText("v-overruns", s.overruns === undefined ? "-" : String(s.overruns));
  if (s.ended) {
    const ended = $("ended");
    ended.hidden = false; ended.textContent = `run ended: ${s.ended}`;
    ended.className = "badge " + (s.ended === "finished" ? "ok" : "warn");
  }
  setText("v-force_measured_n", fmt(p.measured_force_xy_n));
  setText("v-force_predicted_n", fmt(p.predicted_force_xy_n));
  setText("v-force_band", p.force_band_low_n === undefined ? "-"
    : `${fmt(p.force_band_low_n, 0)} .. ${fmt(p.force_band_high_n, 0)}`);
  setText("v-force_out", p.force_out_of_band === undefined ? "-"
    : (p.force_out_of_band >= 0.5 ? "YES" : "no"));
  $("v-force_out").parentElement.classList.toggle("alarm", p.force_out_of_band >= 0.5);
  setText("v-spindle_rpm", fmt(m.spindle_rpm, 0));
  setText("v-spindle_torque_nm", fmt(m.spindle_torque_nm, 2));
  setText("v-spindle_power_w", fmt(m.spindle_power_w, 0));
  setText("v-spindle_current_a", fmt(m.spindle_current_a, 2));
  setText("v-ae_mm", fmt(p.ae_mm, 2));
  setText("v-ap_mm", fmt(p.ap_mm, 2));
  setText("v-mrr_mm3_s", fmt(p.mrr_mm3_s, 0));
  setText("v-feed_mm_min", fmt(m.feed_mm_min, 0));
  setText("v-feed_override_pct", fmt(m.feed_override_pct, 0));
  setText("v-spindle_override_pct", fmt(m.spindle_override_pct, 0));
  setText("v-form_error_um", fmt(p.form_error_um, 1));
  setText("v-form_error_tolerance_um", fmt(p.form_error_tolerance_um, 0));
  $("v-form_error_um").parentElement.classList.toggle("alarm", p.form_error_out >= 0.5);
  setText("v-line", s.line === undefined ? "-" : String(s.line));
  setText("v-tool", s.tool === undefined ? "-" : `T${s.tool}`);
  const pos = s.position_mm;
  setText("v-position", pos ? `tool tip X ${fmt(pos[0], 2)}  Y ${fmt(pos[1], 2)}  Z ${fmt(pos[2], 2)} mm` : "-");
  showProgramLine(s.line);
  showConnection(s);
  showPredictions(p);
}

let programLine = -1;
function showProgram(info) {
  const pre = $("program");
  pre.replaceChildren();
  info.program.forEach((text, i) => {
    const div = document.createElement("div");
    div.textContent = `${String(i + 1).padStart(4)}  ${text}`;
    pre.appendChild(div);
  });
  setText("program-name", info.program_name);
}

function showProgramLine(lineNo) {
  if (lineNo === programLine || lineNo === undefined) return;
  const rows = $("program").children;
  if (programLine > 0 && rows[programLine - 1]) rows[programLine - 1].classList.remove("current");
  programLine = lineNo;
  const row = rows[lineNo - 1];
  if (row) {
    row.classList.add("current");
    const pre = $("program");
    pre.scrollTop = Math.max(row.offsetTop - pre.offsetTop - pre.clientHeight / 2, 0);
  }
}

function fillTable(table, rows) {
  // rows: [name, text]; rewrites only the cells that changed
  while (table.rows.length > rows.length) table.deleteRow(-1);
  rows.forEach(([name, text], i) => {
    const row = table.rows[i] || table.insertRow();
    while (row.cells.length < 2) row.insertCell();
    if (row.cells[0].textContent !== name) row.cells[0].textContent = name;
    if (row.cells[1].textContent !== text) row.cells[1].textContent = text;
  });
}

function showConnection(s) {
  const rejected = Object.entries(s.rejected || {}).map(([k, v]) => `${k}: ${v}`).join("; ");
  fillTable($("connection"), [
    ["machine", s.connected === undefined ? "-" : (s.connected ? "connected" : "lost")],
    ["this cycle's reading", s.reading === undefined ? "-" : (s.reading ? (s.stale ? "stale" : "fresh") : "failed")],
    ["sample age", s.sample_age_s === undefined ? "-" : `${fmt(s.sample_age_s * 1e3, 1)} ms`],
    ["rejected signals", rejected || "none"],
    ["cycle period", s.cycle_s === undefined ? "-" : `${fmt(s.cycle_s * 1e3, 1)} ms`],
    ["stop", s.stop_outcome || "-"],
    ["cycles dropped by the feed", String(s.feed_dropped)],
    ["pages open / dropped", `${s.pages} / ${s.pages_dropped}`],
  ]);
}

// the predictions that go with a band or a limit, and how the page names them
const BANDS = {
  predicted_force_xy_n: ["force_band_low_n", "force_band_high_n"],
  form_error_um: [null, "form_error_tolerance_um"],
};
function showPredictions(p) {
  const rows = [];
  for (const [name, value] of Object.entries(p)) {
    let text = fmt(value, 3);
    const band = BANDS[name];
    if (band) {
      const low = band[0] ? fmt(p[band[0]], 1) : "";
      text += `  [${low} .. ${fmt(p[band[1]], 1)}]`;
    }
    rows.push([name, text]);
  }
  fillTable($("predictions"), rows);
}

function addTimeline(items) {
  const body = $("timeline").tBodies[0];
  for (const item of items) {
    live.timeline.push(item);
    const row = body.insertRow(0);
    if (item.who === "dashboard") row.classList.add("dashboard");
    if (item.what === "stop" || item.what === "stop_confirmed") row.classList.add("stop");
    const values = Object.entries(item.values || {})
      .map(([k, v]) => `${k}=${typeof v === "number" ? Number(v.toPrecision(4)) : v}`).join(" ");
    const value = item.value === undefined || item.value === null ? "" : fmt(item.value, 1);
    for (const text of [fmt(item.t_s, 2), item.who, item.what, value, item.outcome, values, item.reason]) {
      row.insertCell().textContent = text;
    }
  }
  while (body.rows.length > MAX_TIMELINE) body.deleteRow(-1);
  live.timeline.splice(0, Math.max(live.timeline.length - MAX_TIMELINE, 0));
}

// ------------------------------------------------------------------ 3D stock
function showStock(stock) {
  // CnctwinStock: static/stock.js (the 3D view shared with the run pages); a promise
  if (!stock || typeof CnctwinStock === "undefined") return null;
  live.stockUpdates += 1;
  return CnctwinStock.draw($("stock3d"), stock);
}

// ------------------------------------------------------------------ control
function setupControl(info) {
  $("control").hidden = !info.control_enabled;
  $("control-off").hidden = info.control_enabled;
  $("token").value = sessionStorage.getItem("cnctwin_token") || "";
}

async function command(body) {
  const token = $("token").value.trim();
  sessionStorage.setItem("cnctwin_token", token);
  const status = $("control-status");
  status.textContent = "sending ...";
  try {
    const response = await fetch("api/control", {
      method: "POST",
      headers: { "Content-Type": "application/json", Authorization: `Bearer ${token}` },
      body: JSON.stringify(body),
    });
    const answer = await response.json();
    status.textContent = response.ok
      ? `queued for the next cycle: ${answer.queued.reason} (see the timeline)`
      : `refused (${response.status}): ${answer.error}`;
  } catch (err) {
    status.textContent = `not sent: ${err}`;
  }
}
$("btn-feed").addEventListener("click", () =>
  command({ command: "feed_override", value: Number($("feed-value").value) }));
$("btn-stop").addEventListener("click", () => command({ command: "stop" }));

// ------------------------------------------------------------------ stream
// Messages are only merged when they arrive; the page draws at most once per animation
// frame: the values every frame, the plots at most every PLOT_MS and the 3D view at most every
// STOCK_MS, each less often when its last drawing took long, so that drawing keeps at most
// about DRAW_SHARE of the page's time and a slow computer (a software-rendered browser) stays
// responsive and never falls behind the stream.
const PLOT_MS = 250;
const STOCK_MS = 500;
const DRAW_SHARE = 0.25;
let pending = null;           // what arrived since the last drawing
let plotsDue = 0;             // performance.now() from which the plots may be drawn again
let stockDue = 0;
let stockBusy = false;

function merge(into, message) {
  for (const [name, values] of Object.entries(message.series || {})) {
    const column = (into.series[name] = (into.series[name] || []).concat(values));
    if (column.length > MAX_POINTS) column.splice(0, column.length - MAX_POINTS);
  }
  into.timeline.push(...(message.timeline || []));
  into.snapshot = message.snapshot;
  if (message.stock) into.stock = message.stock;
}

function draw(now) {
  requestAnimationFrame(draw);
  if (pending === null) return;
  const update = pending;
  if (now >= plotsDue && Object.keys(update.series).length) {
    const started = performance.now();
    extendPlots(update.series);
    update.series = {};
    live.plotMs = performance.now() - started;
    plotsDue = now + Math.max(PLOT_MS, live.plotMs / DRAW_SHARE);
  }
  if (update.timeline.length) addTimeline(update.timeline);
  update.timeline = [];
  if (update.snapshot) showSnapshot(update.snapshot);
  update.snapshot = null;
  if (update.stock && !stockBusy && now >= stockDue) {
    stockBusy = true;
    const stock = update.stock, started = performance.now();
    update.stock = null;
    Promise.resolve(showStock(stock)).finally(() => {
      live.stockMs = performance.now() - started;
      stockDue = performance.now() + Math.max(STOCK_MS, live.stockMs / DRAW_SHARE);
      stockBusy = false;
    });
  }
  const empty = !update.stock && Object.keys(update.series).length === 0;
  pending = empty ? null : update;
  live.draws += 1;
}

function handle(message) {
  live.messages += 1;
  const now = performance.now();
  live.arrivals.push(now);
  while (live.arrivals.length > 2 && now - live.arrivals[0] > 10000) live.arrivals.shift();
  setText("v-rate", fmt(live.rateHz(), 1));
  const snap = message.snapshot || {};
  if (message.type === "update" && snap.run_state === "running" && !snap.ended) {
    if (live.run.count === 0) live.run.first = now;
    live.run.count += 1; live.run.last = now;
  }
  if (message.type === "hello") {
    live.info = message.info;
    setText("title", `cnctwin live: ${message.info.title}`);
    document.title = `cnctwin live: ${message.info.title}`;
    showProgram(message.info);
    programLine = -1;
    setupControl(message.info);
    drawPlots(message.series);
    $("timeline").tBodies[0].replaceChildren();
    live.timeline = [];
    pending = null;
    addTimeline(message.timeline);
    showSnapshot(message.snapshot);
    showStock(message.stock);
    return;
  }
  if (pending === null) pending = { series: {}, timeline: [], snapshot: null, stock: null };
  merge(pending, message);
}

requestAnimationFrame(draw);
const source = new EventSource("api/stream");
source.onmessage = (event) => handle(JSON.parse(event.data));
source.onerror = () => {
  const conn = $("conn");
  conn.textContent = "dashboard disconnected (retrying)"; conn.className = "badge bad";
};
