"use strict";
// The live trend: three stacked uPlot panels (flow and setpoint, VFD command, fuel temperature)
// on one time axis that follows the newest sample for as long as the page is open. Zooming (drag
// across a panel) or a longer range stops following; "follow live" resumes it. The element
// carries data-newest (the newest sample drawn) and data-range-end (the axis' end), as ISO times.
//
// Samples arrive from the stream; the trend keeps the newest span (plus a margin) in plain arrays,
// one point in `step` (a 50 Hz loop draws about 5 points a second), so memory stays bounded
// however long the page is open. A jump in time of more than GAP_PERIODS sampling periods (a
// link blip, a stopped service) breaks the lines instead of joining across it.

const GAP_PERIODS = 5;
const KEEP_MARGIN = 1.1;      // the ring keeps 10 % more than the span shown
const LIVE_POINTS = 3000;     // points per series on screen while following

const PANELS = [
  { id: "trend-flow", height: 230, series: [
    { key: "y", label: "flow [L/min]", stroke: "#1565c0" },
    { key: "setpoint", label: "setpoint [L/min]", stroke: "#000", dash: [4, 4] },
  ], unit: "L/min" },
  { id: "trend-u", height: 130, series: [{ key: "u", label: "VFD command [V]", stroke: "#6a1b9a" }], unit: "V" },
  { id: "trend-tf", height: 130, series: [{ key: "fuel_temperature", label: "fuel temperature [°C]", stroke: "#ef6c00" }], unit: "°C" },
];

// the time axis' tick labels, 24-hour clock in the site's zone (uPlot's table: tick step [s],
// its format, then the formats where the year, month, day, hour, minute or second changes)
const TIME_TICKS = [
  [86400, "{YYYY}-{MM}-{DD}", null, null, null, null, null, null, 1],
  [60, "{HH}:{mm}", "\n{YYYY}-{MM}-{DD}", null, "\n{MM}-{DD}", null, null, null, 1],
  [1, "{HH}:{mm}:{ss}", "\n{YYYY}-{MM}-{DD}", null, "\n{MM}-{DD}", null, null, null, 1],
  [0.001, "{HH}:{mm}:{ss}.{fff}", "\n{YYYY}-{MM}-{DD}", null, "\n{MM}-{DD}", null, null, null, 1],
];

function isoTime(t) {
  return t === null || t === undefined ? "" : new Date(t * 1000).toISOString();
}

class LiveTrend {
  constructor(box, { tz, minutes, period, api, onZoom }) {
    this.box = box;
    this.tz = tz;
    this.span = minutes * 60;
    this.period = period > 0 ? period : 0.02;
    this.api = api;
    this.onZoom = onZoom || (() => {});
    this.step = Math.max(1, Math.ceil(this.span / this.period / LIVE_POINTS));
    this.taken = 0;
    this.following = true;
    this.ring = { t: [], y: [], setpoint: [], u: [], fuel_temperature: [] };
    this.bad = [];          // times of samples not ok (red ticks)
    this.bands = [];        // [from, to] of link-down stretches (shaded)
    this.newest = null;
    this.shown = null;      // the data drawn when not following (a stored range)
    this.applying = false;
    this.plots = PANELS.map((panel) => this.makePanel(panel));
  }

  makePanel(panel) {
    const div = document.createElement("div");
    div.id = panel.id;
    this.box.append(div);
    const width = Math.max(300, this.box.clientWidth || 1000);
    const opts = {
      width, height: panel.height,
      tzDate: (ts) => uPlot.tzDate(new Date(ts * 1000), this.tz),
      scales: { x: { time: true } },
      cursor: { sync: { key: "fuelid-trend", setSeries: false }, drag: { x: true, y: false } },
      legend: { live: false },
      series: [{}, ...panel.series.map((s) => ({ label: s.label, stroke: s.stroke, width: 1.2, dash: s.dash, spanGaps: false }))],
      // small panels: ticks every 20 px (uPlot's default spacing leaves a 130 px panel one label)
      axes: [{ values: TIME_TICKS }, { label: panel.unit, size: 60, space: 20 }],
      hooks: {
        setSelect: [(u) => this.userZoom(u)],
        draw: panel.id === "trend-flow" ? [(u) => this.drawMarks(u)] : [],
      },
    };
    return { panel, plot: new uPlot(opts, this.emptyData(panel), div) };
  }

  emptyData(panel) {
    return [[], ...panel.series.map(() => [])];
  }

  resize() {
    const width = Math.max(300, this.box.clientWidth || 1000);
    for (const { panel, plot } of this.plots) plot.setSize({ width, height: panel.height });
  }

  // --- data in ---------------------------------------------------------------------------

  load(data) {
    // a stored stretch (the API's thinned answer): the ring while following, else what is shown
    const flow = ((data.series || {}).y || { t: [] }).t;
    if (this.following) {
      this.ring = { t: [], y: [], setpoint: [], u: [], fuel_temperature: [] };
      const keys = Object.keys(this.ring).filter((k) => k !== "t");
      // each series was thinned on its own: the flow's times carry the others by nearest value
      for (let i = 0; i < flow.length; i += 1) this.ring.t.push(flow[i]);
      for (const key of keys) this.ring[key] = this.alignTo(flow, (data.series || {})[key]);
      this.bad = (data.bad || []).slice();
      if (flow.length) this.newest = Math.max(this.newest || -Infinity, flow[flow.length - 1]);
    } else {
      this.shown = data;
    }
    this.redraw();
  }

