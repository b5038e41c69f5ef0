"""The browser client in Debian's Chromium (Playwright drives it; no browser is downloaded).

On a machine without Chromium these tests skip, saying how to get it, so the README's test command
passes on a fresh Debian machine; in CI (``CI=true``, where `.ci/run` installs it from
`.ci/apt-packages.txt`) a missing browser is a failure, as for the Betaflight SITL tests.
"""

from __future__ import annotations

import json
import math
import os
import re
import socket
import time
import urllib.error
import urllib.request
from decimal import ROUND_HALF_UP, Decimal

import numpy as np
import pytest

pytestmark = pytest.mark.slow

CHROMIUM = "/usr/bin/chromium"
# The machine's own mDNS name is one of the daemon's allowed hosts (feelium/http/hosts.py); mapped to the loopback
# address it reaches the test daemon under a name, which browsers treat as plain HTTP (not a secure context),
# exactly as a wearer opening http://blimp.local:8080/ would.
PLAIN_HOST = f"{socket.gethostname().split('.')[0]}.local"
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", f"--host-resolver-rules=MAP {PLAIN_HOST} 127.0.0.1",
    "--use-fake-device-for-media-stream", "--use-fake-ui-for-media-stream", "--autoplay-policy=no-user-gesture-required",
]  # fmt: skip


@pytest.fixture(scope="module")
def browser():  # type: ignore[no-untyped-def]
    if not os.path.exists(CHROMIUM):
        reason = f"{CHROMIUM} is missing: sudo apt-get install chromium (listed in .ci/apt-packages.txt)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(reason)
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        yield b
        b.close()


# The documented assumption of the browser client (docs/api.md, "The browser client"): the skin's sensitive
# patch is centred on the front camera's axis, u to the wearer's right, v down, spanning these angles.
SKIN_PATCH_DEG = (100.0, 75.0)


def api(live, method: str, path: str, body: dict | None = None) -> dict | None:  # type: ignore[no-untyped-def]
    headers = dict(live.auth)
    data = None
    if body is not None:
        headers["Content-Type"] = "application/json"
        data = json.dumps(body).encode()
    req = urllib.request.Request(f"{live.api}{path}", data=data, headers=headers, method=method)
    with urllib.request.urlopen(req, timeout=5) as resp:
        return json.load(resp) if resp.status != 204 else None


def motion_state(live) -> dict:  # type: ignore[no-untyped-def]
    state = api(live, "GET", "/motion")
    assert state is not None
    return state


def lens_model(live) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """K and D of the front lens: GET /lens, or the client's documented stand-in where the route is missing."""
    try:
        lens = api(live, "GET", "/lens")
    except urllib.error.HTTPError as exc:
        assert exc.code == 404
        w, h = 640, 480  # the sim front camera's frames; the stand-in is the simulator's 180-degree equidistant lens
        f = min(w, h) / 2 / (math.pi / 2)
        return np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]]), np.zeros(4)
    assert lens is not None
    return np.array(lens["K"], float), np.array(lens["D"], float)


def skin_direction(u: float, v: float) -> np.ndarray:
    az, el = math.radians((u - 0.5) * SKIN_PATCH_DEG[0]), math.radians((0.5 - v) * SKIN_PATCH_DEG[1])
    return np.array([math.sin(az) * math.cos(el), -math.sin(el), math.cos(az) * math.cos(el)])


def expected_pixel(live, u: float, v: float) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    import cv2

    K, D = lens_model(live)
    points, _ = cv2.fisheye.projectPoints(skin_direction(u, v).reshape(1, 1, 3), np.zeros(3), np.zeros(3), K, D)
    return float(points[0, 0, 0]), float(points[0, 0, 1])


MARKER_RADIUS_PX = 12  # feelium/http/static/view.js, at 640 px wide frames


