// The wearer's view: video with touch markers, hold-to-move motion, answers, face and voice, state, events, WebXR.
"use strict";
const $ = (s) => document.querySelector(s);
const video = $("#video"), overlay = $("#overlay"), log = $("#log"), linkBadge = $("#link");
Feelium.ready.then(() => { video.src = Feelium.streamUrl("/video/front.mjpeg"); });
let videoFrames = 0;
video.addEventListener("load", () => videoFrames++);

function logLine(text) {
  const li = document.createElement("li");
  li.textContent = `${new Date().toLocaleTimeString()} ${text}`;
  log.prepend(li);
  while (log.children.length > 200) log.lastChild.remove();
}

// --- touch markers and ripples (normalised u, v across the membrane) ---
const marks = new Map(); // contact id -> {u, v, phase, t0}
const ripples = [];
function onTouch(e) {
  const u = e.u ?? 0.5, v = e.v ?? 0.5;
  if (e.phase === "up") { marks.delete(e.id); ripples.push({ u, v, t0: performance.now() }); }
  else { if (!marks.has(e.id)) ripples.push({ u, v, t0: performance.now() }); marks.set(e.id, { u, v, kind: e.kind }); }
  document.body.dataset.touches = String(marks.size);
  document.body.dataset.lastTouch = String(e.id);
}
function draw() {
  const w = overlay.clientWidth, h = overlay.clientHeight;
  if (overlay.width !== w || overlay.height !== h) { overlay.width = w; overlay.height = h; }
  const g = overlay.getContext("2d");
  g.clearRect(0, 0, w, h);
  const now = performance.now();
  for (let i = ripples.length - 1; i >= 0; i--) {
    const r = ripples[i], age = (now - r.t0) / 900;
    if (age > 1) { ripples.splice(i, 1); continue; }
    g.strokeStyle = `rgba(255,159,67,${1 - age})`; g.lineWidth = 3;
    g.beginPath(); g.arc(r.u * w, r.v * h, 10 + age * 60, 0, 2 * Math.PI); g.stroke();
  }
  for (const m of marks.values()) {
    g.fillStyle = "rgba(255,159,67,0.85)";
    g.beginPath(); g.arc(m.u * w, m.v * h, 14, 0, 2 * Math.PI); g.fill();
  }
  overlay.dataset.markers = String(marks.size);
  requestAnimationFrame(draw);
}
requestAnimationFrame(draw);

Feelium.events((item) => {
  if (item.type === "touch") onTouch(item.event);
  if (item.type === "reset") { marks.clear(); logLine("(missed events; state re-read)"); }
  logLine(`#${item.seq} ${item.type} ${JSON.stringify(item.event)}`);
}, (ok) => { linkBadge.textContent = ok ? "live" : "reconnecting"; linkBadge.className = `badge ${ok ? "ok" : "bad"}`; });

// --- motion: a dead man; the command is refreshed every 150 ms while held, with a 500 ms hold ---
let held = null, timer = null;
async function send(cmd) {
  try { await Feelium.call("POST", "/motion", { command: cmd, hold_ms: 500 }); }
  catch (err) { logLine(`motion ${cmd}: ${err.message}`); }
}
function hold(cmd) {
  if (held === cmd) return;
  release();
  if (cmd === "stop") { send("stop"); return; }
  held = cmd;
  document.querySelector(`[data-cmd="${cmd}"]`)?.classList.add("active");
  send(cmd); timer = setInterval(() => send(cmd), 150);
}
function release() {
  if (!held) return;
  document.querySelector(`[data-cmd="${held}"]`)?.classList.remove("active");
  clearInterval(timer); held = null; send("stop");
}
for (const b of document.querySelectorAll("#motion button")) {
  b.addEventListener("pointerdown", (e) => { e.preventDefault(); hold(b.dataset.cmd); });
  for (const ev of ["pointerup", "pointerleave", "pointercancel"]) b.addEventListener(ev, release);
}
const keys = { KeyW: "forward", ArrowUp: "forward", KeyS: "backward", ArrowDown: "backward", KeyA: "turn_left",
  ArrowLeft: "turn_left", KeyQ: "turn_left", KeyD: "turn_right", ArrowRight: "turn_right", KeyE: "turn_right",
  KeyR: "up", KeyF: "down", Space: "stop" };
