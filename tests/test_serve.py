"""mlct serve: the JSON API, its limits and errors, the queue and dynamic batching.

A fake generator (instant, gated, counting its calls) drives the batching and queue tests; the
bundled model checks that the API returns what the library generates.
"""

from __future__ import annotations

import importlib.util
import io
import json
import re
import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

import mlct
from mlct.errors import MlctError
from mlct.motion.skeleton import get_skeleton
from mlct.generate.output.generated import GeneratedMotion
from mlct.serve import ServeSettings, create_app

pytestmark = pytest.mark.usefixtures("one_thread")

GOOD = {"text": "a person walks forward", "lengths": 20, "nfe": 2, "seed": 3}


class FakeGenerator:
    """MotionGenerator's interface, instant: joints encode (seed, frame) so tests can check
    which seed made which motion. `gate` (when set) holds every call until released."""

    def __init__(self, gate: threading.Event | None = None) -> None:
        self.skeleton = get_skeleton("humanml3d")
        self.max_frames = 196
        self.default_nfe = 5
        self.meta = {"sampler": "consistency", "text_encoder": "fake", "step": 0}
        self.gate = gate
        self.calls: list[tuple[list[str], int | None]] = []
        self.candidates_asked: list[int | None] = []  # per call, beside self.calls
        self.entered = threading.Event()

    def generate(self, texts: Sequence[str], lengths: Sequence[int] | None = None,
                 nfe: int | None = None, seed: Sequence[int] | None = None,
                 candidates: int | None = None) -> list[GeneratedMotion]:
        self.calls.append((list(texts), nfe))
        self.candidates_asked.append(candidates)
        self.entered.set()
        if self.gate is not None:
            assert self.gate.wait(10), "test gate never opened"
        if any(t == "explode" for t in texts):
            raise MlctError("the fake cannot make 'explode'")
        if any(t == "crash" for t in texts):
            raise RuntimeError("a bug in the model")
        assert lengths is not None and seed is not None
        out = []
        for text, frames, s in zip(texts, lengths, seed):
            joints = np.zeros((frames, 22, 3), dtype=np.float32)
            joints[:, :, 0] = s
            joints[:, :, 1] = np.arange(frames)[:, None]
            out.append(GeneratedMotion(text, np.zeros((frames, 263), np.float32), joints,
                                       20.0, "humanml3d"))
        return out


def fake_client(gate: threading.Event | None = None, **settings: Any
                ) -> tuple[TestClient, FakeGenerator]:
    generator = FakeGenerator(gate)
    app = create_app(generator, ServeSettings(warmup=False, **settings))
    return TestClient(app), generator


def post_async(client: TestClient, body: dict[str, Any]) -> tuple[threading.Thread, list]:
    """POST from a thread; the response lands in the returned list."""
    box: list = []
    thread = threading.Thread(target=lambda: box.append(client.post("/generate", json=body)))
    thread.start()
    return thread, box