  alignTo(times, series) {
    if (!series || !series.t.length) return times.map(() => null);
    const out = [];
    let j = 0;
    for (const t of times) {
      while (j + 1 < series.t.length && Math.abs(series.t[j + 1] - t) <= Math.abs(series.t[j] - t)) j += 1;
      out.push(series.v[j]);
    }
    return out;
  }

  append(batch) {
    if (!batch.t.length) return;
    const ring = this.ring;
    for (let i = 0; i < batch.t.length; i += 1) {
      this.taken += 1;
      if (this.taken % this.step !== 0 && i !== batch.t.length - 1) continue;
      const t = batch.t[i];
      const last = ring.t.length ? ring.t[ring.t.length - 1] : null;
      if (last !== null && t <= last) continue; // a back-filled sample older than the drawn ones
      if (last !== null && t - last > GAP_PERIODS * Math.max(this.period * this.step, this.period)) {
        this.push(last + this.period, null, null, null, null); // break the line across the gap
      }
      this.push(t, batch.y[i], batch.setpoint[i], batch.u[i], batch.fuel_temperature[i]);
    }
    batch.t.forEach((t, i) => { if (batch.quality[i] !== 0) this.bad.push(t); });
    this.newest = Math.max(this.newest || -Infinity, batch.t[batch.t.length - 1]);
    this.trim();
    this.redraw();
  }

  push(t, y, sp, u, tf) {
    const r = this.ring;
    r.t.push(t); r.y.push(y); r.setpoint.push(sp); r.u.push(u); r.fuel_temperature.push(tf);
  }

  trim() {
    // keep the newest span (and a margin): the page may stay open for days
    const oldest = this.newest - KEEP_MARGIN * this.span;
    let cut = 0;
    while (cut < this.ring.t.length && this.ring.t[cut] < oldest) cut += 1;
    if (cut > 0) for (const key of Object.keys(this.ring)) this.ring[key].splice(0, cut);
    let badCut = 0;
    while (badCut < this.bad.length && this.bad[badCut] < oldest) badCut += 1;
    if (badCut > 0) this.bad.splice(0, badCut);
  }

  setBands(bands) {
    this.bands = bands;
    this.plots[0].plot.redraw(false, false);
  }

  // --- drawing -----------------------------------------------------------------------------

  dataOf(panel) {
    if (this.following || !this.shown) {
      return [this.ring.t, ...panel.series.map((s) => this.ring[s.key])];
    }
    const series = this.shown.series || {};
    // a stored range: each series has its own thinned times; the panel's first sets the axis
    const first = series[panel.series[0].key] || { t: [], v: [] };
    return [first.t, ...panel.series.map((s) => this.alignTo(first.t, series[s.key]))];
  }

  redraw() {
    const range = this.range();
    this.applying = true;
    try {
      for (const { panel, plot } of this.plots) {
        plot.setData(this.dataOf(panel), false);
        if (range) plot.setScale("x", { min: range[0], max: range[1] });
      }
    } finally {
      this.applying = false;
    }
    this.box.dataset.newest = isoTime(this.newest);
    this.box.dataset.rangeEnd = range ? isoTime(range[1]) : "";
    this.box.dataset.following = this.following ? "1" : "0";
    this.box.dataset.points = String(this.ring.t.length);
  }

  range() {
    if (this.following) return this.newest === null ? null : [this.newest - this.span, this.newest];
    if (this.shown && this.shown.start !== null) return [this.shown.start, this.shown.end];
    return null;
  }

  drawMarks(u) {
    // link-down stretches shaded, samples not ok as red ticks at the bottom of the flow panel
    const ctx = u.ctx;
    const { left, top, width, height } = u.bbox;
    ctx.save();
    ctx.fillStyle = "rgba(198, 40, 40, 0.12)";
    for (const [a, b] of this.bands) {
      const x0 = Math.max(left, u.valToPos(a, "x", true));
      const x1 = Math.min(left + width, u.valToPos(b, "x", true));
      if (x1 > x0) ctx.fillRect(x0, top, x1 - x0, height);
    }
    ctx.strokeStyle = "#c62828";
    ctx.lineWidth = 1;
    const marks = this.following || !this.shown ? this.bad : this.shown.bad || [];
    for (const t of marks) {
      const x = u.valToPos(t, "x", true);
      if (x < left || x > left + width) continue;
      ctx.beginPath(); ctx.moveTo(x, top + height - 8); ctx.lineTo(x, top + height); ctx.stroke();
    }
    ctx.restore();
  }

  // --- following and zooming -----------------------------------------------------------------

  userZoom(u) {
    if (this.applying || u.select.width < 3) return;
    const a = u.posToVal(u.select.left, "x");
    const b = u.posToVal(u.select.left + u.select.width, "x");
    u.setSelect({ left: 0, width: 0, top: 0, height: 0 }, false);
    this.showRange(a, b);
  }

  async showRange(start, end) {
    // a stored range, thinned by the server to the chart's width: following stops
    this.following = false;
    this.onZoom(false);
    const width = Math.max(300, this.box.clientWidth || 1000);
    const data = await getJSON(`${this.api}/trend?width=${width}&start=${start}&end=${end}`);
    if (this.following) return; // "follow live" was pressed meanwhile
    this.shown = data;
    this.onZoom(false, data);
    this.redraw();
    return data;
  }

  follow() {
    this.following = true;
    this.shown = null;
    this.onZoom(true);
    this.redraw();
  }
}