addEventListener("keydown", (e) => { if (e.target.tagName !== "INPUT" && keys[e.code]) { e.preventDefault(); hold(keys[e.code]); } });
addEventListener("keyup", (e) => { if (keys[e.code] === held) release(); });
addEventListener("blur", release);

// --- answers for the interaction engine ---
for (const b of document.querySelectorAll("[data-action]")) {
  b.addEventListener("click", () => Feelium.call("POST", `/actions/${b.dataset.action}`).catch((e) => logLine(e.message)));
}
$("#guess").addEventListener("submit", (e) => {
  e.preventDefault();
  Feelium.call("POST", "/actions/guess", { word: e.target.word.value }).catch((err) => logLine(err.message));
  e.target.word.value = "";
});

// --- state ---
async function pollState() {
  try { $("#state").textContent = JSON.stringify((await Feelium.call("GET", "/state")).data, null, 1); }
  catch (err) { $("#state").textContent = err.message; }
}
setInterval(pollState, 1000); pollState();

// --- face: the camera as JPEG frames, newest wins on the blimp ---
let faceTimer = null;
$("#face-btn").addEventListener("click", async (e) => {
  if (faceTimer) { clearInterval(faceTimer); faceTimer = null; e.target.classList.remove("on"); return; }
  const stream = await navigator.mediaDevices.getUserMedia({ video: { width: 320, height: 240 } });
  const cam = Object.assign(document.createElement("video"), { srcObject: stream, muted: true, playsInline: true });
  await cam.play();
  const c = Object.assign(document.createElement("canvas"), { width: 320, height: 240 });
  e.target.classList.add("on");
  faceTimer = setInterval(() => {
    c.getContext("2d").drawImage(cam, 0, 0, c.width, c.height);
    c.toBlob((b) => b && Feelium.call("PUT", "/face", b, "image/jpeg").catch((err) => logLine(err.message)), "image/jpeg", 0.7);
  }, 200);
});

// --- voice: PCM16 WAV chunks both ways ---
function wav(samples, rate) {
  const buf = new ArrayBuffer(44 + samples.length * 2), d = new DataView(buf);
  const str = (o, s) => [...s].forEach((ch, i) => d.setUint8(o + i, ch.charCodeAt(0)));
  str(0, "RIFF"); d.setUint32(4, 36 + samples.length * 2, true); str(8, "WAVEfmt "); d.setUint32(16, 16, true);
  d.setUint16(20, 1, true); d.setUint16(22, 1, true); d.setUint32(24, rate, true); d.setUint32(28, rate * 2, true);
  d.setUint16(32, 2, true); d.setUint16(34, 16, true); str(36, "data"); d.setUint32(40, samples.length * 2, true);
  samples.forEach((s, i) => d.setInt16(44 + i * 2, Math.max(-1, Math.min(1, s)) * 32767, true));
  return new Blob([buf], { type: "audio/wav" });
}
let audioCtx = null, talking = false;
async function micSetup() {
  audioCtx = audioCtx || new AudioContext();
  const stream = await navigator.mediaDevices.getUserMedia({ audio: true });
  const src = audioCtx.createMediaStreamSource(stream), proc = audioCtx.createScriptProcessor(2048, 1, 1);
  proc.onaudioprocess = (ev) => { if (talking) Feelium.call("POST", "/speech", wav(ev.inputBuffer.getChannelData(0), audioCtx.sampleRate), "audio/wav").catch(() => {}); };
  src.connect(proc); proc.connect(audioCtx.destination);
}
const talk = $("#talk-btn");
talk.addEventListener("pointerdown", async () => { if (!audioCtx) await micSetup(); talking = true; talk.classList.add("on"); });
for (const ev of ["pointerup", "pointerleave"]) talk.addEventListener(ev, () => { talking = false; talk.classList.remove("on"); });
let listening = false;
$("#listen-btn").addEventListener("click", async (e) => {
  listening = !listening; e.target.classList.toggle("on", listening);
  audioCtx = audioCtx || new AudioContext();
  let after = 0, playAt = 0;
  while (listening) {
    try {
      const r = await Feelium.call("GET", `/speech?after=${after}&timeout=2`);
      if (!r) continue;
      after = Number(r.resp.headers.get("X-Speech-Seq"));
      const buf = await audioCtx.decodeAudioData(await r.data.arrayBuffer());
      const node = audioCtx.createBufferSource(); node.buffer = buf; node.connect(audioCtx.destination);
      // keep at most ~300 ms queued, so lateness never accumulates
      playAt = Math.max(playAt, audioCtx.currentTime + 0.05);
      if (playAt > audioCtx.currentTime + 0.3) playAt = audioCtx.currentTime + 0.05;
      node.start(playAt); playAt += buf.duration;
    } catch (err) { logLine(`listen: ${err.message}`); await new Promise((r) => setTimeout(r, 1000)); }
  }
});

