"""Rendering: GIF / PNG filmstrip outputs, colours by side, bad input, atomic writes, the CLI."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from mlct.cli import main
from mlct.errors import MlctError
from mlct.motion import render
from mlct.data.layout import dataset_caption
from mlct.motion.render import limb_sides, render_file, render_motion
from mlct.motion.skeleton import HUMANML3D, KIT, Skeleton


def _rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def walk(skeleton: Skeleton, n_frames: int, speed: float = 1.0) -> np.ndarray:
    """(T, J, 3) a stick walk facing +Z: legs and arms swing about x, the root moves along +z
    by `speed` metres per second (in the skeleton's unit), feet on y = 0."""
    scale = 1000.0 if skeleton.unit == "mm" else 1.0
    swing = {}
    for j, name in enumerate(skeleton.joint_names):
        side = 1.0 if "left" in name else -1.0 if "right" in name else 0.0
        if name.endswith("hip"):
            swing[j] = 0.5 * side
        elif name.endswith("shoulder"):
            swing[j] = -0.4 * side
    out = np.zeros((n_frames, skeleton.n_joints, 3))
    for t in range(n_frames):
        phase = np.sin(2 * np.pi * t / 10)  # a stride every 10 frames: every frame moves
        rotation = [np.eye(3)] * skeleton.n_joints
        for j, parent in enumerate(skeleton.parents):  # parents precede children
            if parent < 0:
                continue
            rotation[j] = rotation[parent] @ _rot_x(swing.get(j, 0.0) * phase)
            out[t, j] = out[t, parent] + rotation[parent] @ skeleton.rest_offsets[j]
        out[t, :, 1] -= out[t, :, 1].min()
        out[t, :, 2] += speed * scale * t / skeleton.fps
    return out


def gif_frames(path: Path) -> list[np.ndarray]:
    with Image.open(path) as im:
        frames = []
        for k in range(im.n_frames):
            im.seek(k)
            frames.append(np.asarray(im.convert("RGB")).astype(int))
    return frames


def colour_mask(image: np.ndarray, hex_colour: str, tol: int = 30) -> np.ndarray:
    rgb = np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)])
    return np.abs(image - rgb).max(axis=-1) <= tol


def test_gif_has_a_frame_per_motion_frame_that_moves(tmp_path):
    joints = walk(HUMANML3D, 16)
    out = render_motion(joints, tmp_path / "walk.gif", HUMANML3D, title="a person walks")
    assert out == tmp_path / "walk.gif"
    with Image.open(out) as im:
        assert im.format == "GIF"
        assert im.n_frames == 16
        assert im.info["duration"] == 50  # HumanML3D's 20 fps
        width, height = im.size
    assert width == round(render.FRAME_INCHES * render.DPI)
    assert 0.4 * width < height <= 1.3 * width  # square at most, plus the title
    frames = gif_frames(out)
    for a, b in zip(frames[:-1], frames[1:]):
        assert (a != b).any(axis=-1).sum() > 20  # the body moved
    assert (frames[0] == 255).all(axis=-1).mean() > 0.5  # a white frame, not a grey one
    assert not list(tmp_path.glob(".*"))  # no temporary file left behind


def test_gif_fps_and_single_frame(tmp_path):
    joints = walk(KIT, 8)
    with Image.open(render_motion(joints, tmp_path / "kit.gif", KIT)) as im:
        assert im.info["duration"] == 80  # KIT's 12.5 fps
    with Image.open(render_motion(joints, tmp_path / "f.gif", KIT, fps=10)) as im:
        assert im.info["duration"] == 100
    with Image.open(render_motion(joints[:1], tmp_path / "one.gif", "kit")) as im:
        assert im.n_frames == 1
    render_motion(joints[:1], tmp_path / "one.png", KIT)  # T = 1 filmstrip: one panel
    with pytest.raises(MlctError, match="fps"):
        render_motion(joints, tmp_path / "bad.gif", KIT, fps=0)


def test_png_filmstrip_is_one_wide_image(tmp_path):
    out = render_motion(walk(HUMANML3D, 40), tmp_path / "strip.png", HUMANML3D,
                        title="a person walks forward " * 12)  # long: wrapped, still one image
    with Image.open(out) as im:
        assert im.format == "PNG"
        assert getattr(im, "n_frames", 1) == 1
        width, height = im.size
        image = np.asarray(im.convert("RGB")).astype(int)
    assert width == round(render.FILMSTRIP_FRAMES * render.PANEL_INCHES * render.FILMSTRIP_DPI)
    assert width > 3 * height
    # A body in every panel: each panel's column band holds limb pixels of both sides.
    panel = width // render.FILMSTRIP_FRAMES
    for i in range(render.FILMSTRIP_FRAMES):
        band = image[:, i * panel:(i + 1) * panel]
        assert colour_mask(band, render.COLORS["left"]).sum() > 30
        assert colour_mask(band, render.COLORS["right"]).sum() > 30


