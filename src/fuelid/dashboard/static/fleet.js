"use strict";
// the fleet table, refreshed every 5 s from /api/loops (the same rows, the same order)
async function refreshFleet() {
  try {
    const data = await getJSON("/api/loops");
    const body = document.querySelector("#fleet tbody");
    const rows = data.loops.map((row) => {
      const tr = el("tr", { class: `level-${row.level}`, "data-loop": row.loop_id });
      const chipCell = el("td");
      chips(chipCell, row.chips);
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
setInterval(refreshFleet, 5000);
document.body.dataset.ready = "1";
