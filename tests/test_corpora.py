"""Real corpora importers (mlct.data.corpora): a corpus's release folder -> a clean dataset with
captions from the clips' labels and every motion's provenance and license. The clips here are
made in the tests, in the corpus's rig and file names; the real files are never in the tree."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mlct.cli import main
from mlct.cli.data import CORPUS_NAMES
from mlct.data.check import check_dataset
from mlct.data.corpora import CORPORA, import_corpus
from mlct.data.corpora.bandai_namco import BANDAI_NAMCO, CONTENTS, STYLES
from mlct.data.corpora.wording import FORMS
from mlct.data.importer import _load_bvh
from mlct.data.synth.build import make_motion
from mlct.errors import MlctError
from mlct.motion.skeleton import HUMANML3D

pytestmark = pytest.mark.usefixtures("one_thread")

# The Bandai Namco rig: (joint, parent, the HumanML3D joint whose position it takes).
_BANDAI = [("joint_Root", None, None), ("Hips", "joint_Root", "pelvis"),
           ("Spine", "Hips", "spine1"), ("Chest", "Spine", "spine2"),
           ("Neck", "Chest", "neck"), ("Head", "Neck", "head")]
for _s in ("L", "R"):
    _side = "left" if _s == "L" else "right"
    _BANDAI += [(f"Shoulder_{_s}", "Chest", f"{_side}_collar"),
                (f"UpperArm_{_s}", f"Shoulder_{_s}", f"{_side}_shoulder"),
                (f"LowerArm_{_s}", f"UpperArm_{_s}", f"{_side}_elbow"),
                (f"Hand_{_s}", f"LowerArm_{_s}", f"{_side}_wrist"),
                (f"UpperLeg_{_s}", "Hips", f"{_side}_hip"),
                (f"LowerLeg_{_s}", f"UpperLeg_{_s}", f"{_side}_knee"),
                (f"Foot_{_s}", f"LowerLeg_{_s}", f"{_side}_ankle"),
                (f"Toes_{_s}", f"Foot_{_s}", f"{_side}_foot")]


def bandai_rig_bvh(path: Path, joints: np.ndarray, fps: float = 30.0) -> None:
    """HumanML3D joints (T, 22, 3) in metres as a BVH in the Bandai Namco rig, in centimetres,
    six channels a joint as the corpus has: each joint's position channels hold its offset from
    its parent and its rotations are zero, so the file's world positions are the joints'."""
    cm = joints * 100.0
    world = {}
    for name, parent, ours in _BANDAI:
        world[name] = (cm[:, HUMANML3D.joint_names.index(ours)] if ours else
                       cm[:, 0] * np.array([1.0, 0.0, 1.0]))  # the root on the floor
    children: dict[str | None, list[str]] = {}
    for name, parent, _ in _BANDAI:
        children.setdefault(parent, []).append(name)
    lines = ["HIERARCHY"]

    def block(name: str, depth: int) -> None:
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET 0 0 0")
        lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation "
                     f"Xrotation")
        for child in children.get(name, []):
            block(child, depth + 1)
        if name not in children:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0 1", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    block("joint_Root", 0)
    order = [n for n, _, _ in _BANDAI]
    depth_first: list[str] = []

    def visit(name: str) -> None:
        depth_first.append(name)
        for child in children.get(name, []):
            visit(child)

    visit("joint_Root")
    assert sorted(depth_first) == sorted(order)
    parent_of = {n: p for n, p, _ in _BANDAI}
    lines += ["MOTION", f"Frames: {len(cm)}", f"Frame Time: {1.0 / fps:.8f}"]
    for t in range(len(cm)):
        values = []
        for name in depth_first:
            parent = parent_of[name]
            local = world[name][t] - (world[parent][t] if parent else 0.0)
            values += [f"{v:.5f}" for v in local] + ["0", "0", "0"]
        lines.append(" ".join(values))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _joints_at_30fps(index: int) -> np.ndarray:
    joints = make_motion(index, seed=0, skeleton=HUMANML3D).joints.astype(np.float64)
    at = np.arange(0, len(joints) - 1, 20.0 / 30.0)  # 20 fps -> 30 fps, linearly
    low = np.floor(at).astype(int)
    weight = (at - low)[:, None, None]
    return (1 - weight) * joints[low] + weight * joints[low + 1]


@pytest.fixture(scope="module")
def release(tmp_path_factory):
    """A folder laid out like the corpus's release: two subsets, clips named by their labels."""
    root = tmp_path_factory.mktemp("bandai")
    one = root / "Bandai-Namco-Research-Motiondataset-1" / "data"
    two = root / "Bandai-Namco-Research-Motiondataset-2" / "data"
    one.mkdir(parents=True)
    two.mkdir(parents=True)
    clips = {one / "dataset-1_walk_tired_001.bvh": 1, one / "dataset-1_bow_normal_001.bvh": 5,
             two / "dataset-2_wave-left-hand_elderly_003.bvh": 2}
    joints = {}
    for path, index in clips.items():
        joints[path.stem] = _joints_at_30fps(index)
        bandai_rig_bvh(path, joints[path.stem])
    return root, joints


