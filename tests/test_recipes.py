"""The bundled-model recipes (tools/make_bundled_model*.sh): they parse, and their shared
`stage` trains a stage anew or resumes it, keeping the data and autoencoder it was given."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parents[1] / "tools"


@pytest.mark.parametrize("script", ["make_bundled_model.sh", "make_bundled_model_3h.sh",
                                    "make_bundled_model_staged.sh",
                                    "make_bundled_model_gpu.sh",
                                    "make_bundled_model_3h_stage2.sh",
                                    "make_bundled_model_narrow_decoder.sh"])
def test_recipe_parses(script):
    subprocess.run(["bash", "-n", str(TOOLS / script)], check=True)


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


def test_recipe_time_counts_training_and_skips_pauses(tmp_path):
    """tools/recipe_time.py: logged intervals under the gap count, a stopped session does not;
    a resumed stage (a second events file) adds its own intervals."""
    import sys

    from torch.utils.tensorboard import SummaryWriter

    tb = tmp_path / "w" / "cm" / "cm" / "tb"
    for times in ([0, 60, 120], [120 + 3600, 120 + 3660]):  # a pause of an hour, then 1 min
        writer = SummaryWriter(str(tb), filename_suffix=f".{times[0]}")
        for i, t in enumerate(times):
            writer.add_scalar("loss", 1.0, 100 * i, walltime=1_000_000 + t)
        writer.close()
    sys.path.insert(0, str(TOOLS))
    try:
        from recipe_time import stage_time
    finally:
        sys.path.remove(str(TOOLS))
    seconds, step, pauses, processes = stage_time(tb, gap_s=600)
    assert (seconds, step, processes) == (180.0, 200, 2)
    assert pauses == []  # the hour lies between two processes' files, not inside one
    out = subprocess.run([sys.executable, str(TOOLS / "recipe_time.py"), str(tmp_path / "w")],
                         check=True, capture_output=True, text=True).stdout
    assert "cm/cm" in out and "3.0" in out


def test_val_curves_puts_runs_side_by_side(tmp_path):
    """tools/val_curves.py: a row per validated step, the later of two lines for one step
    wins, "-" where a run did not validate; a folder of two stages' logs is an error."""
    a = tmp_path / "a" / "cm"
    b = tmp_path / "b" / "cm"
    for run, lines in ((a, [{"step": 0, "val_loss": 9.0, "val_denoise": 1.0},
                            {"step": 500, "loss": 5.0},  # a training line: not a row
                            {"step": 500, "val_loss": 8.0, "val_denoise": 0.9},
                            {"step": 500, "val_loss": 7.5, "val_denoise": 0.8}]),  # again
                       (b, [{"step": 0, "val_loss": 9.0, "val_denoise": 1.0},
                            {"step": 250, "val_loss": 8.5, "val_denoise": 0.95}])):
        run.mkdir(parents=True)
        (run / "log.jsonl").write_text("\n".join(json.dumps(r) for r in lines) + "\n")
    out = subprocess.run([sys.executable, str(TOOLS / "val_curves.py"), str(tmp_path / "a"),
                          str(b / "log.jsonl"), "--labels", "base", "change", "--parts",
                          "denoise", "--every", "250"],
                         check=True, capture_output=True, text=True).stdout.splitlines()
    rows = {line.split()[0]: line.split()[1:] for line in out[2:]}
    assert rows == {"0": ["9.000/1.000", "9.000/1.000"], "250": ["-", "8.500/0.950"],
                    "500": ["7.500/0.800", "-"]}
    assert "[0] base" in out[0] and "[1] change" in out[0]
    (tmp_path / "a" / "ae").mkdir()
    (tmp_path / "a" / "ae" / "log.jsonl").write_text("")
    bad = subprocess.run([sys.executable, str(TOOLS / "val_curves.py"), str(tmp_path / "a")],
                         capture_output=True, text=True)
    assert bad.returncode != 0 and "expected one log.jsonl" in bad.stderr


def test_self_samples_adds_passing_samples_and_leaves_the_source_alone(tmp_path):
    """tools/self_samples.py: a hard-linked copy whose train split and labels gain the model's
    own samples that pass their motion's read-outs; the source's files keep their bytes."""
    from mlct.data.synth.build import synthesize_dataset

    src = tmp_path / "src"
    synthesize_dataset(src, num=24, seed=0, progress=False)
    before = {name: (src / name).read_bytes() for name in ("train.txt", "labels.jsonl")}
    out = subprocess.run([sys.executable, str(TOOLS / "self_samples.py"), "--data", str(src),
                          "--out", str(tmp_path / "dst"), "--samples", "4"],
                         check=True, capture_output=True, text=True)
    assert "one-action training motions have a passing sample" in out.stdout
    assert {name: (src / name).read_bytes() for name in before} == before
    train = (tmp_path / "dst" / "train.txt").read_text().split()
    added = [n for n in train if n.startswith("s")]
    assert added  # the bundled model passes most one-action motions (9 of 9 here)
    assert train[:len(train) - len(added)] == before["train.txt"].decode().split()
    labels = [json.loads(line) for line in (tmp_path / "dst" / "labels.jsonl").open()]
    assert {r["name"] for r in labels} >= set(added)
    for name in added:  # each added motion has its features, joints and the source's captions
        assert (tmp_path / "dst" / "new_joint_vecs" / f"{name}.npy").is_file()
        original = name[1:].rsplit("_", 1)[0]
        assert ((tmp_path / "dst" / "texts" / f"{name}.txt").read_text()
                == (src / "texts" / f"{original}.txt").read_text())