def dome_centroid(live, centre, radius, size, f) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """Where the centroid of a disc drawn in the fisheye frame lands on a straight-ahead pinhole view."""
    import cv2

    K, D = lens_model(live)
    ys, xs = np.mgrid[-radius:radius:0.25, -radius:radius:0.25]
    inside = np.hypot(xs, ys) <= radius
    pixels = np.stack([xs[inside] + centre[0], ys[inside] + centre[1]], axis=-1).reshape(-1, 1, 2)
    normalised = cv2.fisheye.undistortPoints(pixels, K, D).reshape(-1, 2)  # x/z, y/z
    return size[0] / 2 + f * float(normalised[:, 0].mean()), size[1] / 2 + f * float(normalised[:, 1].mean())


def open_wearer(browser, live, host: str = "127.0.0.1", context=None):  # type: ignore[no-untyped-def]
    """The wearer page as `feelium http-url` opens it (token in the fragment), once its first frame is shown."""
    page = context.new_page() if context else browser.new_page(viewport={"width": 1100, "height": 800})
    page.errors = []
    page.on("pageerror", lambda exc: page.errors.append(str(exc)))
    page.goto(f"http://{host}:{live.port}/#token={live.token}", wait_until="domcontentloaded")
    page.wait_for_function("document.body.dataset.lens", timeout=15000)
    return page


# One displayed frame, rendered now (a held touch keeps moving a little, so both views must show the same
# moment): the centroid of the marker layer's most opaque pixels (the markers; ripples are fainter), in pixels of
# the fisheye frame, the u, v the page placed them by, and a copy of the dome canvas for DOME_CENTROID.
RENDER_NOW = """() => {
  const view = window.feeliumView;
  view.composedAt = -Infinity;
  view.renderPage();
  const c = document.querySelector('#markers'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let n = 0, sx = 0, sy = 0;
  for (let i = 3; i < d.length; i += 4) if (d[i] > 200) { const p = (i - 3) / 4; n++; sx += p % c.width; sy += Math.floor(p / c.width); }
  const dome = document.querySelector('#dome'), gl = dome.getContext('webgl');
  window.domeSnapshot = new Uint8Array(dome.width * dome.height * 4);
  gl.readPixels(0, 0, dome.width, dome.height, gl.RGBA, gl.UNSIGNED_BYTE, window.domeSnapshot);
  return { n, x: sx / n, y: sy / n, marks: [...view.marks.values()], dome: [dome.width, dome.height] };
}"""

# Orange marker pixels of that dome copy within r of (x, y), as a centroid (pixel centres at +0.5).
DOME_CENTROID = """([x0, y0, r]) => {
  const c = document.querySelector('#dome'), w = c.width, h = c.height, px = window.domeSnapshot;
  let n = 0, sx = 0, sy = 0;
  for (let y = Math.max(0, Math.floor(y0 - r)); y < Math.min(h, y0 + r); y++) {
    for (let x = Math.max(0, Math.floor(x0 - r)); x < Math.min(w, x0 + r); x++) {
      const i = ((h - 1 - y) * w + x) * 4;  // readPixels rows start at the bottom
      if (px[i] > 220 && px[i + 1] > 120 && px[i + 1] < 190 && px[i + 2] < 110) { n++; sx += x + 0.5; sy += y + 0.5; }
    }
  }
  return { n, x: sx / n, y: sy / n };
}"""


def js_to_fixed(value: float, digits: int) -> str:
    """What JavaScript's ``value.toFixed(digits)`` prints.

    It rounds the exact binary value, ties away from zero; Python's format rounds ties to even, so an altitude
    of exactly 1.125 m reads "1.13" on the page and "1.12" in an f-string (a flaky CI run, session 37).
    """
    return str(Decimal(value).quantize(Decimal(1).scaleb(-digits), rounding=ROUND_HALF_UP))


def js_round(value: float) -> int:
    """What JavaScript's ``Math.round`` gives: halves round up, not to even as Python's ``round`` does."""
    return math.floor(value + 0.5)


