"""The static site of `mlct export-web` end to end in headless Chromium: export the bundled model,
serve the folder with a plain static file server, type a prompt, generate in the page, and
compare the joints the page computed with the Python ONNX path (the site's own graphs, the same
portable noise) for the same seed; and the page's downloads (JSON, NPY, and the BVH and GLB of
its own rotation fit, read back with mlct's BVH and glTF readers).

Needs Debian's chromium and playwright (skipped without them, as tests/test_web_e2e.py), onnx
and onnxruntime, and the npm tarballs of onnxruntime-web and three (fetched once into
~/.cache/mlct/web, or MLCT_WEB_CACHE). Set MLCT_WEB_SCREENSHOT=PATH to keep the page's picture
(docs/img/web_static.png is made this way).
"""

from __future__ import annotations

import functools
import http.server
import io
import json
import os
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
if not os.path.exists(CHROMIUM):
    pytest.skip("Debian's chromium is not installed (apt-get install chromium)",
                allow_module_level=True)
playwright = pytest.importorskip("playwright.sync_api",
                                 reason="playwright is not installed (pip install playwright)")
pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
Image = pytest.importorskip("PIL.Image")

from mlct.errors import MlctError
from mlct.generate.samplers.portable_noise import PortableNoise
from mlct.motion.foot_lock import foot_contacts
from mlct.motion.skeleton import get_skeleton
from mlct.serve.site import export_site, load_site_reference
from mlct.serve.site.reference import generate_with_portable_noise, page_text_vector

pytestmark = pytest.mark.slow  # an export (graphs, quantization) and a browser

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
PROMPT = "a person jumps up and down."
HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    try:
        return export_site("bundled", tmp_path_factory.mktemp("web") / "site")
    except MlctError as error:
        if "cannot fetch" in str(error):  # no network and no cached npm tarballs
            pytest.skip(str(error))
        raise


class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):  # keep the test output clean
        pass


@pytest.fixture(scope="module")
def url(site):
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                             functools.partial(Quiet, directory=str(site)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}/"
    server.shutdown()


@pytest.fixture(scope="module")
def page(url, tmp_path_factory):
    with playwright.sync_playwright() as p:
        context = p.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("profile")), executable_path=CHROMIUM, args=FLAGS,
            headless=True, viewport={"width": 1280, "height": 860}, accept_downloads=True)
        outside: list[str] = []  # the site must not reach past its own server (no CDN)

        def local_only(route):
            if route.request.url.startswith(url):
                route.continue_()
            else:
                outside.append(route.request.url)
                route.abort()

        context.route("**/*", local_only)
        page = context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda error: errors.append(str(error)))
        page.goto(url)
        page.wait_for_function("window.mlct && window.mlct.ready", timeout=120_000)
        assert page.evaluate("window.mlct.lastMotion !== null"), page.inner_text("#status")
        yield page
        context.close()
        assert errors == [] and outside == []


@pytest.fixture(scope="module")
def reference(site):
    return load_site_reference(site, threads=1)


def bvh_joints(path) -> np.ndarray:
    """A BVH file's joints (T, 22, 3) in metres, in the humanml3d skeleton's order."""
    from mlct.motion.bvh import read_bvh
    from mlct.motion.skeleton import get_skeleton

    clip = read_bvh(path)
    names = get_skeleton("humanml3d").joint_names
    assert sorted(clip.joint_names) == sorted(names) and clip.fps == 20
    return clip.positions[:, [clip.joint_names.index(n) for n in names]] / 100.0


def glb_joints(path, expected: np.ndarray) -> np.ndarray:
    """A GLB's joints (T, 22, 3) in metres, skeleton order; checked against expected (the BVH
    of the same motion, read back)."""
    pytest.importorskip("pygltflib")
    from mlct.motion.gltf import read_gltf
    from mlct.motion.skeleton import get_skeleton

    clip = read_gltf(path)
    names = get_skeleton("humanml3d").joint_names
    assert sorted(clip.joint_names) == sorted(names)
    assert np.allclose(np.diff(clip.times), 1 / 20, atol=1e-6)
    positions = clip.positions[:, [clip.joint_names.index(n) for n in names]]
    assert positions.shape == expected.shape
    assert np.abs(positions - expected).max() < 1e-4  # the BVH text's 1e-4 cm and degrees
    return positions


