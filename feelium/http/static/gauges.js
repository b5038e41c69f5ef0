// The HUD's gauges from GET /state, once a second: altitude, heading, battery, and the link (the flight
// controller's link to the motor board, and this page's own event stream to the blimp).

const COMPASS = ["N", "NE", "E", "SE", "S", "SW", "W", "NW"];

function set(id, text, value, bad) {
  const gauge = document.getElementById(id), out = gauge.querySelector("output");
  out.textContent = text;
  gauge.dataset.value = value === null || value === undefined ? "" : String(value);
  gauge.classList.toggle("bad", Boolean(bad));
  return gauge;
}

export class Gauges {
  constructor(call) {
    this.call = call;
    this.streamUp = false;
    this.flight = null;
    this.error = null;
  }

  // The event stream's state, from the Feelium.events status callback.
  setStream(up) { this.streamUp = up; this.render(); }

  async poll() {
    try {
      const { data } = await this.call("GET", "/state");
      this.flight = data.services.flight || null;
      this.error = null;
    } catch (err) {
      this.error = err.message;
    }
    this.render();
  }

  start(everyMs = 1000) { this.poll(); setInterval(() => this.poll(), everyMs); }

  render() {
    const f = this.flight;
    if (f && f.altitude_m !== null && f.altitude_m !== undefined) {
      const g = set("g-altitude", `${f.altitude_m.toFixed(2)} m`, f.altitude_m);
      g.style.setProperty("--level", Math.max(0, Math.min(1, f.altitude_m / 3)));
    } else set("g-altitude", "-", null);
    if (f && f.heading_deg !== null && f.heading_deg !== undefined) {
      const h = ((f.heading_deg % 360) + 360) % 360;
      const g = set("g-heading", `${Math.round(h)}\u00b0 ${COMPASS[Math.round(h / 45) % 8]}`, f.heading_deg);
      g.style.setProperty("--heading", `${h}deg`);
    } else set("g-heading", "-", null);
    if (f && f.battery_v !== null && f.battery_v !== undefined) {
      set("g-battery", `${f.battery_v.toFixed(2)} V ${f.battery}`, f.battery_v, f.battery !== "ok");
    } else set("g-battery", f ? f.battery || "-" : "-", null, true);
    // The link is good only when both hops are: this page to the blimp, and the blimp to its motors.
    const board = f ? f.link : "unknown";
    const text = this.error ? `no answer (${this.error})` : `motors ${board}, events ${this.streamUp ? "live" : "reconnecting"}`;
    set("g-link", text, board, this.error || board !== "up" || !this.streamUp);
  }
}