def test_the_rig_maps_onto_the_skeleton_with_spine3_between_chest_and_neck(release):
    root, joints = release
    path = next(root.rglob("dataset-1_walk_tired_001.bvh"))
    positions, fps = _load_bvh(path, HUMANML3D, BANDAI_NAMCO.joint_map, BANDAI_NAMCO.between)
    assert fps == pytest.approx(30.0)
    source = joints[path.stem] * 100.0
    names = HUMANML3D.joint_names
    spine3 = names.index("spine3")
    others = [j for j in range(len(names)) if j != spine3]
    np.testing.assert_allclose(positions[:, others], source[:, others], atol=1e-3)
    halfway = (source[:, names.index("spine2")] + source[:, names.index("neck")]) / 2
    np.testing.assert_allclose(positions[:, spine3], halfway, atol=1e-3)


def test_a_release_folder_imports_as_a_clean_dataset_with_provenance(release, tmp_path):
    root, _ = release
    out = tmp_path / "real"
    summary = import_corpus("bandai-namco", root, out, seed=0)
    assert summary.clips == 3 and summary.motions == 3
    assert check_dataset(out) == []
    records = [json.loads(line) for line in (out / "provenance.jsonl").read_text().splitlines()]
    by_name = {r["name"]: r for r in records}
    assert set(by_name) == {"dataset-1_walk_tired_001", "dataset-1_bow_normal_001",
                            "dataset-2_wave-left-hand_elderly_003"}
    wave = by_name["dataset-2_wave-left-hand_elderly_003"]
    assert wave["license"] == "CC BY-NC 4.0" and wave["commercial_use"] is False
    assert wave["labels"] == {"content": "wave-left-hand", "style": "elderly",
                              "subset": "dataset-2", "take": "003"}
    assert wave["file"] == ("Bandai-Namco-Research-Motiondataset-2/data/"
                            "dataset-2_wave-left-hand_elderly_003.bvh")
    features = len(np.load(out / "new_joints" / f"{wave['name']}.npy"))
    assert wave["window"] == [0, features + 1]  # joint frames of the clip at 20 fps
    assert "arXiv:2306.08861" in wave["citation"]
    # the floor tilt the import took out (motion/floor.py): these clips stand level
    assert all(r["floor_tilt_deg"] == 0.0 for r in records)
    # captions from the labels: several distinct wordings, each saying the content and style
    texts = (out / "texts" / "dataset-2_wave-left-hand_elderly_003.txt").read_text().splitlines()
    captions = [line.split("#")[0] for line in texts]
    assert len(captions) == 4 == len(set(captions))
    assert all("left" in c and "wav" in c for c in captions)
    assert all(("old" in c or "elderly" in c) for c in captions)
    walk = [line.split("#")[0] for line in
            (out / "texts" / "dataset-1_walk_tired_001.txt").read_text().splitlines()]
    assert all("walk" in c or "steps" in c for c in walk)
    assert all(any(w in c for w in ("tired", "weary", "wearily")) for c in walk)


