"use strict";
// The loop page: the live trend (one event stream), model history, K(T), gains, tables.
const LOOP = document.body.dataset.loop;
const TZ = document.body.dataset.tz || "UTC";
const API = `/api/loops/${encodeURIComponent(LOOP)}`;
const LIVE_SPAN_S = 600;       // the live trend shows the newest 10 minutes
const LIVE_POINTS = 3000;      // points per series kept on screen while live
const state = { live: true, newest: null, step: 1, taken: 0, units: { Kc: "", Ti: "" } };
// what the trend shows, for the tests and the latency benchmark: the newest sample drawn [plant s]
// and when [wall s], and the last 1,000 such moments
window.fuelidShown = { newest: null, at: null };
window.fuelidShownLog = [];

const TREND_TRACES = [
  { key: "y", name: "flow [L/min]", yaxis: "y", color: "#1565c0" },
  { key: "setpoint", name: "setpoint [L/min]", yaxis: "y", color: "#000", dash: "dot" },
  { key: "u", name: "VFD command [V]", yaxis: "y2", color: "#6a1b9a" },
  { key: "fuel_temperature", name: "fuel temperature [°C]", yaxis: "y3", color: "#ef6c00" },
];

function trendLayout(title) {
  return {
    margin: { t: 30, r: 20, b: 40, l: 60 }, showlegend: true, legend: { orientation: "h", y: 1.08 },
    title: { text: title, font: { size: 12 }, x: 1, xanchor: "right" },
    xaxis: { type: "date", anchor: "y4" },
    yaxis: { domain: [0.52, 1], title: { text: "L/min" } },
    yaxis2: { domain: [0.27, 0.5], title: { text: "V" } },
    yaxis3: { domain: [0.08, 0.25], title: { text: "°C" } },
    yaxis4: { domain: [0, 0.06], showticklabels: false, range: [0, 1], fixedrange: true },
  };
}

function trendTraces(data) {
  const traces = TREND_TRACES.map((s) => {
    const series = (data.series || {})[s.key] || { t: [], v: [] };
    return {
      type: "scatter", mode: "lines", name: s.name, yaxis: s.yaxis, x: toZone(TZ, series.t), y: series.v,
      line: { color: s.color, width: 1.2, dash: s.dash || "solid" }, connectgaps: false,
    };
  });
  traces.push({
    type: "scatter", mode: "markers", name: "samples not ok", yaxis: "y4", x: toZone(TZ, data.bad || []),
    y: (data.bad || []).map(() => 0.5), marker: { color: "#c62828", symbol: "line-ns-open", size: 10 },
  });
  return traces;
}

function sourceText(data) {
  if (!data.source || data.source === "none") return "no samples yet";
  const what = data.source === "raw" ? "raw samples" : `min/max per ${data.level_s} s bucket`;
  return `${what}, ${data.points} points thinned to the chart's width`;
}

async function loadTrend(start, end) {
  const div = document.getElementById("trend");
  if (!div) return null; // no samples to draw (a central loop without --archive)
  const width = Math.max(300, div.clientWidth || 1000);
  let url = `${API}/trend?width=${width}`;
  if (start !== undefined) url += `&start=${start}&end=${end}`;
  const data = await getJSON(url);
  const newest = (((data.series || {}).y || {}).t || []).slice(-1)[0];
  if (newest !== undefined && (state.newest === null || newest > state.newest)) state.newest = newest;
  document.getElementById("trend-source").textContent = sourceText(data);
  await Plotly.react(div, trendTraces(data), trendLayout(state.live ? "live" : "history"), PLOT_CONFIG);
  state.taken = 0;
  return data;
}

function appendSamples(batch) {
  if (!state.live || !batch.t.length) return;
  const div = document.getElementById("trend");
  if (!div || !div.data) return;
  // keep every k-th sample (and always the newest): a 50 Hz loop draws at about 5 Hz
  const keep = [];
  for (let i = 0; i < batch.t.length; i += 1) {
    state.taken += 1;
    if (state.taken % state.step === 0 || i === batch.t.length - 1) keep.push(i);
  }
  const x = toZone(TZ, keep.map((i) => batch.t[i]));
  const ys = TREND_TRACES.map((s) => keep.map((i) => batch[s.key][i]));
  Plotly.extendTraces(div, { x: [x, x, x, x], y: ys }, [0, 1, 2, 3], LIVE_POINTS);
  const bad = batch.t.filter((t, i) => batch.quality[i] !== 0);
  if (bad.length) Plotly.extendTraces(div, { x: [toZone(TZ, bad)], y: [bad.map(() => 0.5)] }, [4], LIVE_POINTS);
  const newest = batch.t[batch.t.length - 1];
  state.newest = newest;
  const first = Date.parse(div.data[0].x[0] + "Z");
  const last = Date.parse(x[x.length - 1] + "Z");
  if (last - first > LIVE_SPAN_S * 1000) {
    Plotly.relayout(div, { "xaxis.range": [new Date(last - LIVE_SPAN_S * 1000).toISOString().replace("T", " ").replace("Z", ""), x[x.length - 1]] });
  }
  // stamped at the next frame: when the browser paints the new points
  requestAnimationFrame(() => {
    window.fuelidShown = { newest, at: Date.now() / 1000 };
    window.fuelidShownLog.push([newest, window.fuelidShown.at]);
    if (window.fuelidShownLog.length > 1000) window.fuelidShownLog.shift();
  });
}

