// fuelid dashboard: helpers shared by the pages (no inline scripts: the CSP allows only these files)
"use strict";

// Plant times [s UTC] as plotly date strings in the site's time zone. The zone's offset is taken
// once per batch (a batch never spans a change of daylight-saving time by more than its length).
function zoneOffset(tz, t) {
  const f = new Intl.DateTimeFormat("en-CA", {
    timeZone: tz, year: "numeric", month: "2-digit", day: "2-digit",
    hour: "2-digit", minute: "2-digit", second: "2-digit", hourCycle: "h23",
  });
  const p = Object.fromEntries(f.formatToParts(new Date(t * 1000)).map((x) => [x.type, x.value]));
  const local = Date.UTC(+p.year, +p.month - 1, +p.day, +p.hour, +p.minute, +p.second) / 1000;
  return local - Math.floor(t);
}

function toZone(tz, times) {
  if (!times.length) return [];
  const offset = zoneOffset(tz, times[0]);
  return times.map((t) => new Date((t + offset) * 1000).toISOString().replace("T", " ").replace("Z", ""));
}

function fromZone(tz, text, hint) {
  // a plotly axis value (date string in the zone) back to plant seconds
  const t = Date.parse(String(text).replace(" ", "T") + "Z") / 1000;
  return t - zoneOffset(tz, hint === undefined ? t : hint);
}

function stamp(tz, t) {
  if (t === null || t === undefined) return "-";
  return toZone(tz, [t])[0].slice(0, 19);
}

function num(x, digits) {
  if (x === null || x === undefined || Number.isNaN(x)) return "-";
  return Number(x).toPrecision(digits || 4).replace(/\.?0+$/, (m) => (m.startsWith(".") ? "" : m));
}

function el(tag, attrs, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "class") node.className = v; else if (k === "href") node.href = v; else node.setAttribute(k, v);
  }
  for (const child of children) node.append(child === null || child === undefined ? "" : child);
  return node;
}

async function getJSON(url) {
  const response = await fetch(url, { credentials: "same-origin" });
  if (!response.ok) throw new Error(`${url}: ${response.status}`);
  return response.json();
}

function csrfToken() {
  const meta = document.querySelector('meta[name="csrf-token"]');
  return meta ? meta.content : "";
}

async function postForm(url, fields) {
  const body = new URLSearchParams(fields); // url-encoded: the server parses forms without multipart
  const response = await fetch(url, {
    method: "POST", body, credentials: "same-origin", headers: { "X-CSRF-Token": csrfToken() },
  });
  let data = {};
  try { data = await response.json(); } catch (e) { data = {}; }
  return { ok: response.ok, status: response.status, data };
}

function chips(container, list, note) {
  container.replaceChildren(...list.flatMap((c) => [el("span", { class: `chip ${c.level}`, title: c.name }, `${c.name}: ${c.text}`), " "]));
  // the test signal while it runs: a note beside the chips, not one of them (it sets no level)
  if (note && note.exciting) container.append(el("span", { class: "chip note exciting", title: "test signal" }, note.text));
}

// no button that sends data anywhere: the charts' toolbars keep zoom, pan, reset and the PNG download
const PLOT_CONFIG = {
  displaylogo: false, responsive: true, showLink: false, showSendToCloud: false, showEditInChartStudio: false,
  modeBarButtonsToRemove: ["lasso2d", "select2d", "sendDataToCloud", "editInChartStudio"],
};