def test_limb_sides_from_joint_names():
    # HumanML3D chains: right leg, left leg, spine, right arm, left arm.
    assert limb_sides(HUMANML3D) == ["right", "left", "center", "right", "left"]
    assert limb_sides(KIT) == ["right", "left", "center", "right", "left"]


def test_left_and_right_drawn_in_their_colours_and_not_mirrored(tmp_path):
    """Facing +Z, the body's left (+x) is on the viewer's right in the 3/4 front view."""
    out = render_motion(walk(HUMANML3D, 1), tmp_path / "pose.png", HUMANML3D)
    with Image.open(out) as im:
        image = np.asarray(im.convert("RGB")).astype(int)
    assert render.COLORS["left"] != render.COLORS["right"]
    left = np.nonzero(colour_mask(image, render.COLORS["left"]))
    right = np.nonzero(colour_mask(image, render.COLORS["right"]))
    assert len(left[0]) > 100 and len(right[0]) > 100
    assert left[1].mean() > right[1].mean()  # columns: left limbs to the right
    # Head above feet: y is drawn up (image rows grow downwards).
    head = np.nonzero(colour_mask(image, render.COLORS["center"], tol=20))
    assert head[0].min() < min(left[0].max(), right[0].max()) - 50


def test_kit_millimetres_get_the_same_view(tmp_path):
    joints = walk(KIT, 20)
    in_metres = dataclasses.replace(KIT, unit="m")
    a = render_motion(joints, tmp_path / "mm.png", KIT)
    b = render_motion(joints / 1000.0, tmp_path / "m.png", in_metres)
    with Image.open(a) as im_a, Image.open(b) as im_b:
        assert im_a.size == im_b.size
        diff = np.abs(np.asarray(im_a.convert("RGB")).astype(int)
                      - np.asarray(im_b.convert("RGB")).astype(int))
    assert (diff.max(axis=-1) > 40).mean() < 0.002  # the same picture, up to anti-aliasing


def test_bad_outputs_and_inputs_raise_one_line_errors(tmp_path):
    joints = walk(HUMANML3D, 4)
    with pytest.raises(MlctError, match=r"\.gif, \.mp4, \.png"):
        render_motion(joints, tmp_path / "x.jpg", HUMANML3D)
    with pytest.raises(MlctError, match=r"\(4, 21, 3\)"):
        render_motion(joints[:, :21], tmp_path / "x.gif", HUMANML3D)
    bad = joints.copy()
    bad[2, 5, 1] = np.nan
    with pytest.raises(MlctError, match="NaN"):
        render_motion(bad, tmp_path / "x.gif", HUMANML3D)
    with pytest.raises(MlctError, match="unknown skeleton"):
        render_motion(joints, tmp_path / "x.gif", "smpl-x")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("shape, named", [((10, 5), "(10, 5)"), ((10, 22, 2), "(10, 22, 2)"),
                                          ((10,), "(10,)"), ((10, 7, 3), "7 joints"),
                                          ((0, 263), "no frames")])
def test_render_file_names_a_bad_shape(tmp_path, shape, named):
    path = tmp_path / "m.npy"
    np.save(path, np.zeros(shape, dtype=np.float32))
    with pytest.raises(MlctError) as error:
        render_file(path, tmp_path / "m.gif")
    assert named in str(error.value)
    assert "\n" not in str(error.value)


def test_render_file_rejects_missing_unreadable_and_non_finite(tmp_path):
    with pytest.raises(MlctError, match="no such file"):
        render_file(tmp_path / "missing.npy", tmp_path / "m.gif")
    garbage = tmp_path / "garbage.npy"
    garbage.write_bytes(b"not a numpy file at all")
    with pytest.raises(MlctError, match="cannot read"):
        render_file(garbage, tmp_path / "m.gif")
    truncated = tmp_path / "truncated.npy"
    np.save(truncated, walk(HUMANML3D, 3))
    truncated.write_bytes(truncated.read_bytes()[:200])
    with pytest.raises(MlctError, match="cannot read"):
        render_file(truncated, tmp_path / "m.gif")
    nan = tmp_path / "nan.npy"
    features = np.zeros((5, 263), dtype=np.float32)
    features[3, 100] = np.inf
    np.save(nan, features)
    with pytest.raises(MlctError, match="NaN/inf .* first at frame 3"):
        render_file(nan, tmp_path / "m.gif")
    joints = tmp_path / "j.npy"
    np.save(joints, walk(HUMANML3D, 3))
    with pytest.raises(MlctError, match="22 joints but the kit skeleton has 21"):
        render_file(joints, tmp_path / "m.gif", skeleton="kit")
    assert not (tmp_path / "m.gif").exists()


