"use strict";
// Staleness made visible. A page left open on a control-room screen must never look healthy when
// its data stopped arriving: a watchdog times every arrival (the loop page's stream sends a status
// event every 2 s; the fleet page polls every 5 s). When one is late, a banner says
// "disconnected — values as of HH:MM:SS" and every element marked .live is greyed (body.stale);
// the page reconnects by itself and says so. body[data-connection] is "live", "disconnected" or
// "reconnected" (for the tests and for assistive tools; the banner has role="alert").

const RECONNECTED_SHOWN_MS = 8000;

function clockText(tz, date) {
  return new Intl.DateTimeFormat("en-GB", {
    timeZone: tz, hour: "2-digit", minute: "2-digit", second: "2-digit", hourCycle: "h23",
  }).format(date);
}

class Watchdog {
  // lateMs: silence after which the page is disconnected; onLost/onBack: what the page does
  constructor({ tz, lateMs, onLost, onBack }) {
    this.tz = tz;
    this.lateMs = lateMs;
    this.onLost = onLost || (() => {});
    this.onBack = onBack || (() => {});
    this.last = null;       // Date of the last arrival
    this.lost = false;
    this.banner = document.getElementById("conn");
    this.timer = setInterval(() => this.check(), 1000);
    document.body.dataset.connection = "live";
  }

  arrived() {
    this.last = new Date();
    if (this.lost) {
      this.lost = false;
      document.body.classList.remove("stale");
      document.body.dataset.connection = "reconnected";
      this.show(`reconnected at ${clockText(this.tz, this.last)}: the values below are live again`, "ok");
      clearTimeout(this.hideTimer);
      this.hideTimer = setTimeout(() => {
        if (!this.lost) { this.hide(); document.body.dataset.connection = "live"; }
      }, RECONNECTED_SHOWN_MS);
      this.onBack();
    }
  }

  check() {
    if (this.lost || this.last === null || Date.now() - this.last.getTime() <= this.lateMs) return;
    this.lost = true;
    document.body.classList.add("stale");
    document.body.dataset.connection = "disconnected";
    const asOf = clockText(this.tz, this.last);
    this.show(`disconnected — values as of ${asOf} (${this.tz}, this screen's clock); reconnecting…`, "alarm");
    this.onLost();
  }

  show(text, level) {
    if (!this.banner) return;
    this.banner.textContent = text;
    this.banner.className = `banner conn ${level}`;
    this.banner.hidden = false;
  }

  hide() {
    if (this.banner) this.banner.hidden = true;
  }
}

// One event stream with a watchdog on its status events. EventSource retries by itself while the
// server is away; it gives up for good on an HTTP error (a dashboard restarting answers 502/503
// through a proxy), and a network that drops silently sends no error at all: both are caught here
// by reopening the stream when it is closed or silent for too long.
class LiveStream {
  constructor(url, { tz, statusEveryMs, handlers, onLost, onBack }) {
    this.url = url;
    this.handlers = handlers;
    this.silentMs = 5 * statusEveryMs;
    this.watchdog = new Watchdog({ tz, lateMs: 2.5 * statusEveryMs, onLost, onBack });
    this.open();
    setInterval(() => this.revive(), 2000);
  }

  open() {
    if (this.source) this.source.close();
    this.source = new EventSource(this.url);
    this.opened = Date.now();
    for (const [kind, handler] of Object.entries(this.handlers)) {
      this.source.addEventListener(kind, (event) => {
        if (kind === "status") this.watchdog.arrived();
        handler(JSON.parse(event.data));
      });
    }
  }

  revive() {
    const last = this.watchdog.last ? this.watchdog.last.getTime() : this.opened;
    const closed = this.source.readyState === EventSource.CLOSED;
    const silent = Date.now() - Math.max(last, this.opened) > this.silentMs;
    if (closed || silent) this.open();
  }
}