def check_bvh_fit(back: np.ndarray, joints: np.ndarray, tmp_path) -> None:
    """The page's BVH (read back) against the joints it was made of, and against Python's
    write_bvh of the same joints: a rigid skeleton gives a generated motion's joints back to
    about its bones' stretch, which reaches 14 cm at an elbow (both writers, bvh.js); the page's
    fit must be as close as Python's, give or take its missing leg IK (2 cm)."""
    from mlct.motion.bvh import write_bvh
    from mlct.motion.skeleton import get_skeleton

    write_bvh(tmp_path / "python.bvh", joints, get_skeleton("humanml3d"), fps=20)
    python = bvh_joints(tmp_path / "python.bvh")
    gap = np.linalg.norm(back - joints, axis=-1)
    python_gap = np.linalg.norm(python - joints, axis=-1)
    assert np.median(gap) < 0.005, np.median(gap)
    assert (gap.max(0) <= python_gap.max(0) + 0.02).all(), (gap.max(0), python_gap.max(0))
    assert np.median(np.linalg.norm(back - python, axis=-1)) < 0.003


def view_pixels(page) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(page.locator("#view").screenshot())).convert("RGB"))


def test_page_joints_match_the_python_onnx_path(page, reference, tmp_path):
    page.fill("#prompt", PROMPT)
    page.fill("#seed", "7")
    page.locator("#seconds").fill("3")  # 60 frames at 20 fps
    page.press("#prompt", "Enter")
    page.wait_for_function(f"window.mlct.lastMotion.text === {json.dumps(PROMPT)}",
                           timeout=60_000)
    got = page.evaluate("window.mlct.lastMotion")
    assert (got["seed"], got["nfe"], got["frames"]) == (7, 5, 60)
    joints = np.asarray(got["joints"], dtype=np.float32).reshape(60, 22, 3)
    _, expected = generate_with_portable_noise(reference, PROMPT, 60, 5, 7)
    scale = float(np.ptp(expected[..., 1]))  # the skeleton's height over the motion, ~1.7 m
    gap = float(np.abs(joints - expected).max())
    assert scale > 1.0 and gap <= 1e-3 * scale, f"{gap:.3g} m apart (scale {scale:.2f} m)"
    # the page plants the feet as Python does: left as decoded, they are further apart
    lock, reference.foot_lock = reference.foot_lock, None
    try:
        _, decoded = generate_with_portable_noise(reference, PROMPT, 60, 5, 7)
    finally:
        reference.foot_lock = lock
    assert np.abs(joints - decoded).max() > 5 * 1e-3 * scale
    # another seed is another motion: the comparison above can fail
    _, other = generate_with_portable_noise(reference, PROMPT, 60, 5, 8)
    assert np.abs(other - expected).max() > 20 * 1e-3 * scale  # 20x the tolerance at least
    assert "ms" in page.inner_text("#timing")

    # the skeleton is drawn and moves
    page.wait_for_timeout(300)
    before = view_pixels(page)
    page.wait_for_timeout(500)
    after = view_pixels(page)
    assert (np.abs(before.astype(int) - after.astype(int)).max(-1) > 30).mean() > 1e-4
    red = (before[..., 0] > 150) & (before[..., 1] < 110) & (before[..., 2] < 110)
    blue = (before[..., 2] > 150) & (before[..., 0] < 110)
    assert red.sum() > 30 and blue.sum() > 30  # right and left limbs in their colours

    # pause holds the frame; the scrubber moves it
    page.click("#play")
    page.wait_for_timeout(150)
    frame = page.evaluate("window.mlct.state.frame")
    page.wait_for_timeout(300)
    assert page.evaluate("window.mlct.state.frame") == frame
    assert page.inner_text("#play") == "Play"
    page.locator("#scrub").fill("30")
    page.wait_for_function("window.mlct.state.frame === 30", timeout=5_000)
    assert page.inner_text("#clock").startswith("1.50 /")
    page.click("#play")

    # the downloads are the motion on screen
    for fmt in ("json", "npy"):
        with page.expect_download(timeout=10_000) as download:
            page.click(f"#dl-{fmt}")
        path = tmp_path / download.value.suggested_filename
        download.value.save_as(path)
        assert path.name.startswith("a_person_jumps_up_and_down_seed7") and path.suffix == f".{fmt}"
        record = json.loads(path.read_text()) if fmt == "json" else None
        data = np.asarray(record["joints"]) if record else np.load(path)
        assert data.shape == (60, 22, 3) and np.abs(data - joints).max() <= 1e-4
        if record:  # the feet's contacts, as Python labels the page's joints
            expected_contacts = foot_contacts(joints, get_skeleton("humanml3d"))
            assert record["foot_contacts"] == expected_contacts.astype(int).tolist()
            assert 0 < expected_contacts.mean() < 1  # a jump: on the floor, then not

    # the BVH: rotations fitted in the page (bvh.js), read back with Python's reader
    with page.expect_download(timeout=10_000) as download:
        page.click("#dl-bvh")
    path = tmp_path / download.value.suggested_filename
    download.value.save_as(path)
    assert path.suffix == ".bvh"
    back = bvh_joints(path)
    check_bvh_fit(back, joints, tmp_path)

    # the GLB: the same fit as a glTF animation (three's GLTFExporter), read back with
    # Python's reader: the BVH's joints, up to the BVH text's rounding
    with page.expect_download(timeout=20_000) as download:
        page.click("#dl-glb")
    path = tmp_path / download.value.suggested_filename
    download.value.save_as(path)
    assert path.suffix == ".glb"
    glb_joints(path, back)

    shot = tmp_path / "web_static.png"
    page.screenshot(path=str(shot))
    if os.environ.get("MLCT_WEB_SCREENSHOT"):
        target = Path(os.environ["MLCT_WEB_SCREENSHOT"])
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(shot, target)


