"use strict";
// The loop page's analysis charts (model history, K against fuel temperature, gains over time),
// drawn with plotly.js. Loaded only when the charts are scrolled into view: the first view of the
// page (chips, live trend, proposals) does not wait for plotly.js (its basic bundle, 1.2 MB;
// loop.js loads both).
// Reads LOOP, TZ and PLOT_CONFIG (loop.js, common.js) and the page's newest sample (trendNewest).

function ci(w, key) {
  const m = (w.model || {})[key];
  const c = (w.ci95 || {})[key];
  if (m === undefined || m === null || !c) return [null, null];
  return [c[1] - m, m - c[0]];
}

function drawModels(history) {
  const accepted = history.windows.filter((w) => w.accepted && w.model);
  const rejected = history.windows.filter((w) => !w.accepted);
  const x = toZone(TZ, accepted.map((w) => w.end));
  const traces = [];
  [["K", "y", "K [(L/min)/V]"], ["T", "y2", "T [s]"], ["delay", "y3", "delay [s]"]].forEach(([key, axis, name]) => {
    traces.push({
      type: "scatter", mode: "markers+lines", name, yaxis: axis, x, y: accepted.map((w) => w.model[key]),
      customdata: accepted.map((w) => w.id), hovertemplate: `window %{customdata}: ${name} %{y:.4g}<extra></extra>`,
      error_y: { type: "data", symmetric: false, array: accepted.map((w) => ci(w, key)[0]), arrayminus: accepted.map((w) => ci(w, key)[1]), thickness: 1 },
    });
  });
  let lastK = accepted.length ? accepted[0].model.K : null;
  const rejectedK = [];
  for (const w of history.windows) {
    if (w.accepted && w.model) lastK = w.model.K; else if (!w.accepted) rejectedK.push(w.model && w.model.K ? w.model.K : lastK);
  }
  traces.push({
    type: "scatter", mode: "markers", name: "rejected window", yaxis: "y", x: toZone(TZ, rejected.map((w) => w.end)), y: rejectedK,
    marker: { symbol: "x", color: "#c62828", size: 9 }, customdata: rejected.map((w) => w.id),
    text: rejected.map((w) => w.reason), hovertemplate: "window %{customdata} rejected: %{text}<extra></extra>",
  });
  const layout = {
    margin: { t: 20, r: 20, b: 40, l: 70 }, legend: { orientation: "h", y: 1.08 }, xaxis: { type: "date", anchor: "y3" },
    yaxis: { domain: [0.68, 1], title: { text: "K [(L/min)/V]" } }, yaxis2: { domain: [0.35, 0.65], title: { text: "T [s]" } },
    yaxis3: { domain: [0, 0.32], title: { text: "delay [s]" } },
  };
  const div = document.getElementById("models");
  Plotly.react(div, traces, layout, PLOT_CONFIG).then(() => {
    div.removeAllListeners && div.removeAllListeners("plotly_click");
    div.on("plotly_click", (event) => {
      const id = event.points && event.points[0] && event.points[0].customdata;
      if (id !== undefined) window.location.href = `/loops/${encodeURIComponent(LOOP)}/windows/${id}`;
    });
  });
}

function drawKTemperature(history) {
  const accepted = history.windows.filter((w) => w.accepted && w.model && w.fuel_temperature !== null);
  const sorted = [...accepted].sort((a, b) => a.fuel_temperature - b.fuel_temperature);
  const traces = [{
    type: "scatter", mode: "markers", name: "K of a window (95 %)", x: accepted.map((w) => w.fuel_temperature), y: accepted.map((w) => w.model.K),
    error_y: { type: "data", symmetric: false, array: accepted.map((w) => ci(w, "K")[0]), arrayminus: accepted.map((w) => ci(w, "K")[1]), thickness: 1 },
    customdata: accepted.map((w) => w.id), hovertemplate: "window %{customdata}: K %{y:.4g} at %{x:.1f} °C<extra></extra>",
  }];
  const withPlant = sorted.filter((w) => w.plant_K !== null && w.plant_K !== undefined);
  if (withPlant.length) {
    traces.push({ type: "scatter", mode: "markers", name: "the plant file's K", x: withPlant.map((w) => w.fuel_temperature), y: withPlant.map((w) => w.plant_K), marker: { symbol: "x-thin-open", size: 8, color: "#777" } });
  }
  const trend = history.k_trend || {};
  const ratio = trend.ratio;
  if (trend.available && ratio && withPlant.length) {
    const slope = ratio.slope || 0;
    traces.push({
      type: "scatter", mode: "markers", name: "tracked K(T) at each window's flow", marker: { symbol: "circle-open", size: 9, color: "#2e7d32" },
      x: withPlant.map((w) => w.fuel_temperature), y: withPlant.map((w) => w.plant_K * (ratio.intercept + slope * (w.fuel_temperature - ratio.T_ref))),
    });
  }
  const layout = { margin: { t: 20, r: 20, b: 50, l: 70 }, legend: { orientation: "h", y: 1.12 }, xaxis: { title: { text: "fuel temperature [°C]" } }, yaxis: { title: { text: "K [(L/min)/V]" } } };
  Plotly.react("ktemp", traces, layout, PLOT_CONFIG);
}