// --- immersive WebXR: the live video on a large panel in front of the wearer ---
async function setupXR() {
  if (!navigator.xr) return;
  const mode = (await navigator.xr.isSessionSupported("immersive-vr")) ? "immersive-vr" : null;
  if (!mode) return;
  const btn = $("#xr"); btn.hidden = false;
  btn.addEventListener("click", async () => {
    const session = await navigator.xr.requestSession(mode, { optionalFeatures: ["local-floor"] });
    const canvas = document.createElement("canvas"), gl = canvas.getContext("webgl", { xrCompatible: true });
    await session.updateRenderState({ baseLayer: new XRWebGLLayer(session, gl) });
    const space = await session.requestReferenceSpace("local");
    const vs = "attribute vec2 p;uniform mat4 proj,view;varying vec2 uv;void main(){uv=vec2(p.x*.5+.5,.5-p.y*.5);gl_Position=proj*view*vec4(p.x*1.6,p.y*1.2,-2.0,1.0);}";
    const fs = "precision mediump float;uniform sampler2D tex;varying vec2 uv;void main(){gl_FragColor=texture2D(tex,uv);}";
    const prog = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s); gl.attachShader(prog, s);
    }
    gl.linkProgram(prog); gl.useProgram(prog);
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, 1, 1]), gl.STATIC_DRAW);
    const loc = gl.getAttribLocation(prog, "p"); gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, 2, gl.FLOAT, false, 0, 0);
    const tex = gl.createTexture(); gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE); gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    const comp = document.createElement("canvas"); // the video with the touch overlay, uploaded as the texture
    const frame = (t, xrFrame) => {
      session.requestAnimationFrame(frame);
      const pose = xrFrame.getViewerPose(space); if (!pose) return;
      const layer = session.renderState.baseLayer;
      gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer); gl.clearColor(0, 0, 0, 1); gl.clear(gl.COLOR_BUFFER_BIT);
      comp.width = video.naturalWidth || 640; comp.height = video.naturalHeight || 480;
      const cg = comp.getContext("2d"); cg.drawImage(video, 0, 0, comp.width, comp.height); cg.drawImage(overlay, 0, 0, comp.width, comp.height);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, comp);
      for (const view of pose.views) {
        const vp = layer.getViewport(view); gl.viewport(vp.x, vp.y, vp.width, vp.height);
        gl.uniformMatrix4fv(gl.getUniformLocation(prog, "proj"), false, view.projectionMatrix);
        gl.uniformMatrix4fv(gl.getUniformLocation(prog, "view"), false, view.transform.inverse.matrix);
        gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
      }
    };
    session.requestAnimationFrame(frame);
  });
}
setupXR();
window.feeliumDebug = { get videoFrames() { return videoFrames; }, markers: () => marks.size };
