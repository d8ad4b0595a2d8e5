"""The web page end to end in headless Chromium: type a prompt, generate, watch it move, download.

Needs Debian's chromium (/usr/bin/chromium) and the playwright package (never `playwright
install`: the system browser is used). Skipped without them. Set MLCT_WEB_SCREENSHOT=PATH to keep
the page's screenshot there (docs/img/web_app.png is made this way).
"""

from __future__ import annotations

import io
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
if not os.path.exists(CHROMIUM):
    pytest.skip("Debian's chromium is not installed (apt-get install chromium)",
                allow_module_level=True)
playwright = pytest.importorskip("playwright.sync_api",
                                 reason="playwright is not installed (pip install playwright)")
Image = pytest.importorskip("PIL.Image")

import mlct
from mlct.serve import ServeSettings, create_app, serve_in_thread

pytestmark = pytest.mark.slow  # a browser against a live server

# No sandbox (containers, root), no network beyond localhost, no GPU: WebGL runs on SwiftShader.
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def _three_available() -> bool:
    """three.js for the humanoid, as `mlct serve` gets it (fetched once into the cache)."""
    from mlct.errors import MlctError
    from mlct.serve.three_files import three_dir
    try:
        three_dir()
    except (MlctError, OSError):
        return False
    return True


THREE = _three_available()


@pytest.fixture(scope="module")
def url():
    app = create_app(mlct.load(), ServeSettings())
    with serve_in_thread(app) as base:
        yield base


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    with playwright.sync_playwright() as p:
        context = p.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("profile")), executable_path=CHROMIUM, args=FLAGS,
            headless=True, viewport={"width": 1280, "height": 860}, accept_downloads=True)
        yield context
        context.close()


@pytest.fixture()
def page(browser, url):
    page = browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(url)
    page.wait_for_function("window.mlct && window.mlct.ready", timeout=60_000)
    yield page
    page.close()
    assert errors == []


def plot_pixels(page) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(page.locator("#plot").screenshot())).convert("RGB"))


def changed(a: np.ndarray, b: np.ndarray) -> float:
    """The fraction of pixels that differ visibly."""
    return float(np.any(np.abs(a.astype(int) - b.astype(int)) > 30, axis=-1).mean())


def test_prompt_generate_play_download(page, tmp_path):
    assert page.evaluate("window.mlct.firstFrameMs.length") == 1  # the page's opening motion
    page.fill("#prompt", "the woman waves the right hand back and forth two times.")
    page.press("#prompt", "Enter")
    page.wait_for_function("window.mlct.firstFrameMs.length === 2", timeout=30_000)
    status = page.inner_text("#status")
    assert "waves the right hand" in status and "server" in status and "first frame" in status

    # playback: the canvas changes between two frames
    drawn = page.evaluate("window.mlct.framesDrawn")
    before = plot_pixels(page)
    page.wait_for_function(f"window.mlct.framesDrawn > {drawn + 4}", timeout=10_000)
    after = plot_pixels(page)
    assert changed(before, after) > 0.001, f"{changed(before, after):.4%} of the pixels changed"
    assert (before < 100).all(axis=-1).sum() > 200  # dark skeleton pixels are drawn at all

    # pause holds the frame (and the picture); the scrubber moves it
    page.click("#play")
    page.wait_for_timeout(150)
    frame = page.evaluate("window.mlct.state.frame")
    held = plot_pixels(page)
    page.wait_for_timeout(300)
    assert page.evaluate("window.mlct.state.frame") == frame
    assert changed(held, plot_pixels(page)) == 0.0
    page.locator("#scrub").fill("30")
    page.wait_for_function("window.mlct.state.frame === 30", timeout=5_000)
    assert page.inner_text("#clock").startswith("1.50 /")

    # the BVH download is the motion on screen
    with page.expect_download(timeout=30_000) as download:
        page.click("#dl-bvh")
    path = tmp_path / download.value.suggested_filename
    download.value.save_as(path)
    text = path.read_text()
    # "length from the text" (the default): the server's default length for the prompt, 5 s;
    # best of the model's 8 by default, as mlct generate
    assert page.inner_text("#seconds-value") == "auto · 5.0 s"
    assert page.input_value("#candidates") == "8" and "best of 8" in status
    assert text.startswith("HIERARCHY") and "Frames: 100" in text
    assert path.name.startswith("the_woman_waves_the_right_hand") and path.suffix == ".bvh"

    shot = tmp_path / "web_app.png"
    page.screenshot(path=str(shot))
    assert Image.open(shot).size == (1280, 860)
    if os.environ.get("MLCT_WEB_SCREENSHOT"):
        target = Path(os.environ["MLCT_WEB_SCREENSHOT"])
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(shot, target)


