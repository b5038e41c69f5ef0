// The wearer's page: the fisheye view with touch markers, the HUD (stop and gauges), hold-to-move motion,
// answers, face and voice, and what happens as sentences.

import { Feelium } from "./api.js";
import { Describer } from "./describe.js";
import { Gauges } from "./gauges.js";
import { FisheyeView } from "./view.js";

const $ = (s) => document.querySelector(s);
const log = $("#log");

function say(text, type = "note") {
  const li = document.createElement("li");
  li.dataset.type = type;
  const time = document.createElement("time");
  time.textContent = new Date().toLocaleTimeString();
  li.append(time, " ", text);
  log.prepend(li);
  while (log.children.length > 200) log.lastChild.remove();
}

// --- the view ---
const view = new FisheyeView({
  video: $("#video"), frame: $("#frame"), dome: $("#dome"), markers: $("#markers"), toggle: $("#view-toggle"),
  call: Feelium.call,
});
Feelium.ready.then(() => { $("#video").src = Feelium.streamUrl("/video/front.mjpeg"); });

// --- gauges and events ---
const gauges = new Gauges(Feelium.call);
gauges.start();
const describer = new Describer();
Feelium.events((item) => {
  if (item.type === "touch") view.touch(item.event);
  if (item.type === "reset") view.clearTouches();
  const sentence = describer.describe(item);
  if (sentence) say(sentence, item.type);
}, (up) => gauges.setStream(up));

// --- motion: a dead man; the command is refreshed every 150 ms while held, with a 500 ms hold ---
let held = null, timer = null;
async function send(cmd) {
  try {
    await Feelium.call("POST", "/motion", { command: cmd, hold_ms: 500 });
    if (cmd !== "stop") $("#takeover").hidden = true;
  } catch (err) {
    if (err.body?.error === "not_in_control") refused(err.body);
    else say(`The blimp refused "${cmd}": ${err.message}`, "error");
  }
}
// Another client steers (409): drop the held command *without* a stop (a stop from here would stop the other
// client's blimp and take its lease) and offer the explicit take-over.
function refused(info) {
  if (held) { document.querySelector(`[data-cmd="${held}"]`)?.classList.remove("active"); clearInterval(timer); held = null; }
  const box = $("#takeover");
  if (box.hidden) say(`${info.controller} is steering the blimp; "take over" to steer it yourself.`, "error");
  box.querySelector("span").textContent = `${info.controller} is steering.`;
  box.hidden = false;
}
// Taking over is a stop from this page: it hands this page the lease (docs/api.md, "A stop sticks"), so the
// hand-over always passes through a stopped blimp; the next held move is this page's.
$("#takeover button").addEventListener("click", async () => {
  await send("stop");
  $("#takeover").hidden = true;
  say("You steer the blimp now; it stopped for the hand-over.");
});
function hold(cmd) {
  if (held === cmd) return;
  release();
  held = cmd;
  document.querySelector(`[data-cmd="${cmd}"]`)?.classList.add("active");
  send(cmd); timer = setInterval(() => send(cmd), 150);
}
function release() {
  if (!held) return;
  document.querySelector(`[data-cmd="${held}"]`)?.classList.remove("active");
  clearInterval(timer); held = null; send("stop");
}
// Stop drops whatever is held and sends stop even when nothing is (another client may be steering).
function stop() {
  if (held) release(); else send("stop");
  const button = $("#stop");
  button.classList.add("pressed");
  setTimeout(() => button.classList.remove("pressed"), 300);
}
$("#stop").addEventListener("click", stop);
for (const b of document.querySelectorAll("#motion button")) {
  b.addEventListener("pointerdown", (e) => { e.preventDefault(); hold(b.dataset.cmd); });
  for (const ev of ["pointerup", "pointerleave", "pointercancel"]) b.addEventListener(ev, release);
}
const keys = { KeyW: "forward", ArrowUp: "forward", KeyS: "backward", ArrowDown: "backward", KeyA: "turn_left",
  ArrowLeft: "turn_left", KeyQ: "turn_left", KeyD: "turn_right", ArrowRight: "turn_right", KeyE: "turn_right",
  KeyR: "up", KeyF: "down" };