def test_wearer_page_video_motion_gauges_and_a_touch_through_the_lens(live, browser):  # type: ignore[no-untyped-def]
    page = open_wearer(browser, live)
    try:
        # an MJPEG <img> fires load once; frames changing is checked by sampling pixels of the image
        first = page.evaluate(SAMPLE_PIXELS)
        page.wait_for_function(f"({SAMPLE_PIXELS})() !== {first!r}", timeout=15000)

        # gauges: the values of a GET /state answer the page received, as the HUD shows them (read in one go,
        # before the next answer, a second later, redraws them)
        with page.expect_response(lambda r: r.url.endswith("/api/v1/state")) as answer:
            pass
        flight = answer.value.json()["services"]["flight"]
        shown = page.evaluate(
            """v => new Promise((resolve) => { const read = () => {
                 const g = (n) => document.querySelector('#g-' + n);
                 if (g('altitude').dataset.value !== String(v)) return setTimeout(read, 10);
                 resolve(Object.fromEntries(['altitude', 'heading', 'battery', 'link'].map(n => [n, g(n).querySelector('output').textContent])));
               }; read(); })""",
            flight["altitude_m"],
        )
        assert shown["altitude"] == f"{js_to_fixed(flight['altitude_m'], 2)} m"
        assert shown["battery"] == f"{js_to_fixed(flight['battery_v'], 2)} V {flight['battery']}"
        assert shown["heading"].startswith(f"{js_round(flight['heading_deg'] % 360)}\u00b0 ")
        page.wait_for_function("!document.querySelector('#g-link').classList.contains('bad')", timeout=10000)
        assert page.locator("#g-link output").inner_text() == "motors up, events live"

        # hold-to-move: the command stays in force while the button is held, and lapses after release
        page.locator('[data-cmd="forward"]').hover()
        page.mouse.down()
        time.sleep(0.8)  # longer than the 500 ms hold: only the page's refreshes keep it moving
        assert motion_state(live)["command"] == "forward"
        page.mouse.up()
        time.sleep(0.2)
        assert motion_state(live)["active"] is False

        # a press off the centre of the skin (where every lens model agrees) shows as a marker where the lens
        # model puts its u, v: in the fisheye frame, and on the dome
        sim = api(live, "GET", "/sim")
        api(live, "POST", "/sim/press", {"x": sim["width"] * 0.3, "y": sim["height"] * 0.3})
        try:
            # once the touch's ripple has faded, the marker alone is orange on the dome
            page.wait_for_function(
                "Number(document.querySelector('#markers').dataset.markers) >= 1 && window.feeliumView.ripples.length === 0",
                timeout=20000,
            )
            found = page.evaluate(RENDER_NOW)
        finally:
            api(live, "POST", "/sim/release")
        assert found["n"] > 100, found
        (mark,) = found["marks"]
        ex, ey = expected_pixel(live, mark["u"], mark["v"])
        assert math.hypot(ex - 319.5, ey - 239.5) > 60, "the test touch must be off the lens's centre"
        assert math.hypot(found["x"] - ex, found["y"] - ey) < 2.0, (found, (ex, ey))

        # on the dome, seen straight ahead by the page's 80-degree pinhole view: the marker disc of the fisheye frame
        # undistorted by the lens model. Its centroid is not the touch's own point (the lens squeezes the disc's
        # outer side more), so the expected centroid is that of the disc's points carried onto the screen.
        w, h = found["dome"]
        f = h / 2 / math.tan(math.radians(40))
        sx, sy = dome_centroid(live, (ex, ey), MARKER_RADIUS_PX, (w, h), f)
        on_dome = page.evaluate(DOME_CENTROID, [sx, sy, 80])
        assert on_dome["n"] > 100, on_dome
        assert math.hypot(on_dome["x"] - sx, on_dome["y"] - sy) < 2.0, (on_dome, (sx, sy))

        # what happened, in sentences
        page.wait_for_function(
            "[...document.querySelectorAll('#log li')].some(li => /The partner (held|let go|swiped)|It was a tap/.test(li.textContent))",
            timeout=10000,
        )
        texts = page.locator("#log li").all_inner_texts()
        assert any("The partner touched the top left of the skin." in t for t in texts), texts
        assert not any("{" in t or '"seq"' in t for t in texts), texts
        # over 127.0.0.1 (a secure context) face and talk are offered, with nothing to explain
        assert page.locator("#face-btn").is_enabled() and page.locator("#media-why").is_hidden()
    finally:
        page.close()
    assert page.errors == []