def test_bad_input_shows_the_servers_message(page):
    page.fill("#prompt", "   ")
    page.click("#generate")
    page.wait_for_function("document.getElementById('status').classList.contains('error')",
                           timeout=10_000)
    assert "prompt is empty" in page.inner_text("#status")
    page.click("#gallery button >> nth=2")  # the server keeps answering
    page.wait_for_function("window.mlct.firstFrameMs.length === 2", timeout=30_000)
    assert "runs straight ahead" in page.inner_text("#status")


@pytest.mark.skipif(not THREE, reason="three.js: no npm tarball cached and no registry")
def test_skinned_humanoid_plays_the_glb_on_each_rig(page, url, tmp_path):
    import json
    import urllib.request

    pytest.importorskip("pygltflib")
    from mlct.motion.gltf import read_gltf

    """The three.js view loads the motion's GLB, follows the skeleton's frame, and reloads
    with the rig's bone names when the rig changes. MLCT_RIG_SCREENSHOTS=DIR keeps a
    screenshot per rig (docs/img/web_rig_mixamo.png and web_rig_vrm.png are made this way)."""
    page.wait_for_function("window.mlctBody && window.mlctBody.ready", timeout=30_000)
    page.fill("#prompt", "a person walks forward and waves")
    page.click("#generate")
    # the humanoid shows this prompt's motion, not the one the page made when it opened (a
    # slow machine may still be loading that one when the click's motion arrives)
    page.wait_for_function(
        "window.mlct.state.request && window.mlct.state.request.text === "
        "'a person walks forward and waves' && window.mlctBody.current && window.mlctBody.shown "
        "=== JSON.stringify(window.mlct.state.request) + '|' + document.getElementById('rig').value",
        timeout=60_000)
    assert page.evaluate("window.mlctBody.bones")[0] == "pelvis"
    # three.js's GLTFLoader poses the bones where mlct's reader of the same GLB puts them
    request = page.evaluate("window.mlct.state.request")
    glb = urllib.request.urlopen(urllib.request.Request(
        f"{url}/generate", data=json.dumps({**request, "format": "glb"}).encode(),
        headers={"Content-Type": "application/json"})).read()
    (tmp_path / "m.glb").write_bytes(glb)
    clip = read_gltf(tmp_path / "m.glb")
    for frame in (0, 25, 60):
        three = page.evaluate(f"window.mlctBody.positionsAt({frame / 20.0})")
        ours = {name: clip.positions[frame, i] for i, name in enumerate(clip.joint_names)}
        assert sorted(three) == sorted(ours)
        assert max(np.abs(np.array(three[n]) - ours[n]).max() for n in ours) < 1e-4
    shots = {}
    # three.js drops ':' from node names (PropertyBinding's reserved characters), as it does
    # for Mixamo's own files
    for rig, root in (("mixamo", "mixamorigHips"), ("vrm", "hips")):
        page.select_option("#rig", rig)
        page.wait_for_function(f"window.mlctBody.current && window.mlctBody.rig === '{rig}'",
                               timeout=60_000)
        bones = page.evaluate("window.mlctBody.bones")
        assert bones[0] == root and len(bones) == 22
        assert rig in page.inner_text("#body-caption")
        # it plays in step with the skeleton view, and the picture changes as it does
        page.locator("#scrub").fill("10")
        page.wait_for_function("window.mlctBody.frame === 10", timeout=5_000)
        before = np.asarray(Image.open(io.BytesIO(page.locator("#body3d").screenshot())))
        page.locator("#scrub").fill("40")
        page.wait_for_function("window.mlctBody.frame === 40", timeout=5_000)
        page.wait_for_timeout(200)
        after = np.asarray(Image.open(io.BytesIO(page.locator("#body3d").screenshot())))
        assert changed(before[..., :3], after[..., :3]) > 0.002
        shots[rig] = tmp_path / f"web_rig_{rig}.png"
        page.screenshot(path=str(shots[rig]))
    if os.environ.get("MLCT_RIG_SCREENSHOTS"):
        target = Path(os.environ["MLCT_RIG_SCREENSHOTS"])
        target.mkdir(parents=True, exist_ok=True)
        for shot in shots.values():
            shutil.copyfile(shot, target / shot.name)