addEventListener("keydown", (e) => {
  if (e.target.tagName === "INPUT") return;
  if (e.code === "Space") { e.preventDefault(); if (!e.repeat) stop(); return; }
  if (keys[e.code]) { e.preventDefault(); hold(keys[e.code]); }
});
addEventListener("keyup", (e) => { if (keys[e.code] === held) release(); });
addEventListener("blur", release);

// --- immersive mode: the dome in the headset; STOP stays reachable (DOM overlay, trigger, space bar) ---
async function setupXR() {
  if (!navigator.xr || !view.dome || !(await navigator.xr.isSessionSupported("immersive-vr"))) return;
  const button = $("#xr");
  button.hidden = false;
  let session = null, stick = null;
  const steer = (cmd) => { if (cmd === stick) return; stick = cmd; if (cmd) hold(cmd); else release(); };
  button.addEventListener("click", async () => {
    if (session) { session.end(); return; }
    try {
      session = await view.enterXR({
        overlay: $("#hud"), onStop: stop, onSteer: steer,
        onEnd: () => { session = null; document.body.classList.remove("immersive"); button.textContent = "enter immersive view"; },
      });
    } catch (err) { say(`Immersive view failed: ${err.message}`, "error"); return; }
    document.body.classList.add("immersive");
    button.textContent = "exit immersive view";
    say("Immersive view: the controller's trigger or the space bar stops the blimp.");
  });
}
setupXR();

// --- answers for the interaction engine ---
for (const b of document.querySelectorAll("[data-action]")) {
  b.addEventListener("click", () => Feelium.call("POST", `/actions/${b.dataset.action}`).catch((e) => say(e.message, "error")));
}
$("#guess").addEventListener("submit", (e) => {
  e.preventDefault();
  Feelium.call("POST", "/actions/guess", { word: e.target.word.value }).catch((err) => say(err.message, "error"));
  e.target.word.value = "";
});

// --- pairing another device (a headset app, a phone for the partner page) with a one-time code ---
$("#pair-btn").addEventListener("click", async () => {
  try {
    const { data } = await Feelium.call("POST", "/pair/code");
    $("#pair-code").textContent = `code ${data.code} (once, ${Math.round(data.expires_in_s)} s): open ${location.origin}/partner `
      + "or the headset app on the other device and enter it";
  } catch (err) { $("#pair-code").textContent = err.message; }
});

// --- face and voice need the camera and microphone, which browsers give only to secure pages ---
const mediaAllowed = window.isSecureContext && Boolean(navigator.mediaDevices?.getUserMedia);
if (!mediaAllowed) {
  for (const id of ["#face-btn", "#talk-btn"]) $(id).disabled = true;
  const why = $("#media-why");
  why.hidden = false;
  why.textContent = `Face and talk are off because this page came over plain HTTP (${location.host}): browsers let `
    + "only secure pages (HTTPS, or localhost itself) use the camera and microphone (getUserMedia needs a secure "
    + "context). Give the blimp a certificate ([http] tls_cert and tls_key, see docs/api.md) and open "
    + `https://${location.host}/ instead. Listening works either way.`;
}

// The face: one frame at a time, the next no sooner than FACE_PERIOD_MS after the last was sent, under the
// per-client action limit (4/s, shared with the wearer's actions); a frame refused with 429 is just skipped.
const FACE_PERIOD_MS = 300;
let faceOn = false;
$("#face-btn").addEventListener("click", async (e) => {
  if (faceOn) { faceOn = false; e.target.classList.remove("on"); return; }
  const stream = await navigator.mediaDevices.getUserMedia({ video: { width: 320, height: 240 } });
  const cam = Object.assign(document.createElement("video"), { srcObject: stream, muted: true, playsInline: true });
  await cam.play();
  const c = Object.assign(document.createElement("canvas"), { width: 320, height: 240 });
  faceOn = true; e.target.classList.add("on");
  while (faceOn) {
    const sent = performance.now();
    c.getContext("2d").drawImage(cam, 0, 0, c.width, c.height);
    const jpeg = await new Promise((done) => c.toBlob(done, "image/jpeg", 0.7));
    try { if (jpeg) await Feelium.call("PUT", "/face", jpeg, "image/jpeg"); }
    catch (err) { if (err.status !== 429) say(err.message, "error"); }
    await new Promise((r) => setTimeout(r, Math.max(0, FACE_PERIOD_MS - (performance.now() - sent))));
  }
  stream.getTracks().forEach((t) => t.stop());
});