def test_stop_is_always_visible_and_stops(live, browser):  # type: ignore[no-untyped-def]
    page = open_wearer(browser, live)
    try:
        page.set_viewport_size({"width": 700, "height": 500})  # narrow: the page scrolls a long way
        page.evaluate("window.scrollTo(0, document.body.scrollHeight)")
        assert page.evaluate(TOPMOST, "#stop")

        # a stop hands its sender the motion lease (docs/api.md), so this page steers even if another just did
        page.click("#stop")
        page.keyboard.down("KeyW")  # held: the page refreshes forward every 150 ms
        page.wait_for_function("document.querySelector('[data-cmd=forward]').classList.contains('active')")
        time.sleep(0.3)
        assert motion_state(live)["active"] is True
        page.click("#stop")
        time.sleep(0.7)  # past the 500 ms hold: no refresh may have followed the stop
        assert motion_state(live)["active"] is False
        page.keyboard.up("KeyW")

        page.keyboard.down("KeyR")
        time.sleep(0.3)
        assert motion_state(live)["command"] == "up"
        page.keyboard.press("Space")
        time.sleep(0.7)
        assert motion_state(live)["active"] is False
        page.keyboard.up("KeyR")
    finally:
        page.close()
    assert page.errors == []


def test_another_client_steering_is_shown_and_taken_over(live, browser):  # type: ignore[no-untyped-def]
    """A move refused because another client steers offers "take over"; the refusal itself must not stop that
    client's blimp, and taking over hands this page the lease through a stop (docs/api.md, "One client steers")."""

    def post_motion(client: str, command: str, take_over: bool = False) -> int:
        headers = dict(live.auth) | {"Content-Type": "application/json", "X-Feelium-Client": client}
        body = json.dumps({"command": command, "hold_ms": 500, "take_over": take_over}).encode()
        req = urllib.request.Request(f"{live.api}/motion", data=body, headers=headers, method="POST")
        try:
            with urllib.request.urlopen(req, timeout=5) as resp:
                return resp.status
        except urllib.error.HTTPError as exc:
            return exc.code

    def controller() -> str:
        state = api(live, "GET", "/state")
        assert state is not None
        return str(state["headset_link"]["controller"])

    page = open_wearer(browser, live)
    try:
        assert post_motion("vision-other", "forward", take_over=True) == 200
        page.keyboard.down("KeyW")
        page.wait_for_selector("#takeover:not([hidden])", timeout=5000)
        assert "vision-other is steering" in page.inner_text("#takeover")
        assert not page.evaluate("document.querySelector('[data-cmd=forward]').classList.contains('active')")
        page.keyboard.up("KeyW")
        assert controller().endswith("/vision-other")  # refused without sending a stop, which would take the lease

        page.click("#takeover button")
        page.wait_for_selector("#takeover", state="hidden")
        assert motion_state(live)["active"] is False  # the hand-over passes through a stopped blimp
        assert controller().endswith(page.evaluate("sessionStorage.getItem('feelium-client')"))
        assert post_motion("vision-other", "forward") == 409
        page.keyboard.down("KeyW")
        time.sleep(0.3)
        assert motion_state(live)["command"] == "forward"
        page.keyboard.up("KeyW")
        time.sleep(0.2)
        assert motion_state(live)["active"] is False
    finally:
        page.close()
    assert page.errors == []


TOPMOST = """(sel) => {
  const el = document.querySelector(sel), r = el.getBoundingClientRect();
  const inside = r.top >= 0 && r.left >= 0 && r.bottom <= innerHeight && r.right <= innerWidth && r.width > 0;
  return inside && document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2) === el;
}"""

