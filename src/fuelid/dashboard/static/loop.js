"use strict";
// The loop page: one event stream feeds every live part. `status` events redraw the chips and the
// link line; `samples` extend the live trend (trend.js); `windows`, `proposals`, `writes` and
// `events` (sent when the store's counts or the link's state change) and `excitation` (the test
// signal's state changed: it lives in the service's record, not in the counts) re-read the page's
// parts (proposals, "Now" with the test signal, the windows and events tables), which the server
// renders with the very templates of the first view: one truth on the page. The analysis charts load plotly.js only when
// scrolled into view (analysis.js).
const LOOP = document.body.dataset.loop;
const TZ = document.body.dataset.tz || "UTC";
const API = `/api/loops/${encodeURIComponent(LOOP)}`;
const PAGE = `/loops/${encodeURIComponent(LOOP)}`;
const STATUS_EVERY_MS = 2000;
const ANALYSIS_EVERY_MS = 10000;   // the analysis charts are redrawn at most this often
const ANALYSIS_WINDOWS = 2000;     // the newest windows they draw (the API pages a year of them)

let trend = null;
const analysis = { loaded: false, loading: null, last: 0, timer: null };
// what the trend shows, for the tests and the latency benchmark: the newest sample drawn [plant s]
// and when [wall s], and the last 1,000 such moments
window.fuelidShown = { newest: null, at: null };
window.fuelidShownLog = [];

function trendNewest() {
  return trend ? trend.newest : null;
}

// --- status: chips and the link line --------------------------------------------------------------

function showStatus(row) {
  chips(document.getElementById("chips"), row.chips || [], row.excitation);
  const link = document.getElementById("link");
  link.textContent = row.link_text || "";
  link.className = `link live ${row.link_state || (row.link && row.link.state) || ""}`;
  document.body.dataset.service = (row.link && row.link.state) || "";
  showExcitationElapsed(row.link && row.link.newest_sample);
}

// how long a burst has run, as format_age says it (fuelid.io._clock): advanced at every status
// event from its newest sample (plant time), so the part is not re-read every 2 s for it
function ageText(s) {
  if (s === null || s === undefined || !Number.isFinite(s)) return "unknown";
  if (s < 10) return `${s.toFixed(1)} s`;
  if (s < 120) return `${s.toFixed(0)} s`;
  if (s < 7200) return `${(s / 60).toFixed(0)} min`;
  if (s < 172800) return `${(s / 3600).toFixed(1)} h`;
  return `${(s / 86400).toFixed(1)} d`;
}

function showExcitationElapsed(newest) {
  const box = document.getElementById("excitation-running");
  const out = document.getElementById("excitation-elapsed");
  if (!box || !out || newest === null || newest === undefined || box.dataset.started === "") return;
  const elapsed = Math.max(0, newest - Number(box.dataset.started));
  const burst = box.dataset.burst === "" ? null : Number(box.dataset.burst);
  if (burst !== null) out.textContent = `${ageText(elapsed)} of ${ageText(burst)}`;
}

// --- the live trend --------------------------------------------------------------------------------

function stampShown(newest) {
  // stamped at the next frame: when the browser paints the new points
  requestAnimationFrame(() => {
    window.fuelidShown = { newest, at: Date.now() / 1000 };
    window.fuelidShownLog.push([newest, window.fuelidShown.at]);
    if (window.fuelidShownLog.length > 1000) window.fuelidShownLog.shift();
  });
}

async function loadTrend() {
  const box = document.getElementById("trend");
  if (!box) return; // no samples to draw (a central loop without --archive)
  if (trend === null) {
    trend = new LiveTrend(box, {
      tz: TZ, api: API, minutes: Number(box.dataset.minutes) || 10,
      period: Number(document.body.dataset.period) || 0.02,
      onZoom: (following, data) => showFollowing(following, data),
    });
    window.addEventListener("resize", () => trend.resize());
  }
  const width = Math.max(300, box.clientWidth || 1000);
  const data = await getJSON(`${API}/trend?width=${width}&minutes=${box.dataset.minutes || 10}`);
  trend.load(data);
  showFollowing(trend.following, data);
  stampShown(trend.newest);
}

