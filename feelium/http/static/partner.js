// The partner page (sim mode): press on the rear camera with the mouse to touch the simulated membrane.

import { Feelium } from "./api.js";

const rear = document.querySelector("#rear"), mode = document.querySelector("#mode"), plog = document.querySelector("#log");
Feelium.ready.then(() => { rear.src = Feelium.streamUrl("/video/rear.mjpeg"); });
let size = null, down = false, lastSent = 0;
function note(text) { const li = document.createElement("li"); li.textContent = text; plog.prepend(li); while (plog.children.length > 100) plog.lastChild.remove(); }
Feelium.call("GET", "/sim").then(({ data }) => {
  if (!data.sim) { mode.textContent = "not in sim mode"; mode.className = "badge bad"; return; }
  size = data; mode.textContent = `sim ${data.width}x${data.height}`; mode.className = "badge ok";
}).catch((e) => { mode.textContent = e.message; mode.className = "badge bad"; });
function pixel(e) {
  const r = rear.getBoundingClientRect();
  const w = size.width || rear.naturalWidth, h = size.height || rear.naturalHeight;
  return { x: Math.max(0, Math.min(w - 1, ((e.clientX - r.left) / r.width) * w)), y: Math.max(0, Math.min(h - 1, ((e.clientY - r.top) / r.height) * h)) };
}
async function press(e) {
  const p = { ...pixel(e), hover: e.shiftKey };
  try { await Feelium.call("POST", "/sim/press", p); note(`${p.hover ? "hover" : "press"} ${p.x.toFixed(0)},${p.y.toFixed(0)}`); }
  catch (err) { note(err.message); }
}
const stage = document.querySelector("#stage");
stage.addEventListener("pointerdown", (e) => { if (!size) return; e.preventDefault(); down = true; stage.setPointerCapture(e.pointerId); press(e); });
stage.addEventListener("pointermove", (e) => { if (down && performance.now() - lastSent > 50) { lastSent = performance.now(); press(e); } });
const up = () => { if (!down) return; down = false; Feelium.call("POST", "/sim/release").then(() => note("release")).catch((err) => note(err.message)); };
stage.addEventListener("pointerup", up); stage.addEventListener("pointercancel", up);