def test_tokenizer_matches_the_python_tokenizer(page, reference):
    prompts = json.loads((HERE.parent / "bench" / "data" / "quality_prompts.json").read_text())
    texts = [item["text"] for key in ("paraphrases", "two_actions") for item in prompts[key]]
    texts += json.loads((HERE / "data" / "tokenizer_texts.json").read_text())  # the odd cases
    # and each in capitals, title case and with punctuation glued on
    texts += [v for t in texts for v in (t.upper(), t.title(), f"«{t.replace(' ', ', ', 1)}»?!")]
    texts.append(" ".join(texts[:40]))  # past max_length: truncated
    assert len(texts) > 300
    tokenizer = reference.text_encoder.tokenizer
    expected = [tokenizer.encode(t).ids for t in texts]
    got = page.evaluate("(texts) => texts.map((t) => window.mlct.model.tokenizer.encode(t))", texts)
    wrong = [t for t, a, b in zip(texts, got, expected) if a != b]
    assert wrong == []
    assert max(map(len, expected)) == 256  # the long text is truncated, as in Python


def test_noise_matches_python(page):
    for seed in (0, 1, 123456, 2**40 + 5):
        got = page.evaluate("async ([seed]) => Array.from(new (await import('./noise.js'))"
                            ".PortableNoise(seed).normals(7))", [seed])
        assert np.array_equal(np.float32(got), PortableNoise(seed).normals(7))


def test_bad_prompt_shows_a_message_and_the_page_recovers(page):
    page.fill("#prompt", "   ")
    page.press("#prompt", "Enter")
    page.wait_for_function("document.getElementById('status').classList.contains('error')",
                           timeout=10_000)
    assert "prompt is empty" in page.inner_text("#status")
    page.click("#gallery button >> nth=4")  # "someone bows."
    page.wait_for_function("window.mlct.lastMotion.text === 'someone bows.'", timeout=60_000)
    assert not page.evaluate("document.getElementById('status').classList.contains('error')")


def test_sides_are_contrasted_as_in_python(page, reference):
    from mlct.text.sides import SIDE_CONTRAST, mirror_sides

    texts = ["a person waves with the LEFT hand", "Right foot, then left", "walks anticlockwise",
             "a person jumps", "the leftover cleft", "gauche: léft ǀright_",
             "a Right-Angle turn to the left, all right", "turns right away, then left now"]
    got = page.evaluate("async (texts) => { const m = await import('./model.js');"
                        " return texts.map((t) => m.mirrorSides(t)); }", texts)
    assert got == [mirror_sides(t) for t in texts]
    assert reference.meta["text_encoder"] == "minilm+sides"  # the bundled model contrasts sides
    alpha = page.evaluate("window.mlct.model.config.text_encoder.side_contrast")
    assert alpha == SIDE_CONTRAST
    for text in texts[:4]:
        vector, raw, raw_mirror = (np.float32(page.evaluate(
            f"async (t) => Array.from(await window.mlct.model.{f}(t))", t))
            for f, t in (("encode", text), ("embed", text), ("embed", mirror_sides(text))))
        # the page's contrast is text/sides.py's, on the page's own network outputs ...
        expected = raw if mirror_sides(text) == text else raw + alpha * (raw - raw_mirror)
        np.testing.assert_allclose(vector, expected, rtol=0, atol=1e-6)
        # ... and those are Python's up to the int8 kernels: WASM's dynamic quantization rounds
        # a few activations otherwise than the native one (up to 0.0023 seen, on "Right foot,
        # then left"; most texts agree to 1e-7)
        python = np.asarray(reference.text_encoder._embed([text])[0])  # an array (onnx)
        assert np.abs(raw - python).max() < 5e-3, text