function showFollowing(following, data) {
  document.getElementById("live").hidden = following;
  const span = document.getElementById("trend-span");
  if (span) span.textContent = following ? `the newest ${trend.span / 60} min, following` : "a stored range, not following";
  if (following) document.getElementById("trend-source").textContent = "live: pushed as the samples are committed";
  else if (data) document.getElementById("trend-source").textContent = sourceText(data);
}

function sourceText(data) {
  if (!data.source || data.source === "none") return "no samples yet";
  const what = data.source === "raw" ? "raw samples" : `min/max per ${data.level_s} s bucket`;
  return `${what}, ${data.points} points thinned to the chart's width`;
}

function appendSamples(batch) {
  if (trend === null || !batch.t.length) return;
  trend.append(batch);
  stampShown(trend.newest);
}

function bindTrend() {
  const follow = document.getElementById("live");
  if (!follow) return;
  follow.addEventListener("click", () => trend.follow());
  document.querySelectorAll("button[data-range-minutes]").forEach((button) => {
    button.addEventListener("click", () => {
      const end = trend.newest === null ? Date.now() / 1000 : trend.newest;
      trend.showRange(end - 60 * Number(button.dataset.rangeMinutes), end + 1e-6).catch(console.warn);
    });
  });
}

// --- the parts the server renders -----------------------------------------------------------------

let partsTimer = null;

function refreshParts() {
  // several events in one beat (a window, its proposal, its event) cost one read
  clearTimeout(partsTimer);
  partsTimer = setTimeout(() => loadParts().catch(console.warn), 300);
}

// what a person typed or was told in the action forms, kept across a refresh of the parts (a
// window judged every few seconds must not wipe a reason half typed)
function formKey(form) {
  // a proposal's form by its id; revert and the test signal's start and stop by their kind
  return form.dataset.proposal || form.dataset.kind || "revert";
}

function cardOf(proposal) {
  return document.querySelector(`#proposals-part div.proposal[data-proposal="${proposal}"]`);
}

// what a proposal's card offers: its state and its actions ("" for a card without a form)
function cardSeen(proposal) {
  const card = cardOf(proposal);
  const form = card && card.querySelector("form.action");
  const kinds = form ? Array.from(form.querySelectorAll("button[data-kind]")).map((b) => b.dataset.kind) : [];
  return { state: card ? card.dataset.state : "", actions: kinds.join(",") };
}

function formsState() {
  const kept = {};
  document.querySelectorAll("form.action").forEach((form) => {
    const why = form.querySelector('input[name="why"]');
    kept[formKey(form)] = {
      proposal: form.dataset.proposal || null,
      seen: form.dataset.proposal ? cardSeen(form.dataset.proposal) : null,
      sent: form.dataset.sent || "",
      why: why ? why.value : "",
      focused: why !== null && document.activeElement === why,
      outcome: (form.querySelector(".outcome") || {}).textContent || "",
      confirming: form.querySelector(".confirm[hidden]") === null ? form.dataset.confirming : null,
    };
  });
  return kept;
}

// a proposal whose state or actions changed under a typed reason or an open question: what was
// typed was meant for the proposal as it was, so it is not kept next to other buttons
function changedUnder(was) {
  if (!was.proposal || (!was.why.trim() && !was.confirming)) return false;
  const now = cardSeen(was.proposal);
  return now.state !== was.seen.state || now.actions !== was.seen.actions;
}

// said on a card until it changes again or the person acts on it: "nothing was sent"
const changedNotes = new Map();

function noteChange(was) {
  const card = cardOf(was.proposal);
  const label = card ? card.querySelector("h3 .state").textContent : "no longer shown";
  changedNotes.set(was.proposal, {
    state: card ? card.dataset.state : "",
    text: `the proposal changed (now: ${label}): nothing was sent`,
  });
}