# Headless Chromium has no XR device: this stands in for one, enough for the page to enter its immersive state
# (the session draws nothing without a viewer pose); the test fires the controller's select on it.
FAKE_XR = """
class FakeSession extends EventTarget {
  constructor() { super(); this.renderState = {}; this.inputSources = []; window.fakeXrSession = this; }
  async updateRenderState(s) { Object.assign(this.renderState, s); }
  async requestReferenceSpace() { return {}; }
  requestAnimationFrame() { return 0; }
  async end() { this.dispatchEvent(new Event('end')); }
}
window.XRWebGLLayer = class { constructor() { this.framebuffer = null; } getViewport() { return { x: 0, y: 0, width: 1, height: 1 }; } };
Object.defineProperty(navigator, 'xr', { value: {
  isSessionSupported: async (mode) => mode === 'immersive-vr',
  requestSession: async (mode, init) => { window.fakeXrInit = init; return new FakeSession(); },
} });
"""


def test_immersive_mode_keeps_stop_reachable(live, browser):  # type: ignore[no-untyped-def]
    context = browser.new_context(viewport={"width": 1100, "height": 800})
    context.add_init_script(FAKE_XR)
    page = open_wearer(browser, live, context=context)
    try:
        page.click("#xr")
        page.wait_for_selector("body.immersive")
        # the HUD is the session's DOM overlay (where a headset offers one) and stays on top of the page
        assert page.evaluate("window.fakeXrInit.domOverlay.root.id") == "hud"
        assert page.evaluate(TOPMOST, "#stop")
        assert page.locator("#g-altitude output").inner_text().endswith(" m")

        is_stop = lambda r: r.url.endswith("/motion") and '"stop"' in (r.request.post_data or "")  # noqa: E731
        for trigger in ("select", "#stop", "Space"):
            api(live, "POST", "/motion", {"command": "forward", "hold_ms": 500, "take_over": True})
            with page.expect_response(is_stop, timeout=5000) as answer:  # a loaded 2-core machine is slow
                if trigger == "select":  # the controller's trigger
                    page.evaluate("window.fakeXrSession.dispatchEvent(new Event('select'))")
                elif trigger == "Space":
                    page.keyboard.press("Space")
                else:
                    page.click(trigger)
            assert answer.value.status == 200, trigger
            assert motion_state(live)["active"] is False, trigger

        page.click("#xr")  # exit
        page.wait_for_function("!document.body.classList.contains('immersive')")
    finally:
        context.close()
    assert page.errors == []


def test_speech_both_ways_streams_on_one_websocket_within_the_limits(live, browser):  # type: ignore[no-untyped-def]
    """Listening reads the room's audio from GET /speech/stream (no polling); talking, from Chromium's fake
    microphone, sends chunks on the same socket under the 20/s speech limit (2048-sample buffers at 48 kHz were
    23 POSTs a second, and 14 % of them were refused)."""
    page = open_wearer(browser, live)
    received, sent, sockets, polls = [], [], [], []

    def on_socket(ws):  # type: ignore[no-untyped-def]
        if "/speech/stream" in ws.url:
            sockets.append(ws)
            ws.on("framereceived", lambda payload: isinstance(payload, bytes) and received.append(payload))
            ws.on("framesent", lambda payload: isinstance(payload, bytes) and sent.append((time.monotonic(), len(payload))))

    page.on("websocket", on_socket)
    page.on("request", lambda r: polls.append(r.url) if re.search(r"/speech(\?|$)", r.url) else None)
    refused_before = live.health()["services"]["http"]["speech_rate_limited"]
    try:
        page.click("#listen-btn")
        deadline = time.monotonic() + 10
        while len(received) < 10 and time.monotonic() < deadline:
            page.wait_for_timeout(100)
        assert len(received) >= 10 and len(sockets) == 1  # 40 ms frames of the simulated room
        box = page.locator("#talk-btn").bounding_box()
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        page.mouse.down()
        page.wait_for_timeout(2000)
        page.mouse.up()
        page.wait_for_timeout(300)
        assert len(sockets) == 1  # talking went on the socket listening opened
        assert len(sent) >= 10, sent
        span = sent[-1][0] - sent[0][0]
        assert (len(sent) - 1) / span < 15.0, (len(sent), span)  # well under the 20/s limit
        page.click("#listen-btn")  # neither listening nor talking: the socket closes
        page.wait_for_function("true", timeout=1000)
        deadline = time.monotonic() + 5
        while not sockets[0].is_closed() and time.monotonic() < deadline:
            page.wait_for_timeout(100)
        assert sockets[0].is_closed()
    finally:
        page.close()
    assert polls == [] and page.errors == []
    assert live.health()["services"]["http"]["speech_rate_limited"] == refused_before


