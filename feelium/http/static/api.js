// The headset API from a browser: the token, JSON calls, and one event stream with resume.
"use strict";
const Feelium = (() => {
  const hash = new URLSearchParams(location.hash.slice(1));
  if (hash.get("token")) sessionStorage.setItem("feelium-token", hash.get("token"));
  const token = sessionStorage.getItem("feelium-token") || "";
  const base = "/api/v1";

  // The token goes into an HttpOnly cookie once, so video, EventSource and WebSocket URLs carry no secret.
  const ready = fetch(`${base}/session`, { method: "POST", headers: { Authorization: `Bearer ${token}` } });
  function streamUrl(path) { return `${base}${path}`; }

  async function call(method, path, body, contentType) {
    const headers = { Authorization: `Bearer ${token}` };
    let payload = body;
    if (body !== undefined && !(body instanceof Blob) && !(body instanceof FormData)) {
      headers["Content-Type"] = "application/json"; payload = JSON.stringify(body);
    } else if (contentType) headers["Content-Type"] = contentType;
    const resp = await fetch(base + path, { method, headers, body: payload });
    if (resp.status === 204) return null;
    const type = resp.headers.get("Content-Type") || "";
    const data = type.includes("json") ? await resp.json() : await resp.blob();
    if (!resp.ok) throw new Error(`${resp.status} ${data.message || data.error || ""}`);
    return { data, resp };
  }

  // One stream of {seq, epoch, type, event}: WebSocket first, Server-Sent Events if that fails; resumes after
  // the last event with its token EPOCH:SEQ (another epoch = the daemon restarted: the server sends a reset).
  function events(onEvent, onStatus) {
    let last = null, failures = 0, useSse = false;
    const deliver = (item) => {
      if (last === null || item.epoch !== last.epoch || item.seq > last.seq || item.type === "reset") {
        last = { epoch: item.epoch, seq: item.seq }; onEvent(item);
      }
    };
    function connect() {
      const after = last === null ? "" : `?after=${encodeURIComponent(`${last.epoch}:${last.seq}`)}`;
      if (!useSse && "WebSocket" in window) {
        const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}${streamUrl("/events/ws")}${after}`);
        ws.onopen = () => { failures = 0; onStatus(true); };
        ws.onmessage = (m) => deliver(JSON.parse(m.data));
        ws.onclose = () => { onStatus(false); if (++failures > 2) useSse = true; setTimeout(connect, 500); };
      } else {
        const es = new EventSource(streamUrl("/events/stream") + after);
        const handler = (m) => deliver(JSON.parse(m.data));
        for (const t of ["touch", "presence", "interaction", "wearer_action", "reset"]) es.addEventListener(t, handler);
        es.onopen = () => onStatus(true);
        es.onerror = () => onStatus(false);
      }
    }
    ready.then(connect);
  }
  return { token, call, streamUrl, ready, events };
})();