function showNotes() {
  for (const [proposal, note] of changedNotes) {
    const card = cardOf(proposal);
    if (!card) { // its card is no longer on the page: said once, above the cards
      const line = el("p", { class: "changed warn", role: "status" }, `#${proposal}: ${note.text}`);
      document.querySelector("#proposals-part h2").after(line);
      changedNotes.delete(proposal);
      continue;
    }
    if (card.dataset.state !== note.state) { changedNotes.delete(proposal); continue; }
    const line = el("p", { class: "changed warn", role: "status" }, note.text);
    const form = card.querySelector("form.action");
    if (form) form.before(line); else card.append(line);
  }
}

function restoreForm(form, was) {
  const why = form.querySelector('input[name="why"]');
  if (why) why.value = was.why;
  if (why && was.focused) why.focus();
  const outcome = form.querySelector(".outcome");
  if (outcome) outcome.textContent = was.outcome;
  if (was.sent) form.dataset.sent = was.sent;
  const button = was.confirming && form.querySelector(`button[data-kind="${was.confirming}"]`);
  if (button && !button.disabled) askToConfirm(button); // the question stays open
}

function restoreForms(kept) {
  for (const was of Object.values(kept)) {
    if (!changedUnder(was)) continue;
    // the question is not asked again and the reason not kept; said on the card unless this
    // page sent something (its outcome says what became of it)
    delete kept[was.proposal];
    const form = cardOf(was.proposal) && cardOf(was.proposal).querySelector("form.action");
    if (form && was.sent) form.querySelector(".outcome").textContent = was.outcome;
    if (!was.sent) noteChange(was);
  }
  document.querySelectorAll("form.action").forEach((form) => {
    const was = kept[formKey(form)];
    if (was) restoreForm(form, was);
  });
  showNotes();
}

async function loadParts() {
  const parts = await getJSON(`${PAGE}/parts`);
  const kept = formsState();
  for (const [name, html] of Object.entries(parts.html)) {
    const box = document.getElementById(`${name}-part`);
    if (box) box.innerHTML = html; // rendered by the server's templates, every value escaped
  }
  restoreForms(kept);
  if (parts.status) showStatus(parts.status);
  if (trend) trend.setBands(parts.link_bands || []);
  bindActions();
  scheduleAnalysis();
}

// --- actions: a reason (optional for a stop of the test signal) and a confirmation ----------------

// the endpoint of each kind of action (a proposal's approve and reject: under its id)
const ACTION_URLS = {
  revert: () => `${API}/revert`,
  excite_start: () => `${API}/excitation/start`,
  excite_stop: () => `${API}/excitation/stop`,
};

function bindActions() {
  document.querySelectorAll("form.action button[data-kind]").forEach((button) => {
    button.addEventListener("click", () => askToConfirm(button));
  });
  // the person acts on the card again: "the proposal changed" has been read
  document.querySelectorAll("form.action[data-proposal] input[name=why]").forEach((input) => {
    input.addEventListener("input", () => forgetChange(input.closest("form")));
  });
}

function forgetChange(form) {
  if (!changedNotes.delete(form.dataset.proposal)) return;
  const line = cardOf(form.dataset.proposal).querySelector("p.changed");
  if (line) line.remove();
}

function askToConfirm(button) {
  const form = button.closest("form");
  const why = form.querySelector('input[name="why"]');
  const outcome = form.querySelector(".outcome");
  const verb = button.dataset.verb || button.dataset.kind;
  if (!why.value.trim() && !button.dataset.whyOptional) {
    outcome.textContent = `a reason is required to ${verb}`;
    why.focus();
    return;
  }
  outcome.textContent = ""; // "a reason is required" no longer holds
  if (form.dataset.proposal) forgetChange(form);
  const confirm = form.querySelector(".confirm");
  form.dataset.confirming = button.dataset.kind;
  confirm.querySelector(".question").textContent = button.dataset.confirm || `${button.dataset.kind}?`;
  confirm.hidden = false;
  const yes = confirm.querySelector("button.yes");
  yes.textContent = `yes, ${verb}`;
  yes.onclick = () => send(form, button.dataset.kind, why.value.trim(), verb);
  confirm.querySelector("button.no").onclick = () => { confirm.hidden = true; outcome.textContent = ""; };
}

