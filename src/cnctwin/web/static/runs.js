// The run browser (cnctwin.web.runs): list the historian's runs, open one, plot a signal
// over the whole run and zoom into it. The server sends min/max per pixel bucket of the
// window asked for; every zoom asks again for the new window at the plot's width.
"use strict";

const Runs = (() => {
  const PREFERRED = ["force_x_n", "spindle_power_w", "spindle_torque_nm"];
  const state = {runs: [], run: null, signal: null, overlay: null, window: null, request: 0,
                 loads: 0, openedMs: null, opening: null};
  const $ = (id) => document.getElementById(id);
  // plotly.js (4.6 MB, about a second to compile on a slow machine) is not loaded with the
  // page: a run's first view is drawn on a canvas (lineplot.js) as soon as its points
  // arrive, then plotly.js is loaded and draws the same points again, zoomable.
  let plotlyLoading = null;
  function loadPlotly() {
    if (!plotlyLoading) {
      plotlyLoading = new Promise((resolve, reject) => {
        if (window.Plotly) { resolve(); return; }
        const script = document.createElement("script");
        script.src = "static/plotly.min.js";
        script.addEventListener("load", () => {
          $("plot").dataset.plotlyReadyMs = performance.now().toFixed(1);  // compiled, run
          resolve();
        });
        script.addEventListener("error", () => reject(new Error("plotly.js did not load")));
        document.head.appendChild(script);
      });
    }
    return plotlyLoading;
  }

  async function getJSON(url) {
    const response = await fetch(url, {credentials: "same-origin"});
    const body = await response.json();
    if (!response.ok) throw new Error(body.error || body.detail || response.statusText);
    return body;
  }

  function cell(row, text, numeric) {
    const td = row.insertCell();
    td.textContent = text;
    if (numeric) td.className = "n";
  }

  // A program's file name without its folders ("" for none).
  const baseName = (path) => (path ? String(path).split(/[\\/]/).pop() : "");

  const fmt = (v, digits) => (v === null || v === undefined) ? "-" : v.toFixed(digits);

  async function loadList() {
    const data = await getJSON("api/runs");
    state.runs = data.runs;
    $("database").textContent = data.database;
    const body = $("runs").tBodies[0];
    body.replaceChildren();
    const overlay = $("overlay");
    overlay.replaceChildren(new Option("none", ""));
    for (const run of data.runs.slice().reverse()) {
      const row = body.insertRow();
      row.dataset.run = run.run_id;
      cell(row, run.run_id, true);
      cell(row, run.machine || "-");
      cell(row, baseName(run.program) || "-");
      row.cells[2].title = run.program || "";  // the whole path on hover
      cell(row, new Date(run.started_at * 1000).toLocaleString());
      cell(row, fmt(run.duration_s, 1), true);
      cell(row, run.status);
      row.addEventListener("click", () => openRun(run.run_id));
      overlay.add(new Option(`${run.run_id}: ${baseName(run.program) || run.machine || ""}`,
                             String(run.run_id)));
    }
    highlight();
  }

  // Mark the run being opened in the list.
  function highlight() {
    for (const row of $("runs").tBodies[0].rows) {
      row.classList.toggle("open", row.dataset.run === String(state.opening));
    }
  }

  function signalChoices(detail) {
    const select = $("signal");
    select.replaceChildren();
    for (const name of detail.signals) select.add(new Option(name, "measured:" + name));
    for (const name of detail.predicted) {
      select.add(new Option("predicted " + name, "predicted:" + name));
    }
    const first = PREFERRED.find((name) => detail.signals.includes(name));
    if (first) select.value = "measured:" + first;
    return select.value;
  }

  function fillLog(table, rows, columns) {
    const body = $(table).tBodies[0];
    body.replaceChildren();
    for (const item of rows) {
      const row = body.insertRow();
      columns.forEach((c) => cell(row, c(item)));
    }
  }

  async function openRun(runId) {
    const started = performance.now();
    $("view-error").textContent = "";
    state.opening = runId;
    highlight();
    $("view").hidden = false;  // laid out now: the plot's width is the buckets asked for
    try {
      const choice = new URLSearchParams(location.hash.slice(1)).get("signal");
      // The signal the address names is asked for with the run, not after it.
      const early = choice ? fetchTrace(runId, choice, null, null) : null;
      early?.catch(() => {});
      const detail = await getJSON(`api/runs/${runId}`);
      state.run = detail;
      state.overlay = null;
      state.window = null;
      $("overlay").value = "";
      $("title").textContent = `run ${detail.run_id}: ` +
        `${baseName((detail.meta || {}).program) || "-"} on ` +
        `${detail.machine || "-"}, ${detail.status}, ${fmt(detail.duration_s, 1)} s, ` +
        `${detail.frames.toLocaleString()} instants`;
      $("export-csv").href = `api/runs/${runId}/export?format=csv`;
      $("export-parquet").href = `api/runs/${runId}/export?format=parquet`;
      fillLog("events", detail.event_log, [(e) => e.t_s.toFixed(3), (e) => e.kind,
                                           (e) => e.message]);
      fillLog("decisions", detail.decision_log, [(d) => d.t_s.toFixed(3), (d) => d.rule,
        (d) => d.action, (d) => String(d.value), (d) => d.accepted ? "yes" : "no",
        (d) => d.readback === null ? "-" : String(d.readback), (d) => d.reason]);
      let value = signalChoices(detail);
      if (choice && [...$("signal").options].some((o) => o.value === choice)) {
        $("signal").value = value = choice;
      }
      state.signal = value;
      history.replaceState(null, "", `#run=${runId}&signal=${encodeURIComponent(value)}`);
      if (value) await plot(true, value === choice ? early : null);
      state.openedMs = performance.now() - started;
      $("plot").dataset.openedMs = state.openedMs.toFixed(1);
    } catch (err) {
      $("view-error").textContent = String(err.message || err);
    }
  }

  async function fetchTrace(runId, signal, t0, t1) {
    const [kind, name] = signal.split(/:(.*)/s);
    const width = Math.max(100, Math.round($("plot").clientWidth));
    let url = `api/runs/${runId}/signal?name=${encodeURIComponent(name)}&kind=${kind}` +
              `&buckets=${width}`;
    if (t0 !== null) url += `&t0=${t0}&t1=${t1}`;
    return getJSON(url);
  }

  // Draw the signal (and the overlay run's) in the current window; fresh: a new plot;
  // early: the main trace's answer when already asked for.
  async function plot(fresh, early) {
    const request = ++state.request;
    const [t0, t1] = state.window || [null, null];
    const runs = [state.run.run_id];
    if (state.overlay !== null) runs.push(state.overlay);
    const traces = await Promise.all(runs.map((id, k) =>
      (k === 0 && early) ? early : fetchTrace(id, state.signal, t0, t1)));
    if (request !== state.request) return;  // a newer zoom superseded this one
    const [kind, name] = state.signal.split(/:(.*)/s);
    const data = traces.map((tr) => ({
      type: "scatter", mode: tr.raw ? "lines+markers" : "lines", x: tr.t, y: tr.y,
      name: `run ${tr.run_id}`, connectgaps: false, marker: {size: 3},
    }));
    const layout = {
      margin: {l: 60, r: 20, t: 10, b: 40}, uirevision: fresh ? Math.random() : "keep",
      xaxis: {title: {text: "time since start [s]"}},
      yaxis: {title: {text: (kind === "predicted" ? "predicted " : "") + name}},
      showlegend: traces.length > 1,
    };
    if (state.window) layout.xaxis.range = state.window;
    const element = $("plot");
    if (!window.Plotly) {
      const quick = $("quick");
      quick.hidden = false;
      LinePlot.draw(quick, data, {x: layout.xaxis.title.text, y: layout.yaxis.title.text});
      element.dataset.quick = String(traces[0].t.length);
      element.dataset.firstDrawnMs = performance.now().toFixed(1);
      // Let the canvas reach the screen before plotly.js takes the main thread.
      await new Promise((resolve) => requestAnimationFrame(() => setTimeout(resolve, 0)));
    }
    await loadPlotly();
    if (request !== state.request) return;
    await Plotly.react(element, data, layout, {displaylogo: false, responsive: true});
    $("quick").hidden = true;
    if (fresh || !element.dataset.bound) bindZoom(element);
    const main = traces[0];
    element.dataset.points = String(main.t.length);
    element.dataset.samples = String(main.samples);
    element.dataset.raw = String(main.raw);
    element.dataset.t0 = String(main.t0);
    element.dataset.t1 = String(main.t1);
    element.dataset.traces = String(traces.length);
    element.dataset.loads = String(++state.loads);
    $("status").textContent = `${main.samples.toLocaleString()} samples in ` +
      `${main.t0.toFixed(3)}-${main.t1.toFixed(3)} s shown as ${main.t.length} points` +
      (main.raw ? " (every sample)" : " (min/max per pixel)") +
      "; drag to zoom, double-click for the whole run.";
  }

  function bindZoom(element) {
    if (element.dataset.bound) return;
    element.dataset.bound = "1";
    element.on("plotly_relayout", (event) => {
      if (event["xaxis.autorange"]) {
        state.window = null;
      } else if ("xaxis.range[0]" in event) {
        state.window = [event["xaxis.range[0]"], event["xaxis.range[1]"]];
      } else if (Array.isArray(event["xaxis.range"])) {
        state.window = event["xaxis.range"].slice();
      } else {
        return;
      }
      plot(false).catch((err) => { $("view-error").textContent = String(err.message || err); });
    });
  }

  // Zoom to [t0, t1] s (what a drag on the plot does); for scripts and tests.
  async function zoom(t0, t1) {
    await loadPlotly();
    return Plotly.relayout($("plot"), {"xaxis.range": [t0, t1]});
  }

  function start() {
    $("signal").addEventListener("change", (e) => {
      state.signal = e.target.value;
      history.replaceState(null, "",
        `#run=${state.run.run_id}&signal=${encodeURIComponent(state.signal)}`);
      plot(false);
    });
    $("overlay").addEventListener("change", (e) => {
      state.overlay = e.target.value === "" ? null : Number(e.target.value);
      plot(false).catch((err) => { $("view-error").textContent = String(err.message || err); });
    });
    $("reset").addEventListener("click", () => {
      state.window = null;
      plot(true);
    });
    // A run the address names is opened while the list loads.
    loadList().catch((err) => { $("list-error").textContent = String(err.message || err); });
    const wanted = new URLSearchParams(location.hash.slice(1)).get("run");
    if (wanted) openRun(Number(wanted));
  }

  return {start, openRun, zoom, state};
})();

Runs.start();