def test_bvh_of_a_rigid_motion_is_exact_and_like_pythons(page, reference, tmp_path):
    """bvh.js's fit on a motion that a rigid skeleton can show exactly (Python's rig fit of a
    generated motion): the file gives the joints back to the text's 1e-4 cm; on the raw motion
    it is as close as Python's write_bvh (check_bvh_fit)."""
    from mlct.motion.rigfit import fit_rig
    from mlct.motion.skeleton import get_skeleton

    skeleton = get_skeleton("humanml3d")
    _, raw = generate_with_portable_noise(reference, "a person waves with the left hand", 50, 5, 3)
    rigid = fit_rig(raw, skeleton).positions.astype(np.float32)
    for name, joints in (("rigid", rigid), ("raw", raw)):
        text = page.evaluate(
            "async ([joints, frames]) => (await import('./bvh.js')).bvhText({joints: "
            "Float32Array.from(joints), frames, skeleton: window.mlct.model.config.skeleton})",
            [joints.reshape(-1).tolist(), len(joints)])
        (tmp_path / f"{name}.bvh").write_text(text)
        back = bvh_joints(tmp_path / f"{name}.bvh")
        gap = np.linalg.norm(back - joints, axis=-1)
        if name == "rigid":
            assert gap.max() < 1e-5, gap.max()  # 0.01 mm: the file's rounding
        else:
            check_bvh_fit(back, joints, tmp_path)


class GzipEncoding(Quiet):
    """A server that sends the .gz files as Content-Encoding: gzip (as some do): the browser
    unpacks them before the page sees them."""

    def end_headers(self):
        if self.path.endswith(".gz"):
            self.send_header("Content-Encoding", "gzip")
        super().end_headers()