function bindTrend() {
  const div = document.getElementById("trend");
  if (!div) return;
  div.on("plotly_relayout", (event) => {
    const a = event["xaxis.range[0]"] || (event["xaxis.range"] || [])[0];
    const b = event["xaxis.range[1]"] || (event["xaxis.range"] || [])[1];
    if (a === undefined || b === undefined || state.applying) return;
    if (state.live && event["xaxis.range"]) return; // the live window's own move
    state.live = false;
    const hint = state.newest || Date.now() / 1000;
    loadTrend(fromZone(TZ, a, hint), fromZone(TZ, b, hint)).catch(console.warn);
  });
  document.getElementById("live").addEventListener("click", () => {
    state.live = true;
    loadTrend().catch(console.warn);
  });
}

// --- history charts -----------------------------------------------------------------------

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
  if (!points.length && box.kc !== "" && box.ti !== "" && first !== null) {
    points.push([first, Number(box.kc), Number(box.ti)]); // no proposal, no write: as commissioned
  }
  const last = points.length ? (state.newest || null) : null;
  if (points.length && last !== null && last > points[points.length - 1][0]) {
    const end = points[points.length - 1];
    points.push([last, end[1], end[2]]);
  }
  return points;
}

function drawGains(history) {
  const units = history.gain_units || history.gains_units || state.units;
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

function fillTables(history) {
  const windows = history.windows.slice(-30).reverse().map((w) => el("tr", { class: w.accepted ? "ok" : "alarm" },
    el("td", {}, el("a", { href: `/loops/${encodeURIComponent(LOOP)}/windows/${w.id}` }, String(w.id))),
    el("td", {}, stamp(TZ, w.end)),
    el("td", {}, (w.accepted ? "accepted" : "rejected: ") + (w.accepted ? "" : w.reason)),
    el("td", {}, w.model ? num(w.model.K) : "-"),
    el("td", {}, w.fuel_temperature === null ? "-" : `${num(w.fuel_temperature, 3)} °C`)));
  document.querySelector("#windows tbody").replaceChildren(...windows);
  const events = history.events.slice(-50).reverse().map((e) => el("tr", {}, el("td", {}, stamp(TZ, e.time)), el("td", {}, e.kind), el("td", {}, e.detail)));
  document.querySelector("#events tbody").replaceChildren(...events);
}

// link-down stretches (link_down to the next link_up) as grey bands on the trend
function linkBands(events) {
  const bands = [];
  let down = null;
  for (const e of events) {
    if (e.kind === "link_down" && down === null) down = e.time;
    if (e.kind === "link_up" && down !== null) { bands.push([down, e.time]); down = null; }
  }
  if (down !== null) bands.push([down, state.newest || down]);
  return bands.map(([a, b]) => {
    const [x0, x1] = toZone(TZ, [a, b]);
    return { type: "rect", xref: "x", yref: "paper", x0, x1, y0: 0, y1: 1, fillcolor: "#c62828", opacity: 0.12, line: { width: 0 } };
  });
}

async function loadHistory() {
  const history = await getJSON(`${API}/history`);
  const trend = document.getElementById("trend");
  if (trend && trend.data) Plotly.relayout(trend, { shapes: linkBands(history.events) });
  drawModels(history);
  drawKTemperature(history);
  drawGains(history);
  fillTables(history);
}

// --- actions ----------------------------------------------------------------------------------

function bindActions() {
  document.querySelectorAll("form.action button[data-kind]").forEach((button) => {
    button.addEventListener("click", async () => {
      const form = button.closest("form");
      const kind = button.dataset.kind;
      const why = form.querySelector('input[name="why"]').value;
      const url = kind === "revert" ? `${API}/revert` : `${API}/proposals/${form.dataset.proposal}/${kind}`;
      const outcome = form.querySelector(".outcome");
      outcome.textContent = "sending…";
      const fields = { why };
      // the proposal as this page showed it: a central store's site refuses a request on a
      // proposal that changed since
      if (form.dataset.seenStatus) fields.seen_status = form.dataset.seenStatus;
      if (form.dataset.seenHistory) fields.seen_history_len = form.dataset.seenHistory;
      const answer = await postForm(url, fields);
      if (answer.ok) {
        const request = answer.data.request || {};
        outcome.textContent = `${kind} ${request.status === "done" ? "done" : "filed"}: ${answer.data.next || ""}`;
        form.querySelectorAll("button").forEach((b) => { b.disabled = true; });
        const card = form.closest(".proposal");
        const title = card && card.querySelector("h3");
        if (title && request.status === "done") {
          title.firstChild.textContent = `#${form.dataset.proposal} ${kind === "approve" ? "approved" : "rejected"} `;
        }
        setTimeout(() => window.location.reload(), 2500);
      } else {
        outcome.textContent = answer.data.error || answer.data.detail || `refused (${answer.status})`;
      }
    });
  });
}

// --- the stream ---------------------------------------------------------------------------------

function openStream() {
  const source = new EventSource(`${API}/stream`);
  source.addEventListener("samples", (event) => appendSamples(JSON.parse(event.data)));
  source.addEventListener("status", (event) => {
    const row = JSON.parse(event.data);
    chips(document.getElementById("chips"), row.chips || []);
    const link = document.getElementById("link");
    link.textContent = row.link_text || "";
    link.className = `link ${(row.link && row.link.state) || ""}`;
  });
  source.addEventListener("history", () => loadHistory().catch(console.warn));
  return source;
}

async function start() {
  const period = 0.02;
  state.step = Math.max(1, Math.ceil(LIVE_SPAN_S / period / LIVE_POINTS));
  await loadTrend();
  bindTrend();
  bindActions();
  await loadHistory();
  window.fuelidStream = openStream();
  document.body.dataset.ready = "1";
}

start().catch((error) => console.error("the loop page could not start:", error));