def _sweep(page, frames) -> list[dict]:
    """The humanoid's bones on screen at each frame, scrubbed to (window.mlctBody.onScreen)."""
    out = []
    for frame in frames:
        page.locator("#scrub").fill(str(frame))
        page.wait_for_function(f"window.mlctBody.frame === {frame}", timeout=5_000)
        # read after the page's next frame: the camera follows in the frame that draws it
        out.append(page.evaluate("new Promise((done) => requestAnimationFrame(() => "
                                 "done(window.mlctBody.onScreen())))"))
    return out


def _inside(shot: dict) -> bool:
    return all(0 <= x <= shot["width"] and 0 <= y <= shot["height"]
               for x, y in shot["pixels"].values())


def _drawn(page, path: Path) -> tuple[int, int]:
    """The humanoid's panel saved to path: how many pixels of the body's grey-blue
    (gltf.BODY_COLOUR, lit) lie within 40 px of the root's projected pixel, and how many of the
    skeleton lines' saturated blue and green the panel shows."""
    page.locator("#body3d").screenshot(path=str(path))
    picture = np.asarray(Image.open(path).convert("RGB")).astype(int)
    shot = page.evaluate("window.mlctBody.onScreen()")
    scale = picture.shape[1] / shot["width"]
    x, y = (int(v * scale) for v in shot["pixels"][page.evaluate("window.mlctBody.bones")[0]])
    r, g, b = np.moveaxis(picture[max(0, y - 40):y + 40, max(0, x - 40):x + 40], -1, 0)
    body = (r > 100) & (g > 100) & (b - r > 12) & (b - r < 70) & (b < 245)
    r, g, b = np.moveaxis(picture, -1, 0)
    lines = (b - r > 120) | (g - r > 120)
    return int(body.sum()), int(lines.sum())


