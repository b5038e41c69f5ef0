// The headset API from a browser: authorisation (token, session cookie, pairing), JSON calls, and one event
// stream with resume. Both pages (wearer and partner) load this module first.

const BASE = "/api/v1";
const TOKEN_KEY = "feelium-token";

// `feelium http-url` hands the token over in the URL fragment (never sent to the server); keep it for this tab
// and take it out of the address bar, so it is neither bookmarked nor shown over the wearer's shoulder.
const hash = new URLSearchParams(location.hash.slice(1));
if (hash.get("token")) {
  sessionStorage.setItem(TOKEN_KEY, hash.get("token"));
  history.replaceState(null, "", location.pathname + location.search);
}
let token = sessionStorage.getItem(TOKEN_KEY) || "";

// A stable id per tab keeps this page's motion lease and rate limits apart from other clients on the address.
const clientId = sessionStorage.getItem("feelium-client") || `browser-${Math.random().toString(36).slice(2, 10)}`;
sessionStorage.setItem("feelium-client", clientId);

function authHeaders() {
  // Without a token of its own, a page relies on the HttpOnly session cookie that fetch sends by itself.
  const headers = { "X-Feelium-Client": clientId };
  if (token) headers.Authorization = `Bearer ${token}`;
  return headers;
}

// POST /session with the token sets the cookie that <img>, EventSource and WebSocket carry (they cannot set
// headers). Without a token it still succeeds when this browser already holds a valid cookie: that is how a
// partner page opened in a new tab from the wearer's page is authorised without a second pairing.
async function openSession() {
  const resp = await fetch(`${BASE}/session`, { method: "POST", headers: authHeaders() });
  return resp.ok;
}

// The pairing dialog: the same one-time code a native headset uses (`feelium pair` on the blimp, or the wearer
// page's "pair a device" button), exchanged at POST /pair for the token.
function askForPairing(reason) {
  return new Promise((resolve) => {
    const dialog = document.createElement("dialog");
    dialog.id = "pairing";
    dialog.innerHTML = `
      <form method="dialog">
        <h2>Pair this browser with the blimp</h2>
        <p class="why"></p>
        <p>Enter a pairing code: run <code>feelium pair</code> on the blimp, or press <em>pair a device</em>
           on the wearer's page. A code works once, for two minutes.</p>
        <label>pairing code <input name="code" autocomplete="one-time-code" inputmode="numeric" required
               placeholder="1234-5678" maxlength="32"></label>
        <button>pair</button>
        <p class="error" role="alert"></p>
      </form>`;
    dialog.querySelector(".why").textContent = reason;
    const form = dialog.querySelector("form"), error = dialog.querySelector(".error");
    form.addEventListener("submit", async (e) => {
      e.preventDefault();
      error.textContent = "";
      const resp = await fetch(`${BASE}/pair`, {
        method: "POST", headers: { "Content-Type": "application/json", "X-Feelium-Client": clientId },
        body: JSON.stringify({ code: form.code.value }),
      });
      const data = await resp.json().catch(() => ({}));
      if (!resp.ok) { error.textContent = data.message || `pairing failed (${resp.status})`; return; }
      token = data.token;
      sessionStorage.setItem(TOKEN_KEY, token);
      dialog.close(); dialog.remove();
      resolve();
    });
    // Escape would close the dialog and leave a page that can do nothing: it stays until paired.
    dialog.addEventListener("cancel", (e) => e.preventDefault());
    document.body.append(dialog);
    dialog.showModal();
  });
}

async function authorise() {
  let reason = token ? "The token this page was opened with is no longer valid (it may have been rotated)."
    : "This browser holds no token for the blimp yet.";
  while (!(await openSession())) {
    await askForPairing(reason);
    reason = "";
  }
}
const ready = authorise();

// A 401 later means the token was rotated under us: pair again once, then retry the request.
let reauthorising = null;
function reauthorise() {
  if (!reauthorising) {
    token = ""; sessionStorage.removeItem(TOKEN_KEY);
    reauthorising = askForPairing("The blimp's token changed, so this page must pair again.")
      .then(openSession).finally(() => { reauthorising = null; });
  }
  return reauthorising;
}

async function call(method, path, body, contentType, retried = false) {
  await ready;
  const headers = authHeaders();
  let payload = body;
  if (body !== undefined && !(body instanceof Blob) && !(body instanceof FormData)) {
    headers["Content-Type"] = "application/json"; payload = JSON.stringify(body);
  } else if (contentType) headers["Content-Type"] = contentType;
  const resp = await fetch(BASE + path, { method, headers, body: payload });
  if (resp.status === 401 && !retried) { await reauthorise(); return call(method, path, body, contentType, true); }
  if (resp.status === 204) return null;
  const type = resp.headers.get("Content-Type") || "";
  const data = type.includes("json") ? await resp.json() : await resp.blob();
  if (!resp.ok) {
    // The status and the JSON error body travel with the error, so a caller can act on its code (not_in_control).
    throw Object.assign(new Error(`${resp.status} ${data.message || data.error || ""}`), { status: resp.status, body: data });
  }
  return { data, resp };
}

// URLs for <img>, EventSource and WebSocket, which cannot send X-Feelium-Client: the id goes in the query.
function streamUrl(path, params = {}) {
  return `${BASE}${path}?${new URLSearchParams({ ...params, client: clientId })}`;
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
    const after = last === null ? {} : { after: `${last.epoch}:${last.seq}` };
    if (!useSse && "WebSocket" in window) {
      const scheme = location.protocol === "https:" ? "wss" : "ws";
      const ws = new WebSocket(`${scheme}://${location.host}${streamUrl("/events/ws", after)}`);
      ws.onopen = () => { failures = 0; onStatus(true); };
      ws.onmessage = (m) => deliver(JSON.parse(m.data));
      ws.onclose = () => { onStatus(false); if (++failures > 2) useSse = true; setTimeout(connect, 500); };
    } else {
      const es = new EventSource(streamUrl("/events/stream", after));
      const handler = (m) => deliver(JSON.parse(m.data));
      for (const t of ["touch", "presence", "interaction", "wearer_action", "reset"]) es.addEventListener(t, handler);
      es.onopen = () => onStatus(true);
      es.onerror = () => onStatus(false);
    }
  }
  ready.then(connect);
}

export const Feelium = { call, streamUrl, ready, events, clientId };
// Page scripts are modules; the global lets a console (and the browser tests) call the API by hand.
window.Feelium = Feelium;
