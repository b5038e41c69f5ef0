"""The browser client in Debian's Chromium (Playwright drives it; no browser is downloaded).

On a machine without Chromium these tests skip, saying how to get it, so the README's test command
passes on a fresh Debian machine; in CI (``CI=true``, where `.ci/run` installs it from
`.ci/apt-packages.txt`) a missing browser is a failure, as for the Betaflight SITL tests.
"""

from __future__ import annotations

import os
import time
import urllib.request

import pytest

pytestmark = pytest.mark.slow

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync",
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


def motion_state(live) -> dict:  # type: ignore[no-untyped-def]
    import json

    req = urllib.request.Request(f"{live.api}/motion", headers=live.auth)
    with urllib.request.urlopen(req, timeout=5) as resp:
        return json.load(resp)


def test_wearer_page_shows_video_drives_motion_and_marks_a_touch(live, browser):  # type: ignore[no-untyped-def]
    page = browser.new_page(viewport={"width": 1100, "height": 800})
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        page.goto(f"{live.base}/#token={live.token}", wait_until="domcontentloaded")
        page.wait_for_function("window.feeliumDebug && window.feeliumDebug.videoFrames >= 1", timeout=15000)
        # an MJPEG <img> fires load once; frames changing is checked by sampling pixels of the image
        first = page.evaluate(SAMPLE_PIXELS)
        page.wait_for_function(f"({SAMPLE_PIXELS})() !== {first!r}", timeout=15000)
        page.wait_for_selector("#link.ok", timeout=15000)

        # hold-to-move: the command stays in force while the button is held, and lapses after release
        button = page.locator('[data-cmd="forward"]')
        button.hover()
        page.mouse.down()
        time.sleep(0.8)  # longer than the 500 ms hold: only the page's refreshes keep it moving
        assert motion_state(live)["command"] == "forward"
        page.mouse.up()
        time.sleep(0.2)
        assert motion_state(live)["active"] is False

        # a simulated touch on the partner side appears as a marker in the wearer's view
        sim = page.evaluate("Feelium.call('GET', '/sim').then(r => r.data)")
        page.evaluate(f"Feelium.call('POST', '/sim/press', {{x: {sim['width'] / 2}, y: {sim['height'] / 2}}})")
        try:
            page.wait_for_function("Number(document.querySelector('#overlay').dataset.markers) >= 1", timeout=20000)
        finally:
            page.evaluate("Feelium.call('POST', '/sim/release')")
        assert page.locator("#log li").count() >= 1
    finally:
        page.close()
    assert errors == []


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