def test_plain_http_explains_why_face_and_talk_are_off(live, browser):  # type: ignore[no-untyped-def]
    page = open_wearer(browser, live, host=PLAIN_HOST)
    try:
        assert page.evaluate("window.isSecureContext") is False
        why = page.locator("#media-why")
        assert why.is_visible()
        text = why.inner_text()
        assert "plain HTTP" in text and "getUserMedia" in text and "secure" in text and "HTTPS" in text
        assert page.locator("#face-btn").is_disabled() and page.locator("#talk-btn").is_disabled()
        assert page.locator("#listen-btn").is_enabled()
    finally:
        page.close()
    assert page.errors == []


def test_partner_page_opens_with_the_wearers_session_or_a_pairing_code(live, browser):  # type: ignore[no-untyped-def]
    # from the wearer's page, in a new tab: no token in its URL, the browser's session cookie authorises it
    context = browser.new_context(viewport={"width": 1100, "height": 800})
    try:
        wearer = open_wearer(browser, live, context=context)
        with context.expect_page() as opened:
            wearer.click("#partner-link")
        partner = opened.value
        partner.wait_for_selector("#mode.ok", timeout=15000)
        assert partner.locator("dialog#pairing").count() == 0

        # the wearer's page gives a one-time code for another device
        wearer.click("#pair-btn")
        wearer.wait_for_function("/\\d{4}-\\d{4}/.test(document.querySelector('#pair-code').textContent)")
        code = re.search(r"\d{4}-\d{4}", wearer.locator("#pair-code").inner_text()).group(0)
    finally:
        context.close()

    # another browser (a partner's phone): nothing to go on, so the page asks for the code, then works
    context = browser.new_context(viewport={"width": 1100, "height": 800})
    try:
        partner = context.new_page()
        partner.goto(f"{live.base}/partner", wait_until="domcontentloaded")
        dialog = partner.locator("dialog#pairing")
        dialog.wait_for(state="visible", timeout=10000)
        assert "pairing code" in dialog.inner_text()
        dialog.locator("input[name=code]").fill("0000-0000")
        dialog.locator("button").click()
        partner.wait_for_function("document.querySelector('#pairing .error').textContent !== ''")
        dialog.locator("input[name=code]").fill(code)
        dialog.locator("button").click()
        partner.wait_for_selector("#mode.ok", timeout=15000)
        partner.wait_for_function("document.querySelector('#rear').naturalWidth > 0", timeout=15000)
        assert dialog.count() == 0
    finally:
        context.close()


def test_partner_page_presses_with_the_mouse(live, browser):  # type: ignore[no-untyped-def]
    page = browser.new_page(viewport={"width": 1100, "height": 800})
    try:
        page.goto(f"{live.base}/partner#token={live.token}", wait_until="domcontentloaded")
        page.wait_for_selector("#mode.ok", timeout=15000)
        page.wait_for_function("document.querySelector('#rear').naturalWidth > 0", timeout=15000)
        box = page.locator("#stage").bounding_box()
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        page.mouse.down()
        page.wait_for_function("[...document.querySelectorAll('#log li')].some(li => li.textContent.startsWith('press'))", timeout=10000)
        page.mouse.up()
        page.wait_for_function("[...document.querySelectorAll('#log li')].some(li => li.textContent === 'release')", timeout=10000)
    finally:
        page.close()


SAMPLE_PIXELS = """() => {
  const img = document.querySelector('#video');
  const c = document.createElement('canvas'); c.width = 32; c.height = 24;
  const g = c.getContext('2d'); g.drawImage(img, 0, 0, 32, 24);
  return Array.from(g.getImageData(0, 0, 32, 24).data.filter((_, i) => i % 37 === 0)).join(',');
}"""
