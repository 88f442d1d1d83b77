// A small line plot on a <canvas>, written for the run browser (cnctwin.web.runs): it draws
// the first view of a run at once, while plotly.js (4.6 MB) is still to be loaded and
// compiled for zooming. Lines only: x and y axes with ticks, one line per trace, a break in
// the line at each null (a gap). No interaction.
"use strict";

const LinePlot = (() => {
  const COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728"];
  const MARGIN = {l: 60, r: 20, t: 10, b: 40};  // as the plotly layout of runs.js

  // About `count` round tick values covering [lo, hi].
  function ticks(lo, hi, count) {
    if (!(hi > lo)) return [lo];
    const raw = (hi - lo) / count;
    const power = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map((m) => m * power).find((s) => s >= raw);
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) {
      out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    }
    return out;
  }

  function label(v) {
    return Math.abs(v) >= 1e5 || (Math.abs(v) < 1e-3 && v !== 0) ?
      v.toExponential(1) : String(Number(v.toPrecision(6)));
  }

  // Draw traces [{x: [...], y: [... or null]}] into `element` (a <canvas> is made in it).
  function draw(element, traces, titles) {
    let canvas = element.querySelector("canvas.lineplot");
    if (!canvas) {
      canvas = document.createElement("canvas");
      canvas.className = "lineplot";
      element.replaceChildren(canvas);
    }
    const width = element.clientWidth, height = element.clientHeight;
    const ratio = window.devicePixelRatio || 1;
    canvas.width = Math.round(width * ratio);
    canvas.height = Math.round(height * ratio);
    canvas.style.width = width + "px";
    canvas.style.height = height + "px";
    const ctx = canvas.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.clearRect(0, 0, width, height);
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (const tr of traces) {
      for (let i = 0; i < tr.x.length; i++) {
        x0 = Math.min(x0, tr.x[i]); x1 = Math.max(x1, tr.x[i]);
        const y = tr.y[i];
        if (y !== null) { y0 = Math.min(y0, y); y1 = Math.max(y1, y); }
      }
    }
    if (!(x1 >= x0)) { x0 = 0; x1 = 1; }
    if (!(y1 >= y0)) { y0 = 0; y1 = 1; }
    if (x1 === x0) { x0 -= 0.5; x1 += 0.5; }
    const pad = (y1 - y0) * 0.05 || 0.5;
    y0 -= pad; y1 += pad;
    const w = width - MARGIN.l - MARGIN.r, h = height - MARGIN.t - MARGIN.b;
    const px = (x) => MARGIN.l + (x - x0) / (x1 - x0) * w;
    const py = (y) => MARGIN.t + (y1 - y) / (y1 - y0) * h;
    ctx.font = "12px system-ui, sans-serif";
    ctx.fillStyle = "#444";
    ctx.strokeStyle = "#eee";
    ctx.lineWidth = 1;
    ctx.textAlign = "center";
    ctx.textBaseline = "top";
    for (const v of ticks(x0, x1, Math.max(2, Math.floor(w / 90)))) {
      ctx.beginPath(); ctx.moveTo(px(v), MARGIN.t); ctx.lineTo(px(v), MARGIN.t + h); ctx.stroke();
      ctx.fillText(label(v), px(v), MARGIN.t + h + 4);
    }
    ctx.textAlign = "right";
    ctx.textBaseline = "middle";
    for (const v of ticks(y0, y1, Math.max(2, Math.floor(h / 50)))) {
      ctx.beginPath(); ctx.moveTo(MARGIN.l, py(v)); ctx.lineTo(MARGIN.l + w, py(v)); ctx.stroke();
      ctx.fillText(label(v), MARGIN.l - 4, py(v));
    }
    ctx.textAlign = "center";
    ctx.textBaseline = "bottom";
    ctx.fillText(titles.x, MARGIN.l + w / 2, height - 2);
    ctx.save();
    ctx.translate(12, MARGIN.t + h / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.textBaseline = "middle";
    ctx.fillText(titles.y, 0, 0);
    ctx.restore();
    ctx.save();
    ctx.beginPath();
    ctx.rect(MARGIN.l, MARGIN.t, w, h);
    ctx.clip();
    ctx.lineWidth = 1.5;
    traces.forEach((tr, k) => {
      ctx.strokeStyle = COLORS[k % COLORS.length];
      ctx.beginPath();
      let pen = false;
      ctx.fillStyle = ctx.strokeStyle;
      for (let i = 0; i < tr.x.length; i++) {
        if (tr.y[i] === null) { pen = false; continue; }
        const X = px(tr.x[i]), Y = py(tr.y[i]);
        if (pen) ctx.lineTo(X, Y); else ctx.moveTo(X, Y);
        const alone = !pen && (i + 1 === tr.x.length || tr.y[i + 1] === null);
        if (alone) ctx.fillRect(X - 1.5, Y - 1.5, 3, 3);  // a sample between two gaps
        pen = true;
      }
      ctx.stroke();
    });
    ctx.restore();
    return canvas;
  }

  return {draw, ticks};
})();
