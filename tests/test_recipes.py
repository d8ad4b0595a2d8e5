"""The bundled-model recipe (tools/make_bundled_model.sh and the scripts it calls) and the GPU
hosts' scripts (bench/gpu/): they parse, and the recipe's shared `stage` trains a stage anew or
resumes it, keeping the data and autoencoder it was given."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parents[1] / "tools"


@pytest.mark.parametrize("script", ["make_bundled_model.sh", "make_bundled_model_3h.sh",
                                    "make_bundled_model_narrow_decoder.sh",
                                    "make_real_model.sh", "make_broad_model.sh",
                                    "make_broad_model_gpu.sh"])
def test_recipe_parses(script):
    subprocess.run(["bash", "-n", str(TOOLS / script)], check=True)


@pytest.mark.parametrize("script", ["make_real_model.sh", "make_broad_model.sh",
                                    "make_broad_model_gpu.sh"])
def test_the_real_data_recipes_need_a_real_dataset(tmp_path, script):
    done = subprocess.run(["bash", str(TOOLS / script), str(tmp_path / "w")],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "give one or more imported real datasets" in done.stderr
    assert not (tmp_path / "w").exists()


def _stage(tmp_path: Path, env: str, args: str) -> str:
    """Run `stage ARGS` with a stand-in `mlct` that prints its arguments."""
    return _stage_shell(tmp_path, f"{env} stage {args}")


def _stage_shell(tmp_path: Path, command: str) -> str:
    """Run COMMAND after sourcing recipe_stage.sh, with a stand-in `mlct` that prints its
    arguments."""
    fake = tmp_path / "bin"
    fake.mkdir(exist_ok=True)
    (fake / "mlct").write_text('#!/usr/bin/env bash\necho "mlct $*"\n')
    (fake / "mlct").chmod(0o755)
    script = (f'set -euo pipefail; export PATH="{fake}:$PATH"; work="{tmp_path}/w"; '
              f'source "{TOOLS}/recipe_stage.sh"; {command}')
    return subprocess.run(["bash", "-c", script], check=True, capture_output=True,
                          text=True).stdout.strip()


def test_stage_trains_then_resumes_with_its_data_and_autoencoder(tmp_path):
    w = tmp_path / "w"
    first = _stage(tmp_path, f'DATA="{w}/rich" AE="{w}/noise"', "cm cm --config small x=1")
    assert first == f"mlct train cm --data {w}/rich --out {w}/cm --ae {w}/noise --config small x=1"
    (w / "cm" / "cm" / "checkpoints" / "step-00000250").mkdir(parents=True)
    again = _stage(tmp_path, f'DATA="{w}/rich" AE="{w}/noise"', "cm cm --config small x=1")
    assert again == f"mlct train cm --data {w}/rich --out {w}/cm --ae {w}/noise --resume"
    plain = _stage(tmp_path, "", "run ae --config small")
    assert plain == f"mlct train ae --data {w}/synth --out {w}/run --config small"


@pytest.mark.parametrize("script", ["check.sh", "setup.sh", "carry.sh", "train_check.sh",
                                    "slim.sh", "train_broad.sh"])
def test_gpu_host_scripts_parse(script):
    subprocess.run(["bash", "-n", str(TOOLS.parent / "bench" / "gpu" / script)], check=True)


def _gpu_module(name):
    sys.path.insert(0, str(TOOLS.parent / "bench" / "gpu"))
    try:
        return __import__(name)
    finally:
        sys.path.pop(0)


def test_a_carried_dataset_comes_back_whole(tmp_path):
    """bench/gpu/dataset_carry.py: the features come back as float32 within float16's rounding,
    the joints recovered from them, everything else as it was; unpacking twice is the same."""
    import numpy as np
    from dataset_factory import make_dataset

    carry = _gpu_module("dataset_carry")
    features = make_dataset(tmp_path / "real")
    archive = tmp_path / "real.tar.xz"
    carry.pack(tmp_path / "real", archive)
    for _ in range(2):
        carry.unpack(archive, tmp_path / "there")
    back = tmp_path / "there" / "real"
    for name, truth in features.items():
        got = np.load(back / "new_joint_vecs" / f"{name}.npy")
        assert got.dtype == np.float32 and got.shape == truth.shape
        np.testing.assert_allclose(got, truth, rtol=1e-3, atol=1e-3)
        assert np.load(back / "new_joints" / f"{name}.npy").shape == (truth.shape[0], 22, 3)
        assert (back / "texts" / f"{name}.txt").read_text() == \
            (tmp_path / "real" / "texts" / f"{name}.txt").read_text()
    assert (back / "train.txt").read_text() == (tmp_path / "real" / "train.txt").read_text()
    assert not (back / carry.PACKED).exists()


def test_the_kept_minilm_rows_cover_the_captions_and_their_mirrors(tmp_path):
    """bench/gpu/minilm_tokens.py: the rows a dataset's captions use include those of the
    mirrored side words; `check` fails when one is missing."""
    from tokenizers import Tokenizer

    from dataset_factory import make_dataset
    from mlct.shipped import MINILM_DIR

    tokens = _gpu_module("minilm_tokens")
    make_dataset(tmp_path / "d", captions={"000001": ["a person waves the left hand#a/DET#0#0"]})
    ids = tokens.caption_token_ids([str(tmp_path / "d")])
    right = Tokenizer.from_file(str(MINILM_DIR / "tokenizer.json")).token_to_id("right")
    assert right in ids
    kept = tmp_path / "kept.txt"
    kept.write_text("\n".join(map(str, sorted(ids))))
    assert tokens.main(["check", str(kept), str(tmp_path / "d")]) == 0
    kept.write_text("\n".join(str(i) for i in sorted(ids) if i != right))
    assert tokens.main(["check", str(kept), str(tmp_path / "d")]) == 1


def test_interpolate_models_mixes_what_differs_and_refuses_bad_input(tmp_path):
    """tools/interpolate_models.py: alpha 0 is the base, 1 the fine-tune, 0.5 the midpoint;
    equal tensors and other files are the fine-tune's; bad input leaves nothing behind."""
    import numpy as np
    from safetensors.numpy import load_file, save_file

    sys.path.insert(0, str(TOOLS))
    try:
        from interpolate_models import interpolate
    finally:
        sys.path.pop(0)
    from mlct.errors import MlctError

    def model(name, denoiser):
        path = tmp_path / name
        path.mkdir()
        save_file({"denoiser.w": denoiser, "decoder.b": np.ones(3, np.float16),
                   "norm.mean": np.zeros(2, np.float32)}, str(path / "model.safetensors"))
        (path / "config.json").write_text(json.dumps({"step": name}))
        return path

    base = model("base", np.zeros((2, 2), np.float16))
    tuned = model("tuned", np.full((2, 2), 2.0, np.float16))
    for alpha, value in ((0.0, 0.0), (0.5, 1.0), (1.0, 2.0)):
        out = tmp_path / f"mix{alpha}"
        assert interpolate(base, tuned, alpha, out) == 1
        mixed = load_file(str(out / "model.safetensors"))
        assert mixed["denoiser.w"].dtype == np.float16
        np.testing.assert_array_equal(mixed["denoiser.w"], np.full((2, 2), value, np.float16))
        np.testing.assert_array_equal(mixed["decoder.b"], np.ones(3, np.float16))
        config = json.loads((out / "config.json").read_text())
        assert config["step"] == "tuned" and config["interpolated"]["alpha"] == alpha
    # several fine-tunes: their uniform average, then mixed with the base
    seed2 = model("seed2", np.full((2, 2), 4.0, np.float16))
    assert interpolate(base, [tuned, seed2], 0.5, tmp_path / "soup") == 1
    soup = load_file(str(tmp_path / "soup" / "model.safetensors"))
    np.testing.assert_array_equal(soup["denoiser.w"], np.full((2, 2), 1.5, np.float16))
    config = json.loads((tmp_path / "soup" / "config.json").read_text())
    assert config["interpolated"]["tuned"] == [str(tuned), str(seed2)]
    other = model("other", np.zeros((3, 2), np.float16))
    with pytest.raises(MlctError, match="same tensors"):
        interpolate(base, other, 0.5, tmp_path / "bad")
    with pytest.raises(MlctError, match="same tensors"):
        interpolate(base, [tuned, other], 0.5, tmp_path / "bad")
    with pytest.raises(MlctError, match="alpha"):
        interpolate(base, tuned, 1.5, tmp_path / "bad")
    with pytest.raises(MlctError, match="exists"):
        interpolate(base, tuned, 0.5, tmp_path / "mix0.5")
    assert not (tmp_path / "bad").exists()
    run = subprocess.run([sys.executable, str(TOOLS / "interpolate_models.py"), str(base),
                          str(tmp_path / "nope"), "--out", str(tmp_path / "cli")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "no model.safetensors" in run.stderr
    assert "Traceback" not in run.stderr


def test_caption_sets_made_once_in_order(tmp_path):
    """recipe_stage.sh caption_sets: the benchmark, then each caption set from the one before;
    a second call, with every set present, makes nothing."""
    w = tmp_path / "w"
    first = _stage_shell(tmp_path, "caption_sets 12").splitlines()
    assert [line.split()[2] for line in first] == ["synth", "rephrase", "oversample", "rephrase",
                                                   "rephrase", "oversample"]
    assert f"--out {w}/synth --num 12" in first[0]
    assert f"{w}/synth_coll --out {w}/synth_collturns --families turn,spin" in first[-1]
    for name in ("synth", "synth_rich", "synth_focus", "synth_short", "synth_coll",
                 "synth_collturns"):
        (w / name).mkdir(parents=True)
        (w / name / "synth.json").write_text("{}")
    assert _stage_shell(tmp_path, "caption_sets 12") == ""


def test_autoencoder_from_bundle_gives_the_recipes_stage_one_runs(tmp_path):
    """tools/autoencoder_from_bundle.py: `armdec` is the bundle's whole autoencoder, and `noise`
    encodes the body's 3 tokens exactly as the 6-token encoder's first 3: the latents the
    recipe's 3-token stage 2 read."""
    import torch

    from mlct.generate.bundle import bundle_autoencoder_state, read_bundle
    from mlct.train.stages import find_autoencoder, load_frozen_autoencoder

    bundle = Path(__file__).resolve().parents[1] / "src" / "mlct" / "assets" / "model"
    subprocess.run([sys.executable, str(TOOLS / "autoencoder_from_bundle.py"), str(bundle),
                    str(tmp_path)], check=True, capture_output=True)
    cpu = torch.device("cpu")
    six, norm, meta6 = load_frozen_autoencoder(find_autoencoder(tmp_path, tmp_path / "armdec"), cpu)
    three, _, meta3 = load_frozen_autoencoder(find_autoencoder(tmp_path, tmp_path / "noise"), cpu)
    _, tensors = read_bundle(bundle)
    shipped = bundle_autoencoder_state(tensors, bundle)
    assert all(torch.equal(value, shipped[key].float()) for key, value in six.state_dict().items())
    assert torch.equal(norm.mean, tensors["norm.mean"].float())
    assert (meta6["config"]["ae"]["n_tokens"], meta3["config"]["ae"]["n_tokens"]) == (6, 3)
    assert meta3["config"]["ae"]["arm_tokens"] == 0
    motion = torch.randn(3, 120, meta6["feature_dim"], generator=torch.Generator().manual_seed(0))
    lengths = torch.tensor([120, 80, 40])
    body = three.encode(motion, lengths).z
    assert body.shape[1] == 3
    assert torch.equal(body, six.encode(motion, lengths).z[:, :3])


def test_stage_two_defaults_to_version_six_denoiser_and_takes_another(tmp_path):
    """stage2_on_body (tools/recipe_stage.sh), the recipe's stage 2:
    version 6's 3 x 192 unless DENOISER names another size."""
    w = tmp_path / "w"
    plain = _stage_shell(tmp_path, "stage2_on_body 1")
    assert plain.startswith(f"mlct train cm --data {w}/synth_collturns --out {w}/cm "
                            f"--ae {w}/noise --config small denoiser.width=192 "
                            f"denoiser.ff_dim=768 denoiser.layers=3 ")
    assert "train.cm.seed=1 " in plain
    other = _stage_shell(tmp_path, 'DENOISER="denoiser.width=256 denoiser.layers=5" '
                                   "stage2_on_body 0")
    assert "denoiser.width=256 denoiser.layers=5 text.encoder" in other
    assert "width=192" not in other


def test_the_cmu_mirrors_extract_into_cmus_names(tmp_path: Path) -> None:
    """tools/extract_cmu_mirrors.sh (EXTRACT_ONLY=1): each snapshot's files land where the CMU
    importers look, motion-out's renamed takes named back to CMU's, the expmap takes the AMC
    imports hold left out, and a blob the snapshot lacks named and skipped."""
    from mlct.data.corpora.cmu_expmap import CMU_TAKES

    def repo(name: str, files: list[str]) -> Path:
        root = tmp_path / name
        for rel in files:
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_text(f"{name}:{rel}\n")
        git = ["git", "-C", str(root), "-c", "user.name=t", "-c", "user.email=t@t"]
        subprocess.run(git[:3] + ["init", "-q"], check=True)
        subprocess.run(git + ["add", "."], check=True)
        subprocess.run(git + ["commit", "-q", "-m", "snapshot"], check=True)
        return root / ".git"

    cyun = repo("cyun", ["data/CMU/asfamc/subjects/01/01.asf",
                         "data/CMU/asfamc/subjects/01/01_02.amc",
                         "data/CMU/asfamc/subjects/04/04_01.amc"])
    przestr = repo("przestr", ["data/02/02_01.bvh", "data/02/02_02.bvh", "data/readme.txt"])
    motion_out = repo("motion_out", ["assets/asf/moderndance.asf",
                                     "assets/amc/moderndance/md_02.amc",
                                     "assets/amc/moderndance/md_walk.amc",
                                     "assets/amc/mjackson/131_04.amc",
                                     "assets/amc/martialwalk/135_02.amc"])
    skipped = next(iter(CMU_TAKES))  # e.g. train/walking/walking_1
    expmap = repo("expmap", [f"data/cmu_mocap/{skipped}.txt",
                             "data/cmu_mocap/train/soccer/soccer_1.txt"])
    # a blob the snapshot lacks (as in a partial clone): its object removed
    blob = subprocess.run(["git", "--git-dir", str(przestr), "rev-parse",
                           "HEAD:data/02/02_02.bvh"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (przestr / "objects" / blob[:2] / blob[2:]).unlink()
    cmu131 = tmp_path / "cmu131"
    cmu131.mkdir()
    for take in ("01", "02", "03"):
        (cmu131 / f"131_{take}.bvh").write_text(take)
    out = tmp_path / "out"
    done = subprocess.run(["bash", str(TOOLS / "extract_cmu_mirrors.sh"), str(out),
                           str(cyun), str(przestr), str(motion_out), str(expmap), str(cmu131)],
                          capture_output=True, text=True, env={**os.environ, "EXTRACT_ONLY": "1"})
    assert done.returncode == 0, done.stderr
    raw = out / "raw"
    found = sorted(p.relative_to(raw).as_posix() for p in raw.rglob("*") if p.is_file())
    assert found == ["cmu1/131_01.bvh", "cmu1/131_02.bvh", "cmu1/131_03.bvh",
                     "cmu1/amc/01/01.asf", "cmu1/amc/01/01_02.amc", "cmu1/bvh/02/02_01.bvh",
                     "cmu2/05/05.asf", "cmu2/05/05_02.amc", "cmu2/131/131_04.amc",
                     "cmu2/135/135_02.amc", "expmap/train/soccer/soccer_1.txt"]
    assert (raw / "cmu2/05/05_02.amc").read_text() == \
        "motion_out:assets/amc/moderndance/md_02.amc\n"
    assert "absent from the snapshot: data/02/02_02.bvh" in done.stderr
    assert not (out / "commercial").exists()  # the imports did not run