// the gains in force over time: each proposal's "old" gains held until the next verified write
function gainsInForce(history) {
  const points = [];
  for (const p of history.proposals) if (p.old && p.old.Kc !== undefined) points.push([p.time, p.old.Kc, p.old.Ti]);
  for (const w of history.writes) if (w.status === "verified") points.push([w.time, w.Kc, w.Ti]);
  points.sort((a, b) => a[0] - b[0]);
  const box = document.getElementById("gains").dataset;
  const first = history.windows.length ? history.windows[0].start : null;
  if (points.length && first !== null && first < points[0][0]) {
    points.unshift([first, points[0][1], points[0][2]]); // the first proposal's "old": since the start
  }
  if (!points.length && box.kc !== "" && box.ti !== "" && first !== null) {
    points.push([first, Number(box.kc), Number(box.ti)]); // no proposal, no write: as commissioned
  }
  const last = points.length ? trendNewest() : null;
  if (points.length && last !== null && last > points[points.length - 1][0]) {
    const end = points[points.length - 1];
    points.push([last, end[1], end[2]]);
  }
  return points;
}

function drawGains(history) {
  const units = history.gain_units || history.gains_units || {};
  const inForce = gainsInForce(history);
  const traces = [];
  [["Kc", "y", 1], ["Ti", "y2", 2]].forEach(([key, axis, column]) => {
    traces.push({ type: "scatter", mode: "lines", line: { shape: "hv", color: "#263238" }, name: `${key} in force`, yaxis: axis, x: toZone(TZ, inForce.map((p) => p[0])), y: inForce.map((p) => p[column]), hovertemplate: `${key} %{y:.4g}<extra></extra>` });
    traces.push({ type: "scatter", mode: "markers", name: `${key} proposed`, yaxis: axis, x: toZone(TZ, history.proposals.map((p) => p.time)), y: history.proposals.map((p) => (p.new || {})[key]), marker: { symbol: "diamond", size: 9, color: "#ef6c00" }, text: history.proposals.map((p) => `#${p.id} ${p.status}`), hovertemplate: `proposal %{text}: ${key} %{y:.4g}<extra></extra>` });
    const withTarget = history.proposals.filter((p) => p.target);
    if (withTarget.length) traces.push({ type: "scatter", mode: "markers", name: `${key} target`, yaxis: axis, x: toZone(TZ, withTarget.map((p) => p.time)), y: withTarget.map((p) => p.target[key]), marker: { symbol: "circle-open", size: 11, color: "#2e7d32" }, hovertemplate: `target ${key} %{y:.4g}<extra></extra>` });
  });
  const written = history.writes.filter((w) => w.kind === "proposal");
  if (written.length) traces.push({ type: "scatter", mode: "markers", name: "write", yaxis: "y", x: toZone(TZ, written.map((w) => w.time)), y: written.map((w) => w.Kc), marker: { symbol: "square", size: 8, color: written.map((w) => (w.status === "verified" ? "#1565c0" : "#c62828")) }, text: written.map((w) => `write #${w.id} ${w.status}`), hovertemplate: "%{text}<extra></extra>" });
  const reverts = history.writes.filter((w) => w.kind !== "proposal");
  if (reverts.length) traces.push({ type: "scatter", mode: "markers", name: "revert / restore", yaxis: "y", x: toZone(TZ, reverts.map((w) => w.time)), y: reverts.map((w) => w.Kc), marker: { symbol: "triangle-down", color: "#c62828", size: 11 }, text: reverts.map((w) => `${w.kind} ${w.status}: ${w.why}`), hovertemplate: "%{text}<extra></extra>" });
  const layout = {
    margin: { t: 20, r: 20, b: 40, l: 80 }, legend: { orientation: "h", y: 1.18 }, xaxis: { type: "date", anchor: "y2" },
    yaxis: { domain: [0.55, 1], title: { text: `Kc [${(units || {}).Kc || "?"}]` } },
    yaxis2: { domain: [0, 0.45], title: { text: `Ti [${(units || {}).Ti || "?"}]` } },
  };
  Plotly.react("gains", traces, layout, PLOT_CONFIG);
}


function drawAnalysis(history) {
  drawModels(history);
  drawKTemperature(history);
  drawGains(history);
}