// Speech both ways on one WebSocket (GET /speech/stream, docs/api.md): binary frames of the room's audio in,
// PCM16 chunks of the wearer's voice out. Open while listening or talking.
const TALK_CHUNK_S = 0.08; // ~12 chunks a second, well under the 20/s speech limit
let audioCtx = null, speech = null, listening = false, talking = false, playAt = 0;
function speechSocket() {
  if (speech && speech.readyState <= WebSocket.OPEN) return speech;
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  speech = new WebSocket(`${scheme}://${location.host}${Feelium.streamUrl("/speech/stream", { rate: audioCtx.sampleRate })}`);
  speech.binaryType = "arraybuffer";
  speech.onmessage = (m) => { if (listening && m.data instanceof ArrayBuffer) play(m.data); };
  speech.onclose = () => { speech = null; if (listening || talking) setTimeout(() => (listening || talking) && speechSocket(), 1000); };
  return speech;
}
function closeSpeechIfIdle() { if (!listening && !talking && speech) speech.close(); }
function play(frame) {
  const d = new DataView(frame), headerBytes = d.getUint16(2, true), rate = d.getUint32(4, true);
  const pcm = new Int16Array(frame, headerBytes, (frame.byteLength - headerBytes) >> 1);
  const buf = audioCtx.createBuffer(1, pcm.length, rate), ch = buf.getChannelData(0);
  for (let i = 0; i < pcm.length; i++) ch[i] = pcm[i] / 32768;
  const node = audioCtx.createBufferSource(); node.buffer = buf; node.connect(audioCtx.destination);
  // keep at most ~300 ms queued, so lateness never accumulates
  playAt = Math.max(playAt, audioCtx.currentTime + 0.05);
  if (playAt > audioCtx.currentTime + 0.3) playAt = audioCtx.currentTime + 0.05;
  node.start(playAt); playAt += buf.duration;
}
let pending = [];
async function micSetup() {
  const stream = await navigator.mediaDevices.getUserMedia({ audio: true });
  const src = audioCtx.createMediaStreamSource(stream), proc = audioCtx.createScriptProcessor(2048, 1, 1);
  proc.onaudioprocess = (ev) => {
    if (!talking) { pending = []; return; }
    pending.push(Float32Array.from(ev.inputBuffer.getChannelData(0)));
    if (pending.reduce((n, b) => n + b.length, 0) < TALK_CHUNK_S * audioCtx.sampleRate) return;
    const samples = new Int16Array(pending.reduce((n, b) => n + b.length, 0));
    let i = 0;
    for (const b of pending) for (const s of b) samples[i++] = Math.max(-1, Math.min(1, s)) * 32767;
    pending = [];
    if (speech && speech.readyState === WebSocket.OPEN) speech.send(samples.buffer);
  };
  src.connect(proc); proc.connect(audioCtx.destination);
}
let micReady = false;
const talk = $("#talk-btn");
talk.addEventListener("pointerdown", async () => {
  audioCtx = audioCtx || new AudioContext();
  if (!micReady) { await micSetup(); micReady = true; }
  talking = true; talk.classList.add("on"); speechSocket();
});
for (const ev of ["pointerup", "pointerleave"]) {
  talk.addEventListener(ev, () => { talking = false; talk.classList.remove("on"); closeSpeechIfIdle(); });
}
$("#listen-btn").addEventListener("click", (e) => {
  listening = !listening; e.target.classList.toggle("on", listening);
  audioCtx = audioCtx || new AudioContext();
  if (listening) speechSocket(); else closeSpeechIfIdle();
});

// For the console and the browser tests: the lens in use and the view.
window.feeliumView = view;