def wait_until(condition, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "condition not reached"
        time.sleep(0.005)


# --- the bundled model -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def model_client():
    generator = mlct.load()
    with TestClient(create_app(generator, ServeSettings(warmup=False))) as client:
        yield client, generator


def test_json_reply_is_the_library_motion(model_client):
    client, generator = model_client
    reply = client.post("/generate", json={"text": "a person runs straight ahead.",
                                           "seconds": 2, "nfe": 3, "seed": 7})
    assert reply.status_code == 200, reply.text
    body = reply.json()
    motion = body["motions"][0]
    assert (motion["frames"], motion["seed"], motion["nfe"], motion["fps"]) == (40, 7, 3, 20.0)
    expected = generator.generate(["a person runs straight ahead."], lengths=[40], nfe=3,
                                  seed=[7])[0].joints
    np.testing.assert_allclose(np.array(motion["joints"]), expected, atol=2e-4)
    assert body["timing"]["batch_size"] == 1
    assert body["timing"]["server_ms"] >= body["timing"]["generate_ms"] > 0


def test_seconds_auto_takes_the_length_from_the_text(model_client):
    client, generator = model_client
    texts = ["a person jumps.", "a person walks in a circle."]
    reply = client.post("/generate", json={"texts": texts, "seconds": ["auto", 3], "seed": 5,
                                           "nfe": 3, "candidates": 1})
    assert reply.status_code == 200, reply.text
    jump, circle = reply.json()["motions"]
    assert jump["frames"] == generator.frames_for(generator.auto_seconds([texts[0]])[0])
    assert circle["frames"] == 60
    expected = generator.generate(texts[:1], seconds="auto", nfe=3, seed=[5],
                                  candidates=1)[0].joints
    np.testing.assert_allclose(np.array(jump["joints"]), expected, atol=2e-4)
    bad = client.post("/generate", json={"text": "a person jumps.", "seconds": "soon"})
    assert bad.status_code == 422
    with_control = client.post("/generate", json={
        "text": "a person walks.", "seconds": "auto",
        "control": {"path": [[0.0, 0.0, 0], [1.0, 0.0, 40]]}})
    assert with_control.status_code == 422
    assert "seconds 'auto' does not go with a control" in with_control.text


def test_a_prompt_that_says_how_long_sets_the_default_length(model_client):
    """As in the CLI and the Python API: "... for 3 seconds" gives 60 frames when the request
    gives no length, the phrase leaves the model's text, the reply keeps the prompt; past the
    server's window a one-line 422 names the prompt; given seconds win."""
    client, generator = model_client
    text = "a person jumps for 3 seconds"
    reply = client.post("/generate", json={"text": text, "seed": 2, "nfe": 3, "candidates": 1})
    assert reply.status_code == 200, reply.text
    motion = reply.json()["motions"][0]
    assert motion["frames"] == 60 and motion["text"] == text
    expected = generator.generate("a person jumps", lengths=60, nfe=3, seed=2,
                                  candidates=1)[0].joints
    np.testing.assert_allclose(np.array(motion["joints"]), expected, atol=2e-4)
    given = client.post("/generate", json={"text": text, "seconds": 2, "nfe": 1})
    assert given.status_code == 200 and given.json()["motions"][0]["frames"] == 40
    long = client.post("/generate", json={"text": "a person walks for 30 seconds"})
    assert long.status_code == 422
    assert "'a person walks for 30 seconds' says 30 s; this server makes motions of at most" \
        in long.json()["detail"]


def test_no_length_gives_the_libraries_default(model_client):
    """Without lengths or seconds a text gets what the CLI and the Python API give it: 5 s, or
    what its actions take (MotionGenerator.default_seconds), picked on the model's thread."""
    client, generator = model_client
    texts = ["a person walks in a circle.", "a person kicks.", "a person waves for 3 seconds"]
    reply = client.post("/generate", json={"texts": texts, "seed": 1, "nfe": 1,
                                           "candidates": 1})
    assert reply.status_code == 200, reply.text
    frames = [m["frames"] for m in reply.json()["motions"]]
    circle = generator.frames_for(generator.default_seconds(texts[:1])[0])
    assert frames == [circle, 100, 60] and circle > 120
    alone = generator.generate(texts[:1], nfe=1, seed=1, candidates=1)[0].joints
    np.testing.assert_allclose(np.array(reply.json()["motions"][0]["joints"]), alone, atol=2e-4)


def test_candidates_pick_as_the_library_does(model_client):
    client, generator = model_client
    assert generator.candidates == 8  # the bundled model's critic
    for asked in (1, 4, None):
        body = {"text": "a person jumps twice.", "seconds": 2, "seed": 3}
        if asked is not None:
            body["candidates"] = asked
        reply = client.post("/generate", json=body)
        assert reply.status_code == 200, reply.text
        motion = reply.json()["motions"][0]
        assert motion["candidates"] == (asked or 8)
        expected = generator.generate(["a person jumps twice."], lengths=[40], seed=[3],
                                      candidates=asked or 8)[0].joints
        np.testing.assert_allclose(np.array(motion["joints"]), expected, atol=2e-4)
    one = client.post("/generate", json={"text": "a person jumps twice.", "seconds": 2,
                                         "seed": 3, "candidates": 1, "format": "npy"})
    assert one.headers["X-Mlct-Candidates"] == "1"


def test_several_texts_and_seeds(model_client):
    client, generator = model_client
    texts = ["a person squats down three times.", "a person runs straight ahead."]
    reply = client.post("/generate", json={"texts": texts, "lengths": [12, 30], "nfe": 1,
                                           "seed": 5})
    assert reply.status_code == 200, reply.text
    motions = reply.json()["motions"]
    assert [m["frames"] for m in motions] == [12, 30]
    assert [m["seed"] for m in motions] == [5, 6]  # one seed s: text i gets s + i
    alone = generator.generate([texts[1]], lengths=[30], nfe=1, seed=[6])[0].joints
    # the second motion does not depend on the first one in its batch
    np.testing.assert_allclose(np.array(motions[1]["joints"]), alone, atol=2e-4)


def test_file_downloads(model_client):
    client, _ = model_client
    request = {"text": "a person walks forward at a brisk pace.", "lengths": 16, "nfe": 2,
               "seed": 1}
    joints = np.array(client.post("/generate", json=request).json()["motions"][0]["joints"])

    npy = client.post("/generate", json={**request, "format": "npy"})
    assert npy.status_code == 200
    assert npy.headers["content-disposition"] == \
        'attachment; filename="a_person_walks_forward_at_a_brisk_pace_seed1.npy"'
    np.testing.assert_allclose(np.load(io.BytesIO(npy.content)), joints, atol=1e-4)

    bvh = client.post("/generate", json={**request, "format": "bvh"})
    assert bvh.status_code == 200
    assert bvh.content.startswith(b"HIERARCHY")
    assert "Frames: 16" in bvh.text
    assert bvh.headers["content-disposition"].endswith('seed1.bvh"')

    gif = client.post("/generate", json={**request, "lengths": 4, "format": "gif"})
    assert gif.status_code == 200
    assert gif.content[:4] == b"GIF8" and gif.headers["content-type"] == "image/gif"

    if importlib.util.find_spec("pygltflib") is not None:  # the [export] extra
        for fmt, rig in (("glb", "mixamo"), ("vrma", None)):
            reply = client.post("/generate", json={**request, "format": fmt, "rig": rig})
            assert reply.status_code == 200, reply.text
            assert reply.content[:4] == b"glTF"
            assert reply.headers["content-type"] == "model/gltf-binary"
        assert b"mixamorig:Hips" in client.post(
            "/generate", json={**request, "format": "glb", "rig": "mixamo"}).content
    npz = client.post("/generate", json={**request, "format": "npz"})
    assert npz.status_code == 200
    assert np.load(io.BytesIO(npz.content))["poses"].shape == (16, 156)
    bvh = client.post("/generate", json={**request, "format": "bvh", "rig": "unreal"})
    assert "ROOT pelvis" in bvh.text and "JOINT thigh_l" in bvh.text
    fbx = client.post("/generate", json={**request, "format": "fbx", "rig": "unreal"})
    assert fbx.status_code == 200, fbx.text
    assert fbx.content.startswith(b"Kaydara FBX Binary  \x00") and b"thigh_l" in fbx.content
    assert fbx.headers["content-disposition"].endswith('.fbx"')
    assert bvh.headers["content-disposition"].endswith('seed1_unreal.bvh"')
    # in place: the pelvis stays over its start, every pose as made
    still = np.load(io.BytesIO(client.post("/generate", json={**request, "format": "npy",
                                                               "in_place": True}).content))
    np.testing.assert_allclose(still[:, 0, [0, 2]], np.repeat(joints[:1, 0, [0, 2]], 16, 0),
                               atol=1e-4)
    np.testing.assert_allclose(still - still[:, :1], joints - joints[:, :1], atol=2e-4)
    assert np.abs(joints[-1, 0, [0, 2]] - joints[0, 0, [0, 2]]).max() > 0.05  # it did travel


# --- bad input: 4xx with one line, and the server keeps answering ------------------------------

BAD_REQUESTS = [
    ({"text": ""}, 422, "empty"),
    ({"text": "  \t  "}, 422, "empty"),
    ({"text": "a" * 10_000}, 422, "10000 characters; the limit is 300"),
    ({"text": "walk\x00forward"}, 422, "U+0000"),
    ({"text": "walk \x1b[31m"}, 422, "U+001B"),
    ({"text": "walk\u202eforward"}, 422, "U+202E"),
    ({"texts": ["ok", ""]}, 422, "texts[1]"),
    ({"text": "walk", "lengths": 0}, 422, "lengths[0]"),
    ({"text": "walk", "lengths": -3}, 422, "lengths[0]"),
    ({"text": "walk", "lengths": 10**30}, 422, "less than or equal to 196"),
    ({"text": "walk", "lengths": 197}, 422, "196"),
    ({"text": "walk", "lengths": 2.5}, 422, "integer"),
    ({"text": "walk", "lengths": True}, 422, "integer"),
    ({"text": "walk", "seconds": 0}, 422, "seconds[0]"),
    ({"text": "walk", "seconds": 0.01}, 422, "one frame"),
    ({"text": "walk", "seconds": 1e9}, 422, "9.8"),
    ({"text": "walk", "seconds": 2, "lengths": 40}, 422, "not both"),
    ({"text": "walk", "nfe": 0}, 422, "nfe"),
    ({"text": "walk", "nfe": 1000}, 422, "nfe"),
    ({"text": "walk", "nfe": "5"}, 422, "nfe"),
    ({"text": "walk", "seed": -1}, 422, "seed"),
    ({"text": "walk", "format": "obj"}, 422, "format"),
    ({"texts": ["a", "b"], "format": "bvh"}, 422, "one motion"),
    ({"texts": ["a", "b"], "lengths": [10, 20, 30]}, 422, "3 values"),
    ({"texts": []}, 422, "texts"),
    ({"texts": ["walk"] * 33}, 422, "at most 32"),
    ({"text": 5}, 422, "valid string"),
    ({"text": "walk", "texts": ["run"]}, 422, "not both"),
    ({}, 422, "no prompt"),
    ({"text": "walk", "temperature": 2}, 422, "unknown field"),
    ({"text": "walk", "format": "glb", "rig": "blender"}, 422, "rig"),
    ({"text": "walk", "format": "gif", "rig": "mixamo"}, 422, "rig applies to"),
    ({"text": "walk", "candidates": 0}, 422, "candidates"),
    ({"text": "walk", "candidates": 65}, 422, "candidates"),
    ({"text": "walk", "candidates": "8"}, 422, "candidates"),
]


@pytest.fixture(scope="module")
def robust_client():
    client, _ = fake_client()
    with client:
        yield client


@pytest.mark.parametrize("body,status,words", BAD_REQUESTS,
                         ids=[str(i) for i in range(len(BAD_REQUESTS))])
def test_bad_request_is_a_one_line_4xx(robust_client, body, status, words):
    reply = robust_client.post("/generate", json=body)
    assert reply.status_code == status, reply.text
    detail = reply.json()["detail"]
    assert isinstance(detail, str) and "\n" not in detail
    assert words in detail
    assert robust_client.post("/generate", json=GOOD).status_code == 200


RAW_BODIES = [
    (b'{"text": "walk", ', "application/json", 400, "malformed JSON"),
    (b"not json at all", "application/json", 400, "malformed JSON"),
    (b'{"text": "walk", "seconds": NaN}', "application/json", 422, "finite"),
    (b'{"text": "walk", "seconds": Infinity}', "application/json", 422, "finite"),
    (b'{"text": "walk", "lengths": NaN}', "application/json", 422, "integer"),
    (b'{"text": "walk", "lengths": 1e999}', "application/json", 422, "integer"),
    (b'{"text": "\\ud800"}', "application/json", 422, "U+D800"),
    (b"[1, 2]", "application/json", 422, "dictionary"),
    (b"", "application/json", 422, "empty"),
    (b'{"text": "walk"}', "text/plain", 415, "Content-Type: application/json"),
]


@pytest.mark.parametrize("raw,content_type,status,words", RAW_BODIES,
                         ids=[str(i) for i in range(len(RAW_BODIES))])
def test_malformed_body_is_a_one_line_4xx(robust_client, raw, content_type, status, words):
    reply = robust_client.post("/generate", content=raw, headers={"content-type": content_type})
    assert reply.status_code == status, reply.text
    assert words in reply.json()["detail"]
    assert robust_client.post("/generate", json=GOOD).status_code == 200


def test_whitespace_is_collapsed_as_the_pipeline_does(robust_client):
    reply = robust_client.post("/generate", json={**GOOD, "text": "  walk\n\tforward  "})
    assert reply.status_code == 200
    assert reply.json()["motions"][0]["text"] == "walk forward"


def test_large_bodies_get_413_before_parsing():
    client, generator = fake_client(max_body_bytes=1000)
    with client:
        big = json.dumps({"text": "walk", "pad": "x" * 2000}).encode()
        reply = client.post("/generate", content=big,
                            headers={"content-type": "application/json"})
        assert reply.status_code == 413
        assert reply.json() == {"detail": "the request body exceeds 1000 bytes"}

        def chunks():  # no Content-Length: the limit applies while reading
            for _ in range(10):
                yield b" " * 500

        reply = client.post("/generate", content=chunks(),
                            headers={"content-type": "application/json"})
        assert reply.status_code == 413 and "1000 bytes" in reply.json()["detail"]
        assert client.post("/generate", json=GOOD).status_code == 200
    assert len(generator.calls) == 1  # only the good request reached the model


def test_model_errors_are_contained():
    client, _ = fake_client()
    with client:
        reply = client.post("/generate", json={**GOOD, "text": "explode"})
        assert reply.status_code == 422 and reply.json()["detail"] == \
            "the fake cannot make 'explode'"
        reply = client.post("/generate", json={**GOOD, "text": "crash"})
        assert reply.status_code == 500 and "RuntimeError" in reply.json()["detail"]
        assert client.post("/generate", json=GOOD).status_code == 200


# --- queue and batching ------------------------------------------------------------------------

def test_full_queue_gives_503_and_recovers():
    gate = threading.Event()
    client, generator = fake_client(gate, queue_depth=1, max_batch=1, max_texts=1)
    with client:
        first, first_reply = post_async(client, GOOD)  # runs, held at the gate
        assert generator.entered.wait(5)
        second, second_reply = post_async(client, GOOD)  # fills the queue
        wait_until(lambda: client.get("/health").json()["queue"]["queued"] == 1)
        reply = client.post("/generate", json=GOOD)
        assert reply.status_code == 503
        assert reply.headers["retry-after"] == "1" and "busy" in reply.json()["detail"]
        gate.set()
        first.join(5)
        second.join(5)
        assert first_reply[0].status_code == second_reply[0].status_code == 200
        assert client.post("/generate", json=GOOD).status_code == 200


def test_concurrent_requests_share_a_batch():
    gate = threading.Event()
    client, generator = fake_client(gate, batch_wait_ms=0)
    with client:
        head, _ = post_async(client, {**GOOD, "seed": 100})  # occupies the worker
        assert generator.entered.wait(5)
        waiting = [post_async(client, {**GOOD, "text": f"walk {i}", "seed": i})
                   for i in range(5)]
        wait_until(lambda: client.get("/health").json()["queue"]["queued"] == 5)
        gate.set()
        head.join(5)
        for thread, _ in waiting:
            thread.join(5)
        replies = [box[0] for _, box in waiting]
        assert [len(texts) for texts, _ in generator.calls] == [1, 5]
        for i, reply in enumerate(replies):
            body = reply.json()
            assert body["timing"]["batch_size"] == 5
            assert body["motions"][0]["text"] == f"walk {i}"
            assert body["motions"][0]["joints"][0][0][0] == i  # its own seed, not a neighbour's
        stats = client.get("/health").json()["queue"]
        assert stats["batch_sizes"] == {"1": 1, "5": 1} and stats["largest_batch"] == 5


def test_overlapping_requests_keep_the_model_threads_from_spinning(monkeypatch):
    """serve/batcher.py: while requests overlap (a batch of several, or more waiting) and for
    OVERLAP_WINDOW_S after, the generator's `spinning` is False; a request alone after that
    window leaves it to the generator (None). The spinning each call saw is recorded."""
    import mlct.serve.batcher as batcher

    monkeypatch.setattr(batcher, "OVERLAP_WINDOW_S", 1.5)  # wide: a slow machine stays inside
    seen: list = []

    class Spinning(FakeGenerator):
        spinning: bool | None = None

        def generate(self, *args, **kwargs):
            seen.append(self.spinning)
            return super().generate(*args, **kwargs)

    gate = threading.Event()
    generator = Spinning(gate)
    client = TestClient(create_app(generator, ServeSettings(warmup=False, batch_wait_ms=0)))
    with client:
        gate.set()
        assert client.post("/generate", json=GOOD).status_code == 200  # alone: None
        gate.clear()
        generator.entered.clear()
        head, _ = post_async(client, GOOD)  # held, while two more wait behind it
        assert generator.entered.wait(5)
        waiting = [post_async(client, {**GOOD, "seed": i}) for i in range(2)]
        wait_until(lambda: client.get("/health").json()["queue"]["queued"] == 2)
        gate.set()
        for thread, _ in [(head, None), *waiting]:
            thread.join(5)
        assert client.post("/generate", json=GOOD).status_code == 200  # within the window
        time.sleep(1.6)
        assert client.post("/generate", json=GOOD).status_code == 200  # alone again: None
    # the held call started alone (the others queued after it), the batch of two overlapped
    assert seen == [None, None, False, False, None]


def queued_behind_one(bodies: list[dict]) -> tuple[list[int], FakeGenerator]:
    """Hold the worker on one request, queue `bodies` behind it, release: their statuses, and
    the fake generator (its calls after the first are the queued bodies' batches)."""
    gate = threading.Event()
    client, generator = fake_client(gate, batch_wait_ms=0)
    with client:
        head, _ = post_async(client, GOOD)
        assert generator.entered.wait(5)
        waiting = [post_async(client, body) for body in bodies]
        wait_until(lambda: client.get("/health").json()["queue"]["queued"] == len(bodies))
        gate.set()
        for thread, _ in [(head, None), *waiting]:
            thread.join(5)
        return [box[0].status_code for _, box in waiting], generator


def test_batches_split_by_nfe_and_a_bad_request_fails_alone():
    statuses, generator = queued_behind_one([
        {**GOOD, "nfe": 1}, {**GOOD, "nfe": 4}, {**GOOD, "nfe": 1, "text": "explode"},
        {**GOOD, "nfe": 1, "text": "run"}])
    assert statuses == [200, 200, 422, 200]
    # nfe 1 (three texts, failed on 'explode', then one by one), nfe 4 (one text)
    # (the two NFE groups run in the order their first requests arrived: either may be first)
    calls = [(len(t), nfe) for t, nfe in generator.calls[1:]]
    assert [c for c in calls if c[1] == 1] == [(3, 1), (1, 1), (1, 1), (1, 1)]
    assert [c for c in calls if c[1] == 4] == [(1, 4)]


def test_requests_with_other_candidate_counts_are_not_merged():
    statuses, generator = queued_behind_one([{**GOOD, "candidates": c} for c in (2, 2, 1)])
    assert statuses == [200, 200, 200]
    calls = list(zip([len(t) for t, _ in generator.calls], generator.candidates_asked))
    assert sorted(calls[1:]) == [(1, 1), (2, 2)]  # the two asking 2 in one call


# --- the rest of the surface -------------------------------------------------------------------

def test_health_examples_docs_and_page():
    client, _ = fake_client(max_text_chars=120)
    with client:
        health = client.get("/health").json()
        assert health["status"] == "ok"
        assert health["model"]["skeleton"] == "humanml3d" and health["model"]["fps"] == 20.0
        assert health["limits"]["max_text_chars"] == 120
        assert health["limits"]["max_seconds"] == pytest.approx(9.8)
        examples = client.get("/examples").json()["examples"]
        assert len(examples) >= 6 and all(e.endswith(".") for e in examples)
        docs = client.get("/docs").text
        # the OpenAPI page works offline: every script and style it loads is served by us
        assets = re.findall(r'(?:src|href)="([^"]+)"', docs)
        assert any("swagger-ui-bundle.js" in a for a in assets)
        for asset in assets:
            assert asset.startswith("/"), asset  # no CDN address
            assert client.get(asset).status_code == 200, asset
        schema = client.get("/openapi.json").json()
        assert "/generate" in schema["paths"]
        request = next(v for k, v in schema["components"]["schemas"].items()
                       if k.startswith("GenerateRequest"))
        assert request["properties"]["nfe"]["anyOf"][0]["maximum"] == 50
        page = client.get("/")
        assert page.status_code == 200 and "/vendor/plotly.min.js" in page.text
        assert client.get("/static/app.js").status_code == 200
        plotly = client.get("/vendor/plotly.min.js")
        assert plotly.status_code == 200 and "javascript" in plotly.headers["content-type"]
        assert b"scatter3d" in plotly.content
        missing = client.get("/nowhere")
        assert missing.status_code == 404 and missing.json() == {"detail": "Not Found"}


def test_settings_are_checked():
    with pytest.raises(MlctError, match="max_texts"):
        ServeSettings(max_texts=64, max_batch=32)
    with pytest.raises(MlctError, match="max_text_chars"):
        ServeSettings(max_text_chars=10_000)
    with pytest.raises(MlctError, match="queue_depth"):
        ServeSettings(queue_depth=0)
    assert ServeSettings(max_frames=50).frame_limit(196) == 50
    assert ServeSettings().frame_limit(196) == 196


def test_cli_serve_passes_its_options(monkeypatch):
    import mlct.serve
    from mlct.cli import main

    calls = []
    monkeypatch.setattr(mlct.serve, "run_server", lambda *a, **k: calls.append((a, k)))
    assert main(["serve", "--port", "9123", "--host", "0.0.0.0", "--device", "cpu",
                 "--token", "a-long-secret"]) == 0
    assert main(["serve", "--backend", "onnx", "--threads", "3"]) == 0
    assert calls == [((None,), {"host": "0.0.0.0", "port": 9123, "device": "cpu",
                                "token": "a-long-secret", "backend": "auto", "threads": None}),
                     ((None,), {"host": "127.0.0.1", "port": 8000, "device": None,
                                "token": None, "backend": "onnx", "threads": 3})]
    with pytest.raises(SystemExit) as exited:
        main(["serve", "--threads", "0"])
    assert exited.value.code == 2 and len(calls) == 2


@pytest.mark.parametrize("host, loopback", [
    ("127.0.0.1", True), ("127.0.0.5", True), ("::1", True), ("[::1]", True),
    ("localhost", True), ("0.0.0.0", False), ("::", False), ("192.168.1.4", False),
    ("example.com", False),
])
def test_non_loopback_hosts_are_told_apart(host: str, loopback: bool) -> None:
    """`mlct serve --host 0.0.0.0` warns: is_loopback decides when."""
    from mlct.serve import is_loopback

    assert is_loopback(host) is loopback


def test_serving_beyond_this_machine_warns(monkeypatch, capsys) -> None:
    import uvicorn

    from mlct.serve import run_server

    monkeypatch.setattr(uvicorn, "run", lambda *args, **kwargs: None)
    monkeypatch.setattr(mlct, "load", lambda *args, **kwargs: object())
    monkeypatch.setattr("mlct.serve.create_app", lambda *args, **kwargs: None)
    monkeypatch.delenv("MLCT_TOKEN", raising=False)
    run_server(host="0.0.0.0", device="cpu")
    assert "warning: listening on 0.0.0.0" in capsys.readouterr().err
    run_server(host="127.0.0.1", device="cpu")
    assert capsys.readouterr().err == ""
    monkeypatch.setenv("MLCT_TOKEN", "a-long-secret")
    run_server(host="0.0.0.0", device="cpu")  # a token is required: nothing to warn about
    assert capsys.readouterr().err == ""


def test_token_guards_generate_and_stays_secret() -> None:
    """--token / MLCT_TOKEN: POST /generate needs the bearer token; health never shows it."""
    client, _ = fake_client(token="s3cret-token")
    body = {"text": "a person walks", "seconds": 1.0, "format": "json"}
    with client:
        missing = client.post("/generate", json=body)
        assert missing.status_code == 401 and missing.headers["www-authenticate"] == "Bearer"
        assert "Authorization: Bearer" in missing.json()["detail"]
        wrong = client.post("/generate", json=body, headers={"Authorization": "Bearer nope"})
        assert wrong.status_code == 401
        right = client.post("/generate", json=body,
                            headers={"Authorization": "Bearer s3cret-token"})
        assert right.status_code == 200 and right.json()["motions"]
        assert "s3cret-token" not in client.get("/health").text
    with pytest.raises(Exception, match="at least 8 characters"):
        ServeSettings(token="short")
