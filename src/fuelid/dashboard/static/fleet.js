"use strict";
// the fleet table, refreshed every 5 s from /api/loops (the same rows, the same order); a watchdog
// (live.js) greys the table and says "disconnected" when the refreshes stop succeeding
const FLEET_EVERY_MS = 5000;
const fleetWatchdog = new Watchdog({
  tz: document.body.dataset.tz || "UTC",
  // one refresh missed and most of the next: "disconnected" within 10 s of the last answer
  lateMs: 1.6 * FLEET_EVERY_MS,
  onBack: () => {},
});
fleetWatchdog.arrived(); // the page itself was just served

async function refreshFleet() {
  try {
    const data = await getJSON("/api/loops");
    fleetWatchdog.arrived();
    const body = document.querySelector("#fleet tbody");
    const rows = data.loops.map((row) => {
      const tr = el("tr", { class: `level-${row.level}`, "data-loop": row.loop_id });
      const chipCell = el("td");
      chips(chipCell, row.chips, row.excitation);
      tr.append(
        el("td", {}, el("a", { href: `/loops/${encodeURIComponent(row.loop_id)}` }, row.loop_id)),
        el("td", {}, row.site_name),
        el("td", {}, el("span", { class: `level ${row.level}` }, row.level)),
        chipCell,
      );
      return tr;
    });
    if (rows.length) body.replaceChildren(...rows);
  } catch (error) {
    console.warn("fleet refresh failed", error);
  }
}
setInterval(refreshFleet, FLEET_EVERY_MS);
document.body.dataset.ready = "1";
