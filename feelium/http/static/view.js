// The wearer's eyes: the front fisheye with touch markers, as a dome (WebGL on the page, WebXR in a headset) or,
// where WebGL is missing, flat as the lens sees it.
//
// Every displayed frame is composed once at the camera's resolution: the newest MJPEG frame, then the markers,
// drawn at the pixel the lens model gives for each touch. That composite is the dome's texture, so markers need
// no geometry of their own and land on the dome wherever the lens model says.

import { Dome, lookAround, perspective, rotationOnly } from "./dome.js";
import { loadLens } from "./lens.js";

const MARKER = "rgba(255,159,67,0.9)";
const RIPPLE_MS = 900;

export class FisheyeView {
  constructor({ video, frame, dome, markers, toggle, call }) {
    Object.assign(this, { video, frame, domeCanvas: dome, markerCanvas: markers, toggle, call });
    this.lens = null;
    this.marks = new Map(); // contact id -> {u, v}
    this.ripples = [];
    this.yaw = 0; this.pitch = 0; this.fovy = (80 * Math.PI) / 180;
    this.composedAt = -Infinity;
    this.dome = this.createDome();
    this.flat = !this.dome;
    this.showMode();
    this.toggle.hidden = !this.dome;
    this.toggle.addEventListener("click", () => { this.flat = !this.flat; this.showMode(); });
    this.lookWithPointer();
    video.addEventListener("load", () => this.start(), { once: true });
  }

  createDome() {
    // xrCompatible: the same context (and texture) then also draws the immersive session
    const gl = this.domeCanvas.getContext("webgl", { xrCompatible: "xr" in navigator, preserveDrawingBuffer: true });
    if (!gl) return null;
    try { return new Dome(gl); } catch (err) { console.warn("no dome, flat view instead:", err); return null; }
  }

  showMode() {
    this.domeCanvas.hidden = this.flat;
    this.frame.hidden = !this.flat;
    this.toggle.textContent = this.flat ? "dome view" : "flat lens view";
    document.body.dataset.view = this.flat ? "flat" : "dome";
  }

  // The lens needs the frame size (the equidistant stand-in is sized by it), so it is read on the first frame.
  async start() {
    const w = this.video.naturalWidth, h = this.video.naturalHeight;
    for (const c of [this.frame, this.markerCanvas]) { c.width = w; c.height = h; }
    this.lens = await loadLens(this.call, w, h);
    this.dome?.setLens(this.lens);
    document.body.dataset.lens = this.lens.source;
    const loop = () => { this.renderPage(); requestAnimationFrame(loop); };
    requestAnimationFrame(loop);
  }

  // --- touches ---
  touch(e) {
    if (e.phase === "up") { this.marks.delete(e.id); this.ripples.push({ u: e.u, v: e.v, t0: performance.now() }); return; }
    if (!this.marks.has(e.id)) this.ripples.push({ u: e.u, v: e.v, t0: performance.now() });
    this.marks.set(e.id, { u: e.u, v: e.v });
  }

  clearTouches() { this.marks.clear(); }

  // Canvas coordinates put pixel centres at +0.5, the lens model on integers: hence the half pixel.
  markerAt(u, v) {
    const [x, y] = this.lens.skinPixel(u, v);
    return [x + 0.5, y + 0.5];
  }

  drawMarkers() {
    const g = this.markerCanvas.getContext("2d"), { width: w, height: h } = this.markerCanvas;
    const scale = w / 640, now = performance.now();
    g.clearRect(0, 0, w, h);
    for (let i = this.ripples.length - 1; i >= 0; i--) {
      const r = this.ripples[i], age = (now - r.t0) / RIPPLE_MS;
      if (age > 1) { this.ripples.splice(i, 1); continue; }
      const [x, y] = this.markerAt(r.u, r.v);
      // fainter than a marker, so a marker is always the most opaque thing on this layer
      g.strokeStyle = `rgba(255,159,67,${0.6 * (1 - age)})`; g.lineWidth = 3 * scale;
      g.beginPath(); g.arc(x, y, (10 + age * 50) * scale, 0, 2 * Math.PI); g.stroke();
    }
    g.fillStyle = MARKER;
    for (const m of this.marks.values()) {
      const [x, y] = this.markerAt(m.u, m.v);
      g.beginPath(); g.arc(x, y, 12 * scale, 0, 2 * Math.PI); g.fill();
    }
    this.markerCanvas.dataset.markers = String(this.marks.size);
  }