@pytest.mark.skipif(not THREE, reason="three.js: no npm tarball cached and no registry")
def test_skinned_humanoid_stays_in_view_while_it_walks(page, tmp_path):
    """The camera goes along with the humanoid's root: every bone stays inside the panel through
    a walk of several metres, the user's orbit is kept, and with following off (the view as it
    was before) the same walk leaves the panel. MLCT_FOLLOW_SCREENSHOTS=DIR keeps the panel at
    the walk's start, middle and end there."""
    page.wait_for_function("window.mlctBody && window.mlctBody.ready", timeout=30_000)
    page.fill("#prompt", "a person walks forward")
    page.click("#generate")
    page.wait_for_function(
        "window.mlct.state.request && window.mlct.state.request.text === 'a person walks forward'"
        " && window.mlctBody.current && window.mlctBody.shown === "
        "JSON.stringify(window.mlct.state.request) + '|' + document.getElementById('rig').value",
        timeout=60_000)
    total = page.evaluate("window.mlct.state.motion.frames")
    assert total == 100  # the server's default length, 5 s at 20 fps
    frames = [*range(0, total, 5), total - 1]

    on = _sweep(page, frames)
    root = np.array([s["root"] for s in on])
    assert np.hypot(*(root[-1] - root[0])[[0, 2]]) > 3.0  # it does travel several metres
    outside = [f for f, s in zip(frames, on) if not _inside(s)]
    assert outside == [], f"bones left the panel at frames {outside}"
    # the camera moves with its target, on the floor only: the view's angle and zoom are kept
    offsets = np.array([np.subtract(s["camera"], s["target"]) for s in on])
    assert np.abs(offsets - offsets[0]).max() < 1e-6
    assert np.ptp([s["target"][1] for s in on]) < 1e-9
    target = np.array([s["target"] for s in on])
    assert np.hypot(*(target[-1] - target[0])[[0, 2]]) > 3.0

    # the body is drawn where the bones project, the skeleton's lines over it
    shots = {}
    for name, frame in (("start", 0), ("middle", total // 2), ("end", total - 1)):
        page.locator("#scrub").fill(str(frame))
        page.wait_for_function(f"window.mlctBody.frame === {frame}", timeout=5_000)
        page.wait_for_timeout(100)
        shots[name] = tmp_path / f"web_follow_{name}.png"
        body, lines = _drawn(page, shots[name])
        assert body > 300 and lines > 100, f"the {name}: {body} body, {lines} line pixels"

    # following off: the camera stays where it was (the view before it followed), and the same
    # walk leaves the panel: what the sweep above measures is the following
    page.evaluate("window.mlctBody.follow = false")
    off = _sweep(page, frames)
    assert np.allclose(off[0]["target"], [0, 0.9, 0])  # where the page's camera starts
    assert np.allclose(off[0]["camera"], [2.6, 1.6, 3.4])
    assert _inside(off[0])
    left = [f for f, s in zip(frames, off) if not _inside(s)]
    assert left and left[-1] == frames[-1], f"without following the walk stays in view ({left})"
    shots["end_unfollowed"] = tmp_path / "web_follow_end_unfollowed.png"
    page.locator("#body3d").screenshot(path=str(shots["end_unfollowed"]))
    page.evaluate("window.mlctBody.follow = true")
    page.evaluate("new Promise((done) => requestAnimationFrame(done))")  # carried back to the end

    # the user's orbit survives following: at the end of the walk, turn the view most of the way
    # round (from the walk's front to its side), then walk again
    box = page.locator("#body3d").bounding_box()
    page.mouse.move(box["x"] + 0.1 * box["width"], box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + 0.9 * box["width"], box["y"] + box["height"] / 2, steps=10)
    page.mouse.up()
    orbited = _sweep(page, [*frames[::3], frames[-1]])
    offset = np.subtract(orbited[0]["camera"], orbited[0]["target"])
    assert np.abs(offset - offsets[0]).max() > 1.0  # the drag did turn the view
    assert all(_inside(s) for s in orbited)
    assert all(np.abs(np.subtract(s["camera"], s["target"]) - offset).max() < 1e-6
               for s in orbited)
    # the body and its lines are drawn where the walk ended up, seen from there (not culled
    # from where they were first drawn)
    shots["end_orbited"] = tmp_path / "web_follow_end_orbited.png"
    body, lines = _drawn(page, shots["end_orbited"])
    assert body > 300 and lines > 100, f"turned round: {body} body, {lines} line pixels"
    if os.environ.get("MLCT_FOLLOW_SCREENSHOTS"):
        target_dir = Path(os.environ["MLCT_FOLLOW_SCREENSHOTS"])
        target_dir.mkdir(parents=True, exist_ok=True)
        for shot in shots.values():
            shutil.copyfile(shot, target_dir / shot.name)