def test_the_import_is_seeded(release, tmp_path):
    root, _ = release
    import_corpus("bandai-namco", root, tmp_path / "a", seed=3)
    import_corpus("bandai-namco", root, tmp_path / "b", seed=3)
    for name in ("texts/dataset-1_bow_normal_001.txt", "train.txt", "provenance.jsonl"):
        assert (tmp_path / "a" / name).read_text() == (tmp_path / "b" / name).read_text()


def test_contents_keep_only_those_clips(release, tmp_path):
    root, _ = release
    summary = import_corpus("bandai-namco", root, tmp_path / "bows", contents={"bow"})
    assert summary.clips == 1
    with pytest.raises(MlctError, match="no bandai-namco clips of content dance"):
        import_corpus("bandai-namco", root, tmp_path / "x", contents={"dance"})
    assert not (tmp_path / "x").exists()


def test_the_command_line(release, tmp_path, capsys):
    root, _ = release
    out = tmp_path / "cli"
    assert main(["data", "import", "--corpus", "bandai-namco", str(root), "--out", str(out),
                 "--quiet"]) == 0
    assert "imported 3 clip(s) as 3 motion(s)" in capsys.readouterr().out
    assert main(["data", "check", str(out)]) == 0


@pytest.mark.parametrize("argv, message", [
    (["--corpus", "mocapland", "DIR"], "unknown corpus 'mocapland'; known: bandai-namco"),
    (["--corpus", "bandai-namco", "DIR", "--captions", "c.csv"],
     "--corpus makes its own captions, joint map and units; drop --captions"),
    (["--corpus", "bandai-namco", "/nonexistent/folder"], "/nonexistent/folder: no such directory"),
    (["--bvh", "DIR"], "--captions FILE is needed with --joints or --bvh"),
])
def test_bad_corpus_arguments_are_one_line_errors(argv, message, tmp_path, capsys):
    code = main(["data", "import", *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_a_badly_named_clip_is_named_in_the_error(tmp_path):
    (tmp_path / "dataset-1_walk_001.bvh").write_text("HIERARCHY\n")
    with pytest.raises(MlctError, match="dataset-1_walk_001.bvh: not a Bandai Namco clip name"):
        import_corpus("bandai-namco", tmp_path, tmp_path / "out")
    (tmp_path / "dataset-1_walk_001.bvh").unlink()
    (tmp_path / "dataset-1_swim_sad_001.bvh").write_text("HIERARCHY\n")
    with pytest.raises(MlctError, match="unknown content 'swim'"):
        import_corpus("bandai-namco", tmp_path, tmp_path / "out")


def test_every_label_has_words_and_every_verb_a_form():
    rng = np.random.default_rng(0)
    for content, phrases in CONTENTS.items():
        for phrase in phrases:
            for verb in __import__("re").findall(r"<(\w+)>", phrase):
                assert verb in FORMS, (content, verb)
        for style in STYLES:
            said = BANDAI_NAMCO.caption({"content": content, "style": style}, rng, 3)
            assert len(said) == 3 and all(s.endswith(".") and "<" not in s for s in said)
            assert not any(" a old" in s or s.startswith("a old") or " an tired" in s
                           for s in said)


def test_the_parser_knows_every_corpus():
    assert set(CORPUS_NAMES) == set(CORPORA)


def test_a_leading_reference_pose_and_its_blend_are_dropped():
    from mlct.data.importer import drop_reference_pose

    motion = make_motion(1, seed=0, skeleton=HUMANML3D).joints.astype(np.float64)
    names = HUMANML3D.joint_names
    t_pose = motion[0].copy()
    for side, sign in (("left", 1.0), ("right", -1.0)):
        shoulder = t_pose[names.index(f"{side}_shoulder")]
        t_pose[names.index(f"{side}_elbow")] = shoulder + [sign * 0.26, 0.0, 0.0]
        t_pose[names.index(f"{side}_wrist")] = shoulder + [sign * 0.52, 0.0, 0.0]
    blend = (t_pose + motion[0]) / 2  # half way down in one frame: faster than a body moves
    clip = np.concatenate([t_pose[None], blend[None], motion])
    kept = drop_reference_pose(clip, HUMANML3D, fps=20.0)
    np.testing.assert_array_equal(kept, motion)
    np.testing.assert_array_equal(drop_reference_pose(motion, HUMANML3D, 20.0), motion)


def test_end_sites_are_read_as_joints_where_asked(tmp_path):
    from mlct.motion.bvh import read_bvh

    path = tmp_path / "clip.bvh"
    bandai_rig_bvh(path, _joints_at_30fps(1)[:5])
    plain = read_bvh(path)
    with_ends = read_bvh(path, end_sites=True)
    assert "Toes_L.end" in with_ends.joint_names and "Toes_L.end" not in plain.joint_names
    toe = with_ends.joint_names.index("Toes_L")
    end = with_ends.joint_names.index("Toes_L.end")
    assert with_ends.parents[end] == toe
    # zero rotations: the End Site is its OFFSET (0 0 1) from its joint
    np.testing.assert_allclose(with_ends.positions[:, end] - with_ends.positions[:, toe],
                               np.tile([0.0, 0.0, 1.0], (5, 1)), atol=1e-9)
    np.testing.assert_allclose(with_ends.positions[:, :len(plain.joint_names)], plain.positions)


def test_leg_scale_gives_any_body_the_skeletons_legs():
    from mlct.data.importer import leg_scale

    motion = make_motion(1, seed=0, skeleton=HUMANML3D).joints.astype(np.float64)
    base = leg_scale(motion, HUMANML3D)
    assert base == pytest.approx(1.0, abs=0.02)
    assert leg_scale(motion * 39.37, HUMANML3D) == pytest.approx(base / 39.37)  # inches
    assert leg_scale(motion * 0.75, HUMANML3D) == pytest.approx(base / 0.75)  # a small body


def test_cmu_takes_are_captioned_from_the_index_and_unknown_ones_left_out(tmp_path):
    from mlct.data.corpora.cmu import CMU, read_index

    index = read_index()
    assert len(index) > 2400 and index["07_01"] == "walk" and index["02_05"] == "punch/strike"
    for take in ("07_01", "02_05", "99_99", "01_02"):  # a walk, a punch, no such take, a climb
        bandai_rig_bvh(tmp_path / f"{take}.bvh", _joints_at_30fps(1))
    clips = CMU.find(tmp_path)
    assert [c.name for c in clips] == ["cmu_02_05", "cmu_07_01"]
    said = CMU.caption(clips[0].labels, np.random.default_rng(0), 3)
    assert all("punch" in s or "strike" in s for s in said)
    assert CMU.commercial and "mocap.cs.cmu.edu" in CMU.citation


def test_a_merge_with_the_benchmark_keeps_every_motions_provenance(release, tmp_path):
    from mlct.data.merge import merge_datasets
    from mlct.data.synth.build import synthesize_dataset

    root, _ = release
    synthesize_dataset(tmp_path / "synth", num=6, seed=0, progress=False)
    import_corpus("bandai-namco", root, tmp_path / "real")
    merge_datasets([tmp_path / "synth", tmp_path / "real"], tmp_path / "mixed")
    records = [json.loads(line) for line in
               (tmp_path / "mixed" / "provenance.jsonl").read_text().splitlines()]
    names = {p.stem for p in (tmp_path / "mixed" / "new_joint_vecs").iterdir()}
    assert {r["name"] for r in records} == names and len(records) == len(names) == 9
    procedural = [r for r in records if not r["name"].startswith("d2_")]
    real = [r for r in records if r["name"].startswith("d2_")]
    assert len(procedural) == 6 and all(r["corpus"] == "procedural" and r["commercial_use"]
                                        for r in procedural)
    assert len(real) == 3 and all(r["corpus"] == "bandai-namco" and r["license"] ==
                                  "CC BY-NC 4.0" and not r["commercial_use"] for r in real)
    assert check_dataset(tmp_path / "mixed") == []
    # the action classifier's records: the real motions by their corpus labels; the merge kept
    # no labels.jsonl (the real source has none), so the benchmark's motions have no record
    from mlct.eval.judge.action_classifier import action_records

    actions = action_records(tmp_path / "mixed")
    assert set(actions) == {r["name"] for r in real}
    assert {a["actions"][0]["family"] for a in actions.values()} == {"walk", "bow",
                                                                      "wave-left-hand"}


def test_the_real_suite_measures_reconstructions_and_spread(release, tmp_path, capsys):
    import argparse

    from mlct.data.layout import DatasetLayout
    from mlct.eval.suites import real

    root, _ = release
    import_corpus("bandai-namco", root, tmp_path / "real", split=(0.0, 0.0, 1.0))
    args = argparse.Namespace(data=tmp_path / "real", ae=Path("identity"), model=None,
                              split="test", json=tmp_path / "r.json", min_motions=2, labels=None,
                              load_autoencoder=lambda path: (lambda x: x))
    real.run(args)
    report = json.loads((tmp_path / "r.json").read_text())
    recon = report["reconstruction"]
    assert set(recon) == {"walk", "bow", "wave-left-hand"}
    # (0) the floor: three motions, the one walk among them counted for the flight read-out
    assert report["floor"]["motions"] == 3 and report["floor"]["walks"] == 1
    assert all(r["mpjpe_m"] == 0.0 and r["pose_m"] == 0.0 for r in recon.values())
    # the identity keeps the walk as it is, off the floor by 5 cm nowhere; a decoder that lifts
    # the body in the clip's middle third by 10 cm makes it read as in flight at both clearances
    flight = report["reconstruction_walks_in_flight"]
    assert flight["walks"] == 1 and flight["made"] == flight["data"] and flight["data"]["5cm"] == 0

    def lifting(x):
        x = x.copy()
        middle = slice(len(x) // 3, 2 * len(x) // 3)
        x[middle, 3] += 0.1  # the root's height
        x[middle, 5:4 + 21 * 3:3] += 0.1  # the other 21 joints' heights (ric y, not root-relative)
        return x

    names = DatasetLayout.existing(tmp_path / "real").read_split("test")
    labels = real.motion_labels(tmp_path / "real")
    lifted = real.reconstructions(DatasetLayout.existing(tmp_path / "real"), names, labels,
                                  lifting)["walks_in_flight"]
    assert lifted["made"] == {"2cm": 1, "5cm": 1} and lifted["data"] == flight["data"]
    # the three motions as one label: the identity keeps their differences, a mean loses them
    layout = DatasetLayout.existing(tmp_path / "real")
    one = {name: "one" for name in real.motion_labels(tmp_path / "real")}
    kept = real.reconstruction_spread(layout, one, lambda x: x, args)["one"]
    assert kept["n"] == 3 and kept["data_m"] > 0.05 and kept["ratio"] == 1.0
    mean = layout.load_features(sorted(one)[0])[:1]
    lost = real.reconstruction_spread(layout, one, lambda x: np.repeat(mean, len(x), 0), args)
    assert lost["one"]["ratio"] < 0.5
    still = np.zeros((10, 22, 3))
    assert real.pairwise_distance([still, still + [0.0, 0.0, 0.3], still[:5]]) == \
        pytest.approx((0.3 + 0.0 + 0.3) / 3)


def test_cmu_prefers_its_own_amc_take_to_a_bvh_conversion(tmp_path):
    from mlct.data.corpora.cmu import CMU

    (tmp_path / "amc").mkdir()
    (tmp_path / "bvh").mkdir()
    (tmp_path / "amc" / "02.asf").write_text(":bonedata\n")
    for name in ("amc/02_05.amc", "amc/02_06.amc", "bvh/02_05.bvh", "bvh/07_01.bvh"):
        (tmp_path / name).write_text("")
    (tmp_path / "amc" / "03_01.amc").write_text("")  # no 03.asf beside it: not a take
    found = {c.name: c.path.relative_to(tmp_path).as_posix() for c in CMU.find(tmp_path)}
    assert found == {"cmu_02_05": "amc/02_05.amc", "cmu_02_06": "amc/02_06.amc",
                     "cmu_07_01": "bvh/07_01.bvh"}


def test_a_model_trained_on_non_commercial_data_says_so_when_loaded(release, tmp_path):
    import shutil
    import warnings

    import mlct
    from mlct.data.corpora import training_data
    from mlct.data.merge import merge_datasets
    from mlct.data.synth.build import synthesize_dataset
    from mlct.errors import MlctWarning
    from mlct.generate import bundle

    root, _ = release
    synthesize_dataset(tmp_path / "synth", num=6, seed=0, progress=False)
    import_corpus("bandai-namco", root, tmp_path / "real", split=(1.0, 0.0, 0.0))
    merge_datasets([tmp_path / "synth", tmp_path / "real"], tmp_path / "mixed")
    summary = training_data(tmp_path / "mixed")
    by_corpus = {c["corpus"]: c for c in summary["corpora"]}
    assert by_corpus["bandai-namco"]["motions"] == 3
    assert by_corpus["bandai-namco"]["commercial_use"] is False
    assert by_corpus["procedural"]["commercial_use"] is True

    model = tmp_path / "model"
    shutil.copytree(Path(mlct.__file__).parent / "assets" / "model", model)
    config = json.loads((model / "config.json").read_text())
    config["training_data"] = summary
    (model / "config.json").write_text(json.dumps(config))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        bundle.read_bundle(model)
        bundle.read_bundle(model)  # once a process
    said = [str(w.message) for w in caught if issubclass(w.category, MlctWarning)]
    assert len(said) == 1 and "Bandai Namco Research Motion Dataset (CC BY-NC 4.0)" in said[0]
    assert "non-commercial use only" in said[0]
    with warnings.catch_warnings(record=True) as caught:  # the bundled model says nothing
        warnings.simplefilter("always")
        bundle.read_bundle(Path(mlct.__file__).parent / "assets" / "model")
    assert not [w for w in caught if issubclass(w.category, MlctWarning)]


def test_provenance_is_read_in_one_place_and_a_broken_line_is_named(tmp_path):
    from mlct.data.layout import BadFileError, provenance_label, read_provenance

    assert read_provenance(tmp_path) == []
    (tmp_path / "provenance.jsonl").write_text('{"name": "a", "labels": {"content": "bow"}}\n'
                                               '{"name": "b", "labels": {"description": "Walk"}}'
                                               '\n{broken\n')
    with pytest.raises(BadFileError, match=r"provenance.jsonl:3: not JSON"):
        read_provenance(tmp_path)
    assert provenance_label({"labels": {"description": "Slow Walk"}}) == "slow walk"
    assert provenance_label({"labels": {"content": "bow", "style": "old"}}) == "bow"


def test_a_real_corpus_trains_the_action_classifier_on_its_corpus_labels(release, tmp_path):
    from mlct.eval.judge.action_classifier import (action_records, load_action_classifier,
                                                   train_action_classifier)

    root, _ = release
    out = tmp_path / "real"
    import_corpus("bandai-namco", root, out, split=(1.0, 0.0, 0.0))
    records = action_records(out)
    assert {r["actions"][0]["family"] for r in records.values()} == {"walk", "bow",
                                                                    "wave-left-hand"}
    summary = train_action_classifier(out, tmp_path / "clf", steps=3, batch_size=3,
                                      progress=False)
    assert summary["classes"] == ["bow", "walk", "wave-left-hand"]
    assert load_action_classifier(tmp_path / "clf").classes == summary["classes"]
    # a dataset with neither file still says what is missing
    bare = tmp_path / "bare"
    bare.mkdir()
    with pytest.raises(MlctError, match="labels.jsonl: missing"):
        action_records(bare)


def test_the_variety_verdict_names_each_part_of_the_goal():
    from mlct.eval.suites.real import variety_verdict

    rows = {"walk": {"defaults_m": 0.40, "data_m": 0.50}, "wave": {"defaults_m": 0.03,
                                                                   "data_m": 0.04}}
    assert variety_verdict(rows) == ("goal: median ratio >= 0.8 (0.78: not met); every label's "
                                     "seeds >= 5 cm apart (1 of 2: not met)")
    rows["wave"]["defaults_m"] = 0.05
    assert variety_verdict(rows) == ("goal: median ratio >= 0.8 (1.02: met); every label's "
                                     "seeds >= 5 cm apart (2 of 2: met)")