  // The camera frame and the markers into one image, at most once per display frame (the page and an XR
  // session may both ask).
  compose() {
    const now = performance.now();
    if (now - this.composedAt < 8) return;
    this.composedAt = now;
    this.drawMarkers();
    const g = this.frame.getContext("2d");
    g.drawImage(this.video, 0, 0, this.frame.width, this.frame.height);
    g.drawImage(this.markerCanvas, 0, 0);
    this.dome?.upload(this.frame);
  }

  renderPage() {
    this.compose();
    if (this.flat || !this.dome) return;
    const c = this.domeCanvas, w = c.clientWidth, h = c.clientHeight;
    if (!w || !h) return;
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    const gl = this.dome.gl;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.clearColor(0, 0, 0, 1); gl.clear(gl.COLOR_BUFFER_BIT);
    this.dome.draw([0, 0, w, h], perspective(this.fovy, w / h, 0.1, 100), lookAround(this.yaw, this.pitch));
  }

  // Drag to look around the dome, wheel to zoom (the headset's head does this in immersive mode).
  lookWithPointer() {
    const c = this.domeCanvas;
    let from = null;
    c.addEventListener("pointerdown", (e) => { from = { x: e.clientX, y: e.clientY }; c.setPointerCapture(e.pointerId); });
    c.addEventListener("pointermove", (e) => {
      if (!from) return;
      const perPx = this.fovy / c.clientHeight;
      this.yaw -= (e.clientX - from.x) * perPx;
      this.pitch = Math.max(-1.5, Math.min(1.5, this.pitch + (e.clientY - from.y) * perPx));
      from = { x: e.clientX, y: e.clientY };
    });
    for (const ev of ["pointerup", "pointercancel"]) c.addEventListener(ev, () => { from = null; });
    c.addEventListener("wheel", (e) => {
      e.preventDefault();
      this.fovy = Math.max(0.5, Math.min(2.2, this.fovy * Math.exp(e.deltaY * 0.001)));
    }, { passive: false });
  }

  // --- immersive WebXR: the dome around the wearer's head ---
  // onStop: the controller's trigger (select) stops the blimp; onSteer(command|null): the thumbstick holds a move.
  async enterXR({ overlay, onStop, onSteer, onEnd }) {
    const session = await navigator.xr.requestSession("immersive-vr", {
      optionalFeatures: ["local", "dom-overlay"], domOverlay: { root: overlay },
    });
    const gl = this.dome.gl; // created xrCompatible (see createDome)
    await session.updateRenderState({ baseLayer: new XRWebGLLayer(session, gl) });
    const space = await session.requestReferenceSpace("local");
    session.addEventListener("select", onStop);
    session.addEventListener("end", () => { onSteer(null); onEnd(); });
    const frame = (t, xrFrame) => {
      session.requestAnimationFrame(frame);
      onSteer(stickCommand(session.inputSources));
      const pose = xrFrame.getViewerPose(space);
      if (!pose) return;
      this.compose();
      const layer = session.renderState.baseLayer;
      gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer);
      gl.clearColor(0, 0, 0, 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      for (const view of pose.views) {
        const vp = layer.getViewport(view);
        this.dome.draw([vp.x, vp.y, vp.width, vp.height], view.projectionMatrix, rotationOnly(view.transform.inverse.matrix));
      }
    };
    session.requestAnimationFrame(frame);
    return session;
  }
}

// The move a controller's thumbstick asks for (xr-standard mapping: axes 2 and 3), or null when centred.
function stickCommand(inputSources) {
  for (const source of inputSources) {
    const axes = source.gamepad?.axes;
    if (!axes || axes.length < 4) continue;
    const [x, y] = [axes[2], axes[3]];
    if (Math.max(Math.abs(x), Math.abs(y)) < 0.5) continue;
    if (Math.abs(y) >= Math.abs(x)) return y < 0 ? "forward" : "backward";
    return x < 0 ? "turn_left" : "turn_right";
  }
  return null;
}