def test_mp4_without_ffmpeg_says_so_before_rendering(tmp_path, monkeypatch):
    monkeypatch.setattr(render, "_ffmpeg_available", lambda: False)
    monkeypatch.setattr(render, "_Scene", None)  # rendering must not even start
    with pytest.raises(MlctError, match=r"mp4 needs ffmpeg: pip install imageio-ffmpeg "
                                        r"\(or apt-get install ffmpeg\), or write \.gif"):
        render_motion(walk(HUMANML3D, 3), tmp_path / "x.mp4", HUMANML3D)
    assert not list(tmp_path.iterdir())


def test_mp4_goes_through_ffmpeg_writer_frame_by_frame(tmp_path, monkeypatch):
    grabbed = []

    class FakeFFMpegWriter:  # stands in for matplotlib's writer where ffmpeg is missing
        def __init__(self, fps):
            self.fps = fps

        def saving(self, fig, outfile, dpi):
            import contextlib

            @contextlib.contextmanager
            def session():
                yield self
                Path(outfile).write_bytes(b"mp4")

            self.fig, self.dpi = fig, dpi
            return session()

        def grab_frame(self):
            grabbed.append(self.fps)

    monkeypatch.setattr(render, "_ffmpeg_available", lambda: True)
    monkeypatch.setattr(render, "FFMpegWriter", FakeFFMpegWriter)
    out = render_motion(walk(HUMANML3D, 7), tmp_path / "x.mp4", HUMANML3D)
    assert out.read_bytes() == b"mp4"
    assert grabbed == [HUMANML3D.fps] * 7


@pytest.mark.parametrize("suffix", [".gif", ".png"])
def test_failure_midway_leaves_no_output(tmp_path, monkeypatch, suffix):
    out = tmp_path / f"walk{suffix}"
    out.write_bytes(b"previous render")
    original = render._StickFigure.update

    def update(self, frame):
        if frame >= 3:
            raise RuntimeError("disk on fire")
        original(self, frame)

    monkeypatch.setattr(render._StickFigure, "update", update)
    with pytest.raises(RuntimeError, match="disk on fire"):
        render_motion(walk(HUMANML3D, 12), out, HUMANML3D)
    assert out.read_bytes() == b"previous render"  # untouched: never half-written
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]  # no temporary left


def _layout_motion(root: Path, folder: str, name: str, array: np.ndarray) -> Path:
    (root / folder).mkdir(parents=True, exist_ok=True)
    (root / "texts").mkdir(exist_ok=True)
    (root / "texts" / f"{name}.txt").write_text(
        "a person walks forward.#a/DET person/NOUN walk/VERB forward/ADV#0.0#0.0\n"
        "someone strolls ahead#someone/PRON stroll/VERB ahead/ADV#0.0#0.0\n", encoding="utf-8")
    path = root / folder / f"{name}.npy"
    np.save(path, array)
    return path


def test_caption_comes_from_the_dataset_texts(tmp_path, monkeypatch):
    path = _layout_motion(tmp_path, "new_joints", "000007", walk(HUMANML3D, 5).astype(np.float32))
    assert dataset_caption(path) == "a person walks forward."
    assert dataset_caption(tmp_path / "elsewhere" / "000007.npy") is None
    assert dataset_caption(tmp_path / "new_joints" / "000008.npy") is None  # no texts file
    titles = []
    monkeypatch.setattr(render, "render_motion",
                        lambda joints, out, skeleton, title=None, fps=None: titles.append(title))
    # mlct render titles with the dataset's caption unless --caption is given
    main(["render", str(path), "--out", str(tmp_path / "a.gif")])
    main(["render", str(path), "--out", str(tmp_path / "b.gif"), "--caption", "given"])
    assert titles == ["a person walks forward.", "given"]


