// The 3D stock view: the height map of cnctwin.web.stock.stock_view as a plotly surface,
// the tool as a cylinder at its position. Rotate by dragging, zoom with the wheel; later
// updates keep the camera (uirevision).
"use strict";

const CnctwinStock = (() => {
  const SEGMENTS = 24;

  // A closed cylinder (mesh3d) from the tool tip up its flute length.
  function toolTrace(tool) {
    if (tool.radius_mm <= 0 || tool.length_mm <= 0) {
      return {type: "scatter3d", mode: "markers", x: [tool.x_mm], y: [tool.y_mm],
              z: [tool.z_mm], marker: {size: 4, color: "#d62728"}, name: "tool",
              hoverinfo: "skip"};
    }
    const x = [], y = [], z = [], i = [], j = [], k = [];
    for (let s = 0; s < SEGMENTS; s++) {
      const a = 2 * Math.PI * s / SEGMENTS;
      const cx = tool.x_mm + tool.radius_mm * Math.cos(a);
      const cy = tool.y_mm + tool.radius_mm * Math.sin(a);
      x.push(cx, cx); y.push(cy, cy); z.push(tool.z_mm, tool.z_mm + tool.length_mm);
    }
    const bottom = x.length, top = x.length + 1;
    x.push(tool.x_mm, tool.x_mm); y.push(tool.y_mm, tool.y_mm);
    z.push(tool.z_mm, tool.z_mm + tool.length_mm);
    for (let s = 0; s < SEGMENTS; s++) {
      const a0 = 2 * s, a1 = a0 + 1, b0 = (2 * s + 2) % (2 * SEGMENTS), b1 = b0 + 1;
      i.push(a0, a1, a0, a1); j.push(b0, b0, b0, b1); k.push(a1, b1, bottom, top);
    }
    return {type: "mesh3d", x, y, z, i, j, k, color: "#d62728", opacity: 0.85,
            flatshading: true, name: "tool", hoverinfo: "skip"};
  }

  // The colour scale's [min, max], mm: the stock's tops from the lowest to the highest, so a
  // cut shows in full colour however shallow it is against the block; an uncut top (one
  // height) is the top colour of a 1 mm scale.
  function colourRange(view) {
    const [low, high] = view.box_mm;
    const [lo, hi] = view.z_range_mm || [low[2], high[2]];
    return hi - lo > 1e-3 ? [lo, hi] : [hi - 1, hi];
  }

  // Draw (or update) the view in `element` from one stock_view object.
  function draw(element, view) {
    const [low, high] = view.box_mm;
    const [cmin, cmax] = colourRange(view);
    const traces = [{
      type: "surface", x: view.x_mm, y: view.y_mm, z: view.z_mm, colorscale: "Viridis",
      cmin, cmax, showscale: true, name: "stock",
      colorbar: {title: {text: "top [mm]"}, thickness: 12, len: 0.6},
      hovertemplate: "x %{x:.2f} y %{y:.2f} top %{z:.3f} mm<extra></extra>",
    }];
    if (view.tool) traces.push(toolTrace(view.tool));
    const top = view.tool ? Math.max(high[2], view.tool.z_mm + view.tool.length_mm) : high[2];
    const layout = {
      uirevision: "stock", margin: {l: 0, r: 0, t: 0, b: 0}, showlegend: false,
      scene: {
        aspectmode: "data",
        xaxis: {title: {text: "x [mm]"}, range: [low[0], high[0]]},
        yaxis: {title: {text: "y [mm]"}, range: [low[1], high[1]]},
        zaxis: {title: {text: "z [mm]"}, range: [low[2], top]},
      },
    };
    return Plotly.react(element, traces, layout, {displaylogo: false, responsive: true});
  }

  return {draw, colourRange};
})();