def test_join_model_parts_gives_the_weights_back(tmp_path):
    """The GPU recipe sends a model in two files; joined, they are the model's tensors."""
    import numpy as np
    import torch
    from safetensors.torch import load_file, save_file

    sys.path.insert(0, str(TOOLS))
    try:
        from join_model_parts import join
    finally:
        sys.path.pop(0)
    tensors = {"denoiser.a": torch.randn(3, 2).half(), "decoder.b": torch.randn(4).half(),
               "norm.mean": torch.zeros(5)}
    parts = tmp_path / "parts"
    parts.mkdir()
    save_file({k: v for k, v in tensors.items() if k.startswith("denoiser.")},
              str(parts / "model_part1.safetensors"), metadata={"sampler": "cm"})
    save_file({k: v for k, v in tensors.items() if not k.startswith("denoiser.")},
              str(parts / "model_part2.safetensors"), metadata={"sampler": "cm"})
    (parts / "config.json").write_text("{}")
    np.save(parts / "Mean.npy", np.zeros(5))
    np.save(parts / "Std.npy", np.ones(5))
    out = join(parts, tmp_path / "model")
    joined = load_file(str(out / "model.safetensors"))
    assert set(joined) == set(tensors)
    assert all(torch.equal(joined[k], v) for k, v in tensors.items())
    assert (out / "Std.npy").is_file()
    (parts / "model_part2.safetensors").unlink()
    with pytest.raises(SystemExit, match="model_part2"):
        join(parts, tmp_path / "again")


def test_join_onto_puts_a_continued_denoiser_into_the_base_model(tmp_path):
    """bench/gpu_stage2_continue.sh sends back the denoiser alone; the rest is the base's."""
    import json

    import numpy as np
    import torch
    from safetensors.torch import load_file, save_file

    sys.path.insert(0, str(TOOLS))
    try:
        from join_model_parts import join_onto
    finally:
        sys.path.pop(0)
    base = tmp_path / "base"
    base.mkdir()
    old = {"denoiser.a": torch.randn(3, 2).half(), "decoder.b": torch.randn(4).half()}
    save_file(old, str(base / "model.safetensors"), metadata={"sampler": "cm"})
    (base / "config.json").write_text(json.dumps(
        {"decoder_from": "armdec", "step": 6000, "config": {"ae": {"n_tokens": 6}, "x": 1}}))
    for name in ("Mean.npy", "Std.npy"):
        np.save(base / name, np.zeros(5))
    (base / "durations.json").write_text("{}")
    run = tmp_path / "run"
    run.mkdir()
    new = {"denoiser.a": torch.randn(3, 2).half()}
    save_file(new, str(run / "denoiser.safetensors"), metadata={"sampler": "cm"})
    (run / "config.json").write_text(json.dumps(
        {"decoder_from": "/tmp/x/bundleAE", "step": 40000,
         "config": {"ae": {"n_tokens": 6, "grown_from": 0}, "x": 2}}))
    out = join_onto(run, base, tmp_path / "model")
    joined = load_file(str(out / "model.safetensors"))
    assert torch.equal(joined["denoiser.a"], new["denoiser.a"])
    assert torch.equal(joined["decoder.b"], old["decoder.b"])
    config = json.loads((out / "config.json").read_text())
    assert config["step"] == 40000 and config["config"]["x"] == 2  # the run's own
    assert config["decoder_from"] == "armdec" and config["config"]["ae"] == {"n_tokens": 6}
    assert (out / "durations.json").is_file() and (out / "Std.npy").is_file()
    with pytest.raises(SystemExit, match="denoiser.safetensors"):
        join_onto(base, base, tmp_path / "again")


@pytest.mark.parametrize("script", ["gpu_stage2_continue.sh", "gpu_stage2_carry.sh"])
def test_gpu_stage2_scripts_parse(script):
    subprocess.run(["bash", "-n", str(TOOLS.parent / "bench" / script)], check=True)


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
    """stage2_on_body (tools/recipe_stage.sh), shared by the recipe and its stage-2-only form:
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
