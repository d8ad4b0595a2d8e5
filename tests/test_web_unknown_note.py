"""The web page says when the model does not know a prompt (the reply's unknown_parts), in
headless Chromium as tests/test_web_e2e.py drives it; skipped without Debian's chromium and
playwright."""

from __future__ import annotations

import os
import shutil

import pytest

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
if not os.path.exists(CHROMIUM):
    pytest.skip("Debian's chromium is not installed (apt-get install chromium)",
                allow_module_level=True)
playwright = pytest.importorskip("playwright.sync_api",
                                 reason="playwright is not installed (pip install playwright)")

import mlct  # noqa: E402
from mlct.serve import ServeSettings, create_app, serve_in_thread  # noqa: E402

pytestmark = pytest.mark.slow  # a browser against a live server
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def test_the_page_notes_an_unknown_prompt_and_clears_the_note(tmp_path):
    app = create_app(mlct.load(), ServeSettings(warmup=False))
    with serve_in_thread(app) as url, playwright.sync_playwright() as p:
        browser = p.chromium.launch_persistent_context(
            str(tmp_path / "profile"), executable_path=CHROMIUM, args=FLAGS, headless=True,
            viewport={"width": 1280, "height": 860})
        try:
            page = browser.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.goto(url)
            page.wait_for_function("window.mlct && window.mlct.ready", timeout=60_000)
            shown = page.evaluate("window.mlct.firstFrameMs.length")
            assert page.locator("#unknown-note").is_hidden()  # the opening motion is known
            page.fill("#prompt", "a person plays the guitar")
            page.press("#prompt", "Enter")
            page.wait_for_function(f"window.mlct.firstFrameMs.length === {shown + 1}",
                                   timeout=60_000)
            note = page.locator("#unknown-note")
            assert note.is_visible()
            assert note.inner_text().startswith("“a person plays the guitar” is far from every "
                                                "caption the model was trained on")
            page.fill("#prompt", "a person walks forward at a brisk pace.")
            page.press("#prompt", "Enter")
            page.wait_for_function(f"window.mlct.firstFrameMs.length === {shown + 2}",
                                   timeout=60_000)
            assert note.is_hidden()
            assert errors == []
        finally:
            browser.close()