def test_a_server_that_unpacks_the_gz_files_itself_works_too(site, page, tmp_path):
    assert any(p.suffix == ".gz" for p in site.rglob("*"))  # the site stores some gzipped
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                             functools.partial(GzipEncoding, directory=str(site)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    address = f"http://127.0.0.1:{server.server_address[1]}/"
    page.context.route(f"{address}**", lambda route: route.continue_())  # before local_only
    try:
        other = page.context.new_page()
        other.goto(address)
        other.wait_for_function("window.mlct && window.mlct.ready", timeout=120_000)
        motion = other.evaluate("window.mlct.lastMotion && window.mlct.lastMotion.frames")
        assert motion, other.inner_text("#status")
        expected = page.evaluate("window.mlct.model.config.graphs")
        assert expected["text_encoder"].endswith(".gz")
        other.close()
    finally:
        server.shutdown()


# a sided part: its vector is contrasted with its mirror's (x5), which the site's text encoder
# must compute as Python does (int8-weights, dequantized as written on both sides)
SEQUENCE = "a person walks forward, then waves with the right hand."


def typed_in(page, text: str, seed: int, seconds: float) -> dict:
    """The motion the page makes of text typed in the form, with its seed and a length set on
    the slider (which turns "length from the text" off): window.mlct.lastMotion."""
    page.fill("#prompt", text)
    page.fill("#seed", str(seed))
    page.locator("#seconds").fill(str(seconds))
    page.press("#prompt", "Enter")
    page.wait_for_function(f"window.mlct.lastMotion.text === {json.dumps(text)}",
                           timeout=60_000)
    return page.evaluate("window.mlct.lastMotion")


def test_actions_are_split_as_in_python(page):
    """The page's splits (static/compose.js) give compose.split_actions' parts and
    split_concurrent's body and arms: on the benchmark's hand-written prompts and on the
    phrasings each rule is for."""
    from mlct.generate.compose.actions import plain_subject, split_actions, split_concurrent

    texts = [SEQUENCE, "after walking forward, a man turns left", "a man walks before turning",
             "a person squats, then stands back up and walks away", "sits down, then stands still",
             "A Person WALKS forward, THEN Waves", "walks forward and back",
             "someone claps twice and jabs with the right arm", "punches twice, jogs ahead",
             "stretches the arms up and leans to the side", "jogging forward, then jumping",
             "a person walks forward while waving", "waves and claps at the same time",
             "turns three hundred and sixty degrees", "a man is slowly walking, then is running",
             "a person jumps; afterwards, kneels", "léft, then rîght", "then", ", then ,",
             "ſomeone walks, then waves", "café walks, then waves", "a person jumps，then waves",
             "a tired woman sinks into a chair, then pushes herself back up",
             "a goalkeeper sidesteps along the line, going to his right",
             "an old man first sits down, then runs", "an elderly woman slowly walks, then sits",
             "an old man walked forward, then sat", "a man is walking, turning left and waving",
             "a boss walks, then waves", "ſomebody's ſister walks, then waves",
             "the left arm rises", "He walks", "A Person walks", "the robot's arm rises",
             "a man power walks", "a person side shuffles to the right"]
    # every hand-written prompt file, so that a set added later is checked too
    for path in sorted((HERE.parent / "bench" / "data").glob("quality_prompts*.json")):
        data = json.loads(path.read_text())
        texts += [item["text"] for items in data.values() if isinstance(items, list)
                  for item in items if isinstance(item, dict) and "text" in item]
    texts += ["a person jogs in place while clapping", "walks and claps at the same time",
              "a person waves while walking, then sits down", "someone claps while smiling",
              "a man walks forward, then jogs while clapping", "jogs and waves simultaneously"]
    expected = [split_actions(t) for t in texts]
    assert sum(len(e) > 1 for e in expected) >= 30  # sequences among them, not only single actions
    got = page.evaluate("(texts) => texts.map((t) => window.mlct.model.splitter.split(t))", texts)
    assert got == expected
    expected = [plain_subject(t) for t in texts]
    assert sum(e != t for e, t in zip(expected, texts)) >= 20  # subjects read as "a person"
    got = page.evaluate("(texts) => texts.map((t) => window.mlct.model.splitter.plainSubject(t))",
                        texts)
    assert got == expected
    expected = [split_concurrent(t) for t in texts]
    assert sum(e is not None for e in expected) >= 5
    got = page.evaluate("(texts) => texts.map((t) => window.mlct.model.splitter.splitConcurrent(t))",
                        texts)
    assert [None if g is None else tuple(g) for g in got] == expected


def test_a_sequence_is_made_in_parts_as_in_python(page, reference):
    """A prompt of two actions: the page makes each part with its share of the clip (the
    duration model's) and chains them, as generate() does; the same joints as the Python
    reference of the page (generate_with_portable_noise), and the parts show in the status."""
    from mlct.generate.compose.actions import split_actions

    got = typed_in(page, SEQUENCE, seed=11, seconds=6)  # 120 frames
    parts = split_actions(SEQUENCE)
    assert len(parts) == 2 and got["frames"] == 120
    assert [p["text"] for p in got["parts"]] == parts
    assert [p["frames"] for p in got["parts"]] == reference.part_frames(parts, 120)
    assert [p["seed"] for p in got["parts"]] == [11, 12] and len(got["seams"]) == 1
    assert "2 parts" in page.inner_text("#status")
    assert page.locator("#parts span").all_inner_texts() == parts  # under the timeline
    joints = np.asarray(got["joints"], dtype=np.float32).reshape(120, 22, 3)
    _, expected = generate_with_portable_noise(reference, SEQUENCE, 120, 5, 11)
    scale = float(np.ptp(expected[..., 1]))
    # planted: the same but where a contact's speed or height sits on its threshold and a few
    # frames of one foot are held otherwise (seen: a toe 2.3 mm apart for 10 frames)
    gap = np.abs(joints - expected).max(-1)
    assert scale > 1.0 and (gap <= 1e-3 * scale).mean() > 0.99 and gap.max() < 0.01
    # as decoded and chained, before the feet are planted: the same joints
    check_joined_before_planting(page, reference, SEQUENCE, 120, 11)
    # made whole (the page before), it is another motion: the comparison above can fail
    _, whole = generate_with_portable_noise(reference, SEQUENCE, 120, 5, 11, split_actions=False)
    assert np.abs(whole - expected).max() > 20 * 1e-3 * scale
    # and the page can still make it whole: one part, Python's whole motion
    unsplit = page.evaluate(f"async () => {{ const m = await window.mlct.model.generate("
                            f"{{text: {json.dumps(SEQUENCE)}, frames: 120, nfe: 5, seed: 11,"
                            f" split: false}}); return [m.parts.length, Array.from(m.joints)]; }}")
    assert unsplit[0] == 1
    gap = np.abs(np.float32(unsplit[1]).reshape(120, 22, 3) - whole).max(-1)
    assert (gap <= 1e-3 * scale).mean() > 0.99 and gap.max() < 0.01


def check_joined_before_planting(page, reference, text, frames, seed):
    """The page's motion of text with its feet as decoded and joined (model.config.foot_lock
    off for the call) is the Python reference's within 1e-3 of the skeleton's height."""
    decoded = np.float32(page.evaluate(
        "async ([text, frames, seed]) => { const m = window.mlct.model;"
        " const lock = m.config.foot_lock; m.config.foot_lock = null; try { return Array.from("
        "(await m.generate({text, frames, nfe: 5, seed})).joints); } finally"
        " { m.config.foot_lock = lock; } }", [text, frames, seed])).reshape(frames, 22, 3)
    lock, reference.foot_lock = reference.foot_lock, None
    try:
        _, joined = generate_with_portable_noise(reference, text, frames, 5, seed)
    finally:
        reference.foot_lock = lock
    scale = float(np.ptp(joined[..., 1]))
    gap = float(np.abs(decoded - joined).max())
    assert scale > 1.0 and gap <= 1e-3 * scale, f"{gap:.3g} m apart (scale {scale:.2f} m)"


CONCURRENT = "a person jogs in place while clapping"


def test_an_arm_action_during_another_is_made_apart_as_in_python(page, reference):
    """"jogs in place while clapping": the page makes the jog and the clap (standing) apart and
    puts the clap's arms on the jog (control_fit.reattach's port), as generate() does: Python's
    joints, and the hands meet while the feet go on jogging."""
    got = typed_in(page, CONCURRENT, seed=4, seconds=4)  # 80 frames
    assert [(p["text"], p.get("arms", False)) for p in got["parts"]] == [
        ("a person jogs in place", False), ("a person claps", True)]
    joints = np.asarray(got["joints"], dtype=np.float32).reshape(80, 22, 3)
    _, expected = generate_with_portable_noise(reference, CONCURRENT, 80, 5, 4)
    gap = np.abs(joints - expected).max(-1)  # planted: see the sequence's test
    assert (gap <= 2e-3).mean() > 0.99 and gap.max() < 0.01
    check_joined_before_planting(page, reference, CONCURRENT, 80, 4)
    names = get_skeleton("humanml3d").joint_names
    hands = np.linalg.norm(joints[:, names.index("left_wrist")] - joints[:, names.index("right_wrist")],
                           axis=-1)
    assert hands.min() < 0.15  # the hands meet
    _, whole = generate_with_portable_noise(reference, CONCURRENT, 80, 5, 4, split_actions=False)
    assert np.abs(whole - expected).max() > 0.05  # made whole it is another motion


def test_the_length_comes_from_the_text_unless_set(page, reference):
    """With "length from the text" on (the default), the page gives a prompt the length Python's
    default_seconds gives it (a circle walk ~7 s, not 5); moving the slider sets it by hand."""
    text = "a person walks in a circle"
    page.check("#auto-length")
    page.fill("#prompt", text)
    page.fill("#seed", "2")
    page.press("#prompt", "Enter")
    page.wait_for_function(f"window.mlct.lastMotion.text === {json.dumps(text)}", timeout=60_000)
    got = page.evaluate("window.mlct.lastMotion")
    (seconds,) = reference.default_seconds([text])
    assert seconds > 6.0 and got["frames"] == reference.frames_for(seconds)
    assert page.inner_text("#seconds-value").startswith("auto")
    _, expected = generate_with_portable_noise(reference, text, None, 5, 2)
    assert len(expected) == got["frames"]
    page.locator("#seconds").fill("3")
    assert not page.is_checked("#auto-length") and page.inner_text("#seconds-value") == "3.0 s"


def test_best_of_n_picks_what_the_python_critic_picks(page, reference):
    """The page samples the model's 8 candidates in one batch (candidate k's noise from seed +
    k * SEED_STRIDE mod 2^63, in BigInt) and keeps the first its critic graph rates within the
    model's margin of the best: the scores are the torch critic's, the motion Python's;
    candidates 1 is the plain sample, and a count past the critic's limit is refused with a
    message."""
    from mlct.generate.seeds import MAX_SEED, SEED_STRIDE

    text = "a person kicks with the left leg"
    assert page.evaluate("window.mlct.model.defaultCandidates") == reference.candidates == 8
    assert page.evaluate("window.mlct.model.config.critic.margin") == reference.critic.margin
    seeds = page.evaluate("(s) => window.mlct.model.candidateSeeds(s, 8).map(String)", 2**40 + 3)
    assert [int(s) for s in seeds] == [(2**40 + 3 + k * SEED_STRIDE) % (MAX_SEED + 1)
                                       for k in range(8)]
    # the critic graph against the torch critic on the same latents
    latents = np.random.default_rng(0).normal(size=(8, 1, 384)).astype(np.float32)
    cond = page_text_vector(reference, text).numpy()[0]
    got = page.evaluate(
        "async ([z, text]) => { const m = window.mlct.model; const ort = await import("
        "'./vendor/ort.wasm.min.mjs'); const out = await m.sessions.critic.run({"
        " z: new ort.Tensor('float32', Float32Array.from(z), [8, 1, 384]),"
        " frames: new ort.Tensor('float32', new Float32Array(8).fill(80), [8]),"
        " text: new ort.Tensor('float32', Float32Array.from(text.flat()), [8, text[0].length]) });"
        " return Array.from(out.score.data); }", [latents.reshape(-1).tolist(), [cond.tolist()] * 8])
    import torch
    expected = reference.critic.network.score(torch.from_numpy(latents), torch.full((8,), 80.0),
                                              torch.from_numpy(cond).repeat(8, 1)).numpy()
    np.testing.assert_allclose(got, expected, atol=1e-4)
    # a seed where Python's critic keeps another candidate than the first (which one depends on
    # the bundle's weights), so that the page's pick is seen to follow the critic
    seed = next(s for s in range(9, 60) if np.abs(
        generate_with_portable_noise(reference, text, 60, 5, s, candidates=1)[1]
        - generate_with_portable_noise(reference, text, 60, 5, s, candidates=8)[1]).max() > 0.05)
    motions = {}
    for count in (1, 8):
        motion = page.evaluate(
            "async ([text, count, seed]) => { const m = await window.mlct.model.generate({text,"
            " frames: 60, nfe: 5, seed, candidates: count}); return [m.candidates,"
            " Array.from(m.joints)]; }", [text, count, seed])
        assert motion[0] == count
        motions[count] = np.float32(motion[1]).reshape(60, 22, 3)
        _, expected = generate_with_portable_noise(reference, text, 60, 5, seed, candidates=count)
        gap = np.abs(motions[count] - expected).max(-1)  # planted: see the sequence's test
        assert (gap <= 2e-3).mean() > 0.99 and gap.max() < 0.01
    assert np.abs(motions[1] - motions[8]).max() > 0.05  # the critic chose another than the first
    error = page.evaluate("async () => { try { await window.mlct.model.generate({text: 'a person"
                          " jumps', frames: 40, nfe: 5, seed: 0, candidates: 65}); return ''; }"
                          " catch (e) { return e.message; } }")
    assert error == "candidates must be within 1..64, got 65"


def test_the_site_stays_within_its_size_goal(site):
    """The site's goal, <= 40 MB on disk, with the critic's graph and the arm pair's decoder:
    the float16 graphs are stored gzipped too (pack.MIN_GAIN)."""
    from mlct.serve.site import site_size

    assert site_size(site)["total"] <= 40e6
    assert (site / "model" / "critic.onnx.gz").is_file()


def test_a_stated_duration_sets_the_length_as_in_python(page, reference):
    """"... for 6 seconds": the page reads the phrase as prompts.stated_seconds does (the same
    pattern, from model.json) and makes the prompt without it at that length; the motion keeps
    the prompt as typed."""
    from mlct.generate.compose.prompts import stated_seconds

    texts = ["a person jogs in place for 6 seconds", "walks forward, for about half a minute",
             "a person waves For Five Seconds", "claps for 2.5 s", "walks for 5 seconds, then "
             "waves for 3 seconds", "for 4 seconds", "a man bows for 0 seconds",
             "a person runs for forty-five seconds", "someone stands for a minute",
             "a person walks for ٥ seconds"]
    got = page.evaluate("(texts) => texts.map((t) => window.mlct.model.stated.read(t))", texts)
    assert [tuple(g) for g in got] == [stated_seconds(t) for t in texts]
    text = "a person jogs in place for 6 seconds."
    motion = page.evaluate("async (text) => { const m = await window.mlct.model.generate({text,"
                           " nfe: 5, seed: 3}); return [m.text, m.frames, m.parts[0].text,"
                           " Array.from(m.joints)]; }", text)
    assert motion[:3] == [text, 120, "a person jogs in place."]
    _, expected = generate_with_portable_noise(reference, text, None, 5, 3)
    gap = np.abs(np.float32(motion[3]).reshape(120, 22, 3) - expected).max(-1)
    assert len(expected) == 120 and (gap <= 2e-3).mean() > 0.99 and gap.max() < 0.01


def test_a_gait_asked_for_longer_than_it_lasts_keeps_going_as_in_python(page, reference):
    """"a person runs forward" for 9.8 s: the model's run stops after ~4 s; the page makes it
    again as takes of its natural length chained into one run (keepgoing.js, the port of
    generate/compose/keep_going.py), as generate() does: Python's joints, still running at the end."""
    from mlct.generate.compose.keep_going import ground_speed

    text = "a person runs forward"
    got = typed_in(page, text, seed=4, seconds=9.8)  # 196 frames
    assert got["frames"] == 196 and got["parts"][0].get("takes", 0) >= 2
    joints = np.asarray(got["joints"], dtype=np.float32).reshape(196, 22, 3)
    _, expected = generate_with_portable_noise(reference, text, 196, 5, 4)
    gap = np.abs(joints - expected).max(-1)  # planted: see the sequence's test
    assert (gap <= 2e-3).mean() > 0.99 and gap.max() < 0.01
    check_joined_before_planting(page, reference, text, 196, 4)
    speed = ground_speed(joints, 20)
    # running in its last second: faster than any walk (~1.3 m/s), if slower than its start
    assert speed[-20:].mean() > 1.5
    # as the model made it in one take, it had stopped
    made = page.evaluate("async () => { const m = window.mlct.model; const kg = m.keepGoing;"
                         " m.keepGoing = null; try { return Array.from((await m.generate({text: "
                         f"{json.dumps(text)}, frames: 196, nfe: 5, seed: 4}})).joints); }} finally"
                         " { m.keepGoing = kg; } }")
    stopped = ground_speed(np.float32(made).reshape(196, 22, 3), 20)
    assert stopped[-20:].mean() < 0.3 * np.median(stopped[10:70])


def test_a_gait_goes_on_past_the_window_and_anything_else_is_refused(page, reference):
    """"a person walks forward for 15 seconds": 300 frames, past the model's 196, made as takes
    chained, as generate() makes it (Python's joints); a jump that long is refused with the
    window's message, as generate() refuses it."""
    text = "a person walks forward for 15 seconds"
    got = page.evaluate("async (text) => { const m = await window.mlct.model.generate({text, nfe: 5,"
                        " seed: 1}); return [m.frames, m.parts[0].takes, Array.from(m.joints)]; }",
                        text)
    assert got[0] == 300 and got[1] >= 4
    _, expected = generate_with_portable_noise(reference, text, None, 5, 1)
    gap = np.abs(np.float32(got[2]).reshape(300, 22, 3) - expected).max(-1)  # planted
    assert len(expected) == 300 and (gap <= 2e-3).mean() > 0.99 and gap.max() < 0.01
    walked = np.linalg.norm(expected[-1, 0, [0, 2]] - expected[0, 0, [0, 2]])
    # walking to the end, not 5 m and standing: ~1.3 m/s for 15 s on the bundle of 2026-11-27,
    # 10.0 m at 0.65-0.87 m/s (every 1.5 s) on the slower-walking one of 2026-11-28
    assert walked > 7.5
    error = page.evaluate("async () => { try { await window.mlct.model.generate({text: 'a person"
                          " jumps for 15 seconds', nfe: 5, seed: 0}); return ''; } catch (e)"
                          " { return e.message; } }")
    assert error.startswith("'a person jumps': 15.0 s is longer than the model's window (9.8 s)")
    with pytest.raises(MlctError, match="outside 1..196"):
        generate_with_portable_noise(reference, "a person jumps for 15 seconds", None, 5, 0)


def test_the_gif_download_is_the_motion_on_screen(page, tmp_path):
    """The GIF button: every frame of the motion at its fps (50 ms delays), 480 pixels wide,
    looping, frames that differ as the figure moves (gifenc in the page)."""
    got = typed_in(page, "a person jumps up and down.", seed=5, seconds=2)  # 40 frames
    with page.expect_download(timeout=60_000) as download:
        page.click("#dl-gif")
    path = tmp_path / download.value.suggested_filename
    download.value.save_as(path)
    assert path.name.startswith("a_person_jumps_up_and_down_seed5") and path.suffix == ".gif"
    gif = Image.open(path)
    assert gif.format == "GIF" and gif.n_frames == got["frames"] == 40
    assert gif.size[0] == 480 and gif.info.get("loop") == 0 and gif.info["duration"] == 50
    frames = []
    for index in (0, 20):
        gif.seek(index)
        frames.append(np.asarray(gif.convert("RGB"), dtype=int))
    assert (np.abs(frames[0] - frames[1]).max(-1) > 30).mean() > 1e-3  # the figure moved
    assert page.evaluate("window.mlct.state.frame") < 40  # the view is back on a frame