async function send(form, kind, why, verb) {
  const url = Object.hasOwn(ACTION_URLS, kind) ? ACTION_URLS[kind]() : `${API}/proposals/${form.dataset.proposal}/${kind}`;
  const outcome = form.querySelector(".outcome");
  form.dataset.sent = kind; // what follows on the card is this page's doing
  form.querySelector(".confirm").hidden = true;
  form.querySelectorAll("button").forEach((b) => { b.disabled = true; });
  outcome.textContent = "sending…";
  const fields = { why };
  // the proposal as this page showed it: a central store's site refuses a request on a proposal
  // that changed since
  if (form.dataset.seenStatus) fields.seen_status = form.dataset.seenStatus;
  if (form.dataset.seenHistory) fields.seen_history_len = form.dataset.seenHistory;
  const answer = await postForm(url, fields);
  if (answer.ok) {
    const request = answer.data.request || {};
    outcome.textContent = `${verb || kind} ${request.status === "done" ? "done" : "filed"}: ${answer.data.next || ""}`;
  } else {
    outcome.textContent = answer.data.error || answer.data.detail || `refused (${answer.status})`;
    form.querySelectorAll("button").forEach((b) => { b.disabled = false; });
  }
  refreshParts(); // the cards follow the request's outcome, whatever it is
}

// --- the analysis charts, loaded when shown ---------------------------------------------------------

function loadScript(src) {
  return new Promise((resolve, reject) => {
    const script = document.createElement("script");
    script.src = src;
    script.onload = resolve;
    script.onerror = () => reject(new Error(`${src} did not load`));
    document.head.append(script);
  });
}

async function drawAnalysisNow() {
  const box = document.getElementById("analysis");
  if (!analysis.loaded) {
    analysis.loading = analysis.loading || loadScript(box.dataset.plotly).then(() => loadScript(box.dataset.script));
    await analysis.loading;
    analysis.loaded = true;
  }
  analysis.last = Date.now();
  const history = await getJSON(`${API}/history?windows=${ANALYSIS_WINDOWS}`);
  drawAnalysis(history);
  box.dataset.drawn = String(analysis.last);
}

function scheduleAnalysis() {
  if (!analysis.loaded || analysis.timer !== null) return;
  const wait = Math.max(0, ANALYSIS_EVERY_MS - (Date.now() - analysis.last));
  analysis.timer = setTimeout(() => {
    analysis.timer = null;
    drawAnalysisNow().catch(console.warn);
  }, wait);
}

function watchAnalysis() {
  const box = document.getElementById("analysis");
  if (!box) return;
  const seen = new IntersectionObserver((entries) => {
    if (entries.some((e) => e.isIntersecting)) {
      seen.disconnect();
      drawAnalysisNow().catch((error) => console.error("the analysis charts could not load:", error));
    }
  }, { rootMargin: "200px" });
  seen.observe(box);
}

async function checkSession() {
  const who = document.querySelector("header.top .who");
  const shown = who && who.querySelector("form.inline") !== null; // a user's name and "log out"
  const me = await getJSON("/api/whoami");
  if (shown && !me.user) {
    const next = encodeURIComponent(window.location.pathname);
    who.replaceChildren("your session ended (the dashboard restarted): ", el("a", { href: `/login?next=${next}` }, "log in again"));
  }
}

// --- start ------------------------------------------------------------------------------------------

function openStream() {
  const refresh = () => refreshParts();
  return new LiveStream(`${API}/stream`, {
    tz: TZ,
    statusEveryMs: STATUS_EVERY_MS,
    handlers: {
      status: showStatus, samples: appendSamples,
      windows: refresh, proposals: refresh, writes: refresh, events: refresh, excitation: refresh,
    },
    // back after a loss: the samples missed meanwhile come from the store, the parts afresh,
    // and a session the dashboard no longer knows (it restarted) is said, not shown as open
    onBack: () => { loadTrend().catch(console.warn); refreshParts(); checkSession().catch(console.warn); },
  });
}

async function start() {
  bindActions();
  window.fuelidStream = openStream();
  await loadTrend();
  bindTrend();
  watchAnalysis();
  document.body.dataset.ready = "1";
  loadParts().catch(console.warn); // the link bands on the trend
}

start().catch((error) => console.error("the loop page could not start:", error));
