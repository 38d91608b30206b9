"use strict";
// The window page: the window's data against its model, residuals, their autocorrelation.
const W_LOOP = document.body.dataset.loop;
const W_ID = document.body.dataset.window;
const W_TZ = document.body.dataset.tz || "UTC";

async function startWindow() {
  // a central loop without its raw samples: the page draws no chart, only says why
  if (!document.getElementById("fit")) {
    document.body.dataset.ready = "1";
    return;
  }
  const data = await getJSON(`/api/loops/${encodeURIComponent(W_LOOP)}/windows/${W_ID}`);
  const ev = data.evidence;
  const x = toZone(W_TZ, ev.t || []);
  Plotly.newPlot("fit", [
    { type: "scatter", mode: "lines", name: "flow measured [L/min]", x, y: ev.y, line: { color: "#1565c0", width: 1 } },
    { type: "scatter", mode: "lines", name: "the model's simulation [L/min]", x, y: ev.y_sim, line: { color: "#c62828", width: 1.5 } },
    { type: "scatter", mode: "lines", name: "VFD command [V]", x, y: ev.u, yaxis: "y2", line: { color: "#6a1b9a", width: 1 } },
  ], {
    margin: { t: 20, r: 20, b: 40, l: 60 }, legend: { orientation: "h", y: 1.08 }, xaxis: { type: "date", anchor: "y2" },
    yaxis: { domain: [0.35, 1], title: { text: "L/min" } }, yaxis2: { domain: [0, 0.3], title: { text: "V" } },
  }, PLOT_CONFIG);
  Plotly.newPlot("resid", [{ type: "scatter", mode: "lines", name: "residual", x, y: ev.residual, line: { width: 1 } }],
    { margin: { t: 20, r: 20, b: 40, l: 60 }, xaxis: { type: "date" }, yaxis: { title: { text: "y − ŷ [L/min]" } } }, PLOT_CONFIG);
  const acf = ev.acf || { lag_s: [], value: [] };
  const lags = acf.lag_s;
  const ends = lags.length ? [lags[0], lags[lags.length - 1]] : [0, 1];
  const traces = [{ type: "scatter", mode: "lines", name: "ρ(k)", x: lags, y: acf.value, line: { width: 1 } }];
  if (ev.acf_bound !== undefined && ev.acf_bound !== null) {
    traces.push({ type: "scatter", mode: "lines", name: "the gate's bound", x: ends, y: [ev.acf_bound, ev.acf_bound], line: { color: "#c62828", dash: "dash" } });
    traces.push({ type: "scatter", mode: "lines", showlegend: false, x: ends, y: [-ev.acf_bound, -ev.acf_bound], line: { color: "#c62828", dash: "dash" } });
  }
  if (ev.white_band) {
    traces.push({ type: "scatter", mode: "lines", name: "±1.96/√n (white)", x: ends, y: [ev.white_band, ev.white_band], line: { color: "#777", dash: "dot" } });
    traces.push({ type: "scatter", mode: "lines", showlegend: false, x: ends, y: [-ev.white_band, -ev.white_band], line: { color: "#777", dash: "dot" } });
  }
  Plotly.newPlot("acf", traces, { margin: { t: 20, r: 20, b: 50, l: 60 }, legend: { orientation: "h", y: 1.12 }, xaxis: { title: { text: "lag [s]" } }, yaxis: { title: { text: "autocorrelation [-]" } } }, PLOT_CONFIG);
  document.body.dataset.ready = "1";
}

startWindow().catch((error) => console.error("the window page could not start:", error));