def test_features_file_renders_through_recover_from_ric(tmp_path):
    from mlct.motion.features import joints_to_features

    motion = joints_to_features(walk(HUMANML3D, 13), HUMANML3D)
    path = _layout_motion(tmp_path, "new_joint_vecs", "000001", motion.features)
    out = render_file(path, tmp_path / "features.gif", caption=dataset_caption(path))
    with Image.open(out) as im:
        assert im.n_frames == 12  # T - 1 feature frames
    # The features draw the same body as the joints they came from.
    render_motion(motion.joints[:12], tmp_path / "joints.gif", HUMANML3D,
                  title="a person walks forward.")
    a, b = gif_frames(out), gif_frames(tmp_path / "joints.gif")
    assert all((np.abs(x - y).max(axis=-1) > 40).mean() < 0.002 for x, y in zip(a, b))


def test_cli_render_prints_the_path(tmp_path, capsys):
    path = tmp_path / "walk.npy"
    np.save(path, walk(KIT, 6))
    out = tmp_path / "walk.gif"
    assert main(["render", str(path), "--out", str(out), "--caption", "a walk"]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    with Image.open(out) as im:
        assert im.n_frames == 6


def test_cli_bad_input_exits_2_with_one_line(tmp_path, capsys):
    path = tmp_path / "flat.npy"
    np.save(path, np.zeros((10, 5)))
    assert main(["render", str(path), "--out", str(tmp_path / "x.gif")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mlct: error: ") and err.count("\n") == 1 and "(10, 5)" in err
    assert main(["render", str(path), "--out", str(tmp_path / "x.webm")]) == 2
    assert ".gif" in capsys.readouterr().err


def test_cli_as_a_user_calls_it(tmp_path):
    path = tmp_path / "walk.npy"
    np.save(path, walk(HUMANML3D, 5))
    ok = subprocess.run([sys.executable, "-m", "mlct.cli", "render", str(path), "--out",
                         str(tmp_path / "w.png")], capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.strip() == str(tmp_path / "w.png")
    bad = subprocess.run([sys.executable, "-m", "mlct.cli", "render", str(tmp_path / "nope.npy"),
                          "--out", str(tmp_path / "w.gif")], capture_output=True, text=True,
                         timeout=120)
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "no such file" in bad.stderr


def test_render_reads_mlct_bvh_and_names_what_it_cannot(tmp_path: Path) -> None:
    """`mlct render x.bvh` had said 'cannot read ... as .npy: pickled data'."""
    from mlct.motion.bvh import write_bvh
    from motion_builders import random_motion

    joints = np.asarray(random_motion(HUMANML3D, 12, seed=0))
    write_bvh(tmp_path / "m.bvh", joints, HUMANML3D, 20.0)
    out = render_file(tmp_path / "m.bvh", tmp_path / "m.png")
    assert Image.open(out).size[0] > 100
    foreign = (tmp_path / "m.bvh").read_text().replace("pelvis", "Hips")
    (tmp_path / "cmu.bvh").write_text(foreign)
    with pytest.raises(MlctError, match="not those of a known skeleton"):
        render_file(tmp_path / "cmu.bvh", tmp_path / "c.png")
    (tmp_path / "m.txt").write_text("hello")
    with pytest.raises(MlctError, match="reads .npy"):
        render_file(tmp_path / "m.txt", tmp_path / "t.png")


def test_mp4_works_after_the_install_alone(tmp_path, monkeypatch):
    """No system ffmpeg needed; the imageio-ffmpeg wheel (a dependency) provides it."""
    pytest.importorskip("imageio_ffmpeg")
    monkeypatch.setenv("PATH", "")  # as on a machine without a system ffmpeg
    out = render_motion(walk(HUMANML3D, 6), tmp_path / "x.mp4", HUMANML3D)
    head = out.read_bytes()[:12]
    assert head[4:8] == b"ftyp" and out.stat().st_size > 1000  # an ISO media file


def test_frames_say_which_side_is_which(tmp_path: Path) -> None:
    """A 'left'/'right' legend in the limbs' colours, bottom right of every image."""
    out = render_motion(walk(HUMANML3D, 8), tmp_path / "x.png", HUMANML3D, title="a walk")
    image = np.asarray(Image.open(out).convert("RGB")).astype(int)
    h, w, _ = image.shape
    corner = image[int(h * 0.85):, int(w * 0.94):].reshape(-1, 3)

    def has(colour: str) -> bool:
        rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])
        return bool((np.abs(corner - rgb).sum(1) < 60).any())

    assert has(render.COLORS["left"]) and has(render.COLORS["right"])
