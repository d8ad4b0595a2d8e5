"""The training engine end to end on a tiny synthetic set: both stages learn, exact resume,
NaN handling, export/load/generate, two-process DDP on gloo."""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

import numpy as np
import pytest
import torch

import mlct
from mlct.config import load_config
from mlct.data.synth.build import synthesize_dataset
from mlct.errors import MlctError
from mlct.train.checkpoint import latest_checkpoint, load_checkpoint
from mlct.train.loop import train

pytestmark = pytest.mark.slow  # trains every stage, DDP and torchrun: about a minute


def _log(run: Path, stage: str) -> list[dict]:
    return [json.loads(line) for line in (run / stage / "log.jsonl").read_text().splitlines()]


def _val(records: list[dict]) -> list[tuple[int, float]]:
    return [(r["step"], r["val_loss"]) for r in records if "val_loss" in r]


def _train_losses(records: list[dict]) -> dict[int, float]:
    return {r["step"]: r["loss"] for r in records if "loss" in r}


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("synth") / "data"
    synthesize_dataset(root, num=48, seed=3, progress=False)
    return root


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> str:
    return f"text.cache_dir={tmp_path_factory.mktemp('cache')}"


@pytest.fixture(scope="module")
def tiny():
    return load_config("tiny")


@pytest.fixture(scope="module")
def trained(data: Path, cache: str, tiny, tmp_path_factory) -> Path:
    """A run with all three stages trained on the tiny preset (shared by several tests)."""
    run = tmp_path_factory.mktemp("run")
    steps = ["train.ae.max_steps=60", "train.ae.val_every=30", "train.ae.lr=2e-3"]
    train("ae", data, run, tiny, overrides=[cache, *steps], progress=False)
    for stage in ("cm", "diffusion"):
        train(stage, data, run, tiny, overrides=[cache], progress=False)
    return run


def test_every_stage_learns(trained: Path) -> None:
    for stage in ("ae", "cm", "diffusion"):
        val = _val(_log(trained, stage))
        assert val[0][0] == 0, "validation runs before the first step"
        first, last = val[0][1], val[-1][1]
        assert np.isfinite(last)
        assert last < 0.95 * first, f"{stage}: validation loss {first:.4f} -> {last:.4f}"


def test_checkpoint_is_self_describing(trained: Path) -> None:
    ckpt = load_checkpoint(latest_checkpoint(trained / "cm" / "checkpoints"))
    assert ckpt.meta["stage"] == "cm" and ckpt.meta["step"] == 30
    assert ckpt.meta["config"]["preset"] == "tiny"
    assert ckpt.meta["text_encoder"] == "minilm" and ckpt.meta["text_dim"] == 384
    assert any(k.startswith("target.module.net.") for k in ckpt.tensors)  # the EMA target
    assert set(ckpt.state) == {"optimizer", "scheduler", "rng"}
    assert (trained / "cm" / "config.yaml").is_file()
    assert any((trained / "cm" / "tb").iterdir())  # TensorBoard events


def test_export_load_generate(trained: Path, tmp_path: Path) -> None:
    from mlct.train.export import export_run

    model_dir = export_run(trained, tmp_path / "model")
    gen = mlct.load(model_dir)
    assert gen.sampler.name == "consistency"
    texts = ["a person walks forward", "someone jumps", "a person waves"]
    out = gen.generate(texts, lengths=[7, 40, 64], nfe=3, seed=5)
    assert [m.features.shape for m in out] == [(7, 263), (40, 263), (64, 263)]
    assert [m.joints.shape for m in out] == [(7, 22, 3), (40, 22, 3), (64, 22, 3)]
    assert all(np.isfinite(m.joints).all() for m in out)
    again = gen.generate(texts, lengths=[7, 40, 64], nfe=3, seed=5)
    other = gen.generate(texts, lengths=[7, 40, 64], nfe=3, seed=6)
    assert all(np.array_equal(a.features, b.features) for a, b in zip(out, again))
    # item i has seed 5 + i whatever else is in the batch (the server batches requests)
    alone = gen.generate(texts[1], lengths=40, nfe=3, seed=6)[0]
    assert alone.seed == out[1].seed == 6
    assert np.allclose(alone.features, out[1].features, atol=1e-4)  # batch size: rounding only
    assert out.joints.shape == (3, 64, 22, 3) and out.lengths.tolist() == [7, 40, 64]
    assert np.array_equal(out.joints[0, 7:], np.broadcast_to(out[0].joints[-1], (57, 22, 3)))
    assert out.texts == texts and out.features.shape == (3, 64, 263)
    assert not np.allclose(out[1].features, other[1].features)
    # the bundle holds no optimizer state; the AE encoder only under ae_encoder.
    from safetensors.torch import load_file

    keys = load_file(str(model_dir / "model.safetensors")).keys()
    assert not any(k.startswith("decoder.encoder.") for k in keys)
    assert (model_dir / "Mean.npy").is_file() and (model_dir / "Std.npy").is_file()


def test_export_with_onnx_graphs(trained: Path, tmp_path: Path) -> None:
    """`mlct export RUN --out DIR --onnx`: the bundle with its graphs; the backends agree."""
    pytest.importorskip("onnxruntime")
    pytest.importorskip("onnx")
    from mlct.cli import main

    assert main(["export", str(trained), "--out", str(tmp_path / "model"), "--onnx"]) == 0
    texts, lengths = ["a person walks forward", "someone jumps"], [64, 23]
    made = [mlct.load(tmp_path / "model", backend=backend).generate(texts, lengths=lengths,
                                                                     nfe=2, seed=3)
            for backend in ("torch", "onnx")]
    for a, b in zip(*made):
        assert np.abs(a.joints - b.joints).max() < 1e-3


def test_diffusion_baseline_samples_with_ddim_cfg(trained: Path, tmp_path: Path) -> None:
    from mlct.train.export import export_run

    gen = mlct.load(export_run(trained, tmp_path / "ldm", stage="diffusion"))
    assert gen.sampler.name == "ddim" and gen.default_nfe == 50
    calls = []
    forward = gen.denoiser.forward

    def counting(x, t, c, cache=None):
        calls.append(x.shape[0])
        return forward(x, t, c, cache=cache)

    gen.denoiser.forward = counting
    out = gen.generate(["a person walks forward"], lengths=40, nfe=10, seed=0)
    assert np.isfinite(out[0].joints).all()
    assert calls == [2] * 10  # ten steps, each one batch of cond + uncond (CFG)


def test_exact_resume(data: Path, cache: str, tiny, tmp_path: Path) -> None:
    common = [cache, "train.ae.max_steps=12", "train.ae.ckpt_every=4", "train.ae.log_every=1",
              "train.ae.val_every=6"]
    whole = train("ae", data, tmp_path / "whole", tiny, overrides=common, progress=False)
    train("ae", data, tmp_path / "split", tiny, overrides=common, progress=False, stop_at=5)
    resumed = train("ae", data, tmp_path / "split", resume=True, progress=False)
    assert resumed["step"] == whole["step"] == 12
    a, b = _log(tmp_path / "whole", "ae"), _log(tmp_path / "split", "ae")
    assert _train_losses(a) == _train_losses(b)  # every step's loss, bit for bit
    assert _val(a) == _val(b)
    assert resumed["weights_digest"] == whole["weights_digest"]


def test_nan_loss_stops_and_keeps_last_checkpoint(data: Path, cache: str, tiny, tmp_path: Path,
                                                  monkeypatch) -> None:
    from mlct.train.stages import AutoencoderStage

    real = AutoencoderStage.loss
    count = {"n": 0}

    def poisoned(self, model, batch, generator=None):
        out = real(self, model, batch, generator)
        if generator is None:  # training batches only
            count["n"] += 1
            if count["n"] == 7:
                out["loss"] = out["loss"] * float("nan")
        return out

    monkeypatch.setattr(AutoencoderStage, "loss", poisoned)
    with pytest.raises(MlctError, match=r"loss is nan at step 7.*step-00000004"):
        train("ae", data, tmp_path, tiny, progress=False,
              overrides=[cache, "train.ae.ckpt_every=4", "train.ae.max_steps=20"])
    ckpt = load_checkpoint(latest_checkpoint(tmp_path / "ae" / "checkpoints"))
    assert ckpt.meta["step"] == 4
    assert all(torch.isfinite(t).all() for t in ckpt.tensors.values() if t.is_floating_point())


def test_bad_inputs(data: Path, cache: str, tiny, trained: Path, tmp_path: Path) -> None:
    with pytest.raises(MlctError, match="already holds a run"):
        train("ae", data, trained, tiny, overrides=[cache], progress=False)
    with pytest.raises(MlctError, match="no checkpoint to resume"):
        train("ae", data, tmp_path / "fresh", resume=True, progress=False)
    with pytest.raises(MlctError, match="no trained autoencoder"):
        train("cm", data, tmp_path / "noae", tiny, overrides=[cache], progress=False)
    with pytest.raises(MlctError, match="only train.ae"):
        train("ae", data, trained, resume=True, overrides=["ae.layers=5"], progress=False)
    # KIT-width data against a HumanML3D autoencoder
    kit = tmp_path / "kit"
    synthesize_dataset(kit, num=30, seed=0, skeleton="kit", progress=False)
    with pytest.raises(MlctError, match="reads 263-d motion, the data has 251-d"):
        train("cm", kit, tmp_path / "kitrun", tiny, overrides=[cache], progress=False,
              ae_path=latest_checkpoint(trained / "ae" / "checkpoints"))
    # a foreign and a corrupted checkpoint
    from safetensors.torch import save_file

    foreign = tmp_path / "foreign.safetensors"
    save_file({"w": torch.zeros(2)}, str(foreign))
    with pytest.raises(MlctError, match="not an mlct checkpoint"):
        load_checkpoint(foreign, with_state=False)
    broken = tmp_path / "broken.safetensors"
    broken.write_bytes(b"\x00" * 64)
    with pytest.raises(MlctError, match="not a readable safetensors file"):
        load_checkpoint(broken, with_state=False)


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _ddp_worker(rank: int, world: int, port: int, data: str, out: str, overrides: list[str],
                results: str) -> None:
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), RANK=str(rank),
                      WORLD_SIZE=str(world), LOCAL_RANK=str(rank))
    torch.set_num_threads(1)
    summary = train("ae", data, out, load_config("tiny"), overrides=overrides, device="cpu",
                    progress=False)
    Path(results, f"rank{rank}.json").write_text(json.dumps(summary))


def test_ddp_two_processes_gloo(data: Path, cache: str, tmp_path: Path) -> None:
    overrides = [cache, "train.ae.max_steps=6", "train.ae.batch_size=8"]
    torch.multiprocessing.spawn(_ddp_worker, args=(2, _free_port(), str(data),
                                                   str(tmp_path / "run"), overrides,
                                                   str(tmp_path)), nprocs=2, join=True)
    ranks = [json.loads((tmp_path / f"rank{r}.json").read_text()) for r in (0, 1)]
    assert ranks[0]["step"] == ranks[1]["step"] == 6
    assert ranks[0]["weights_digest"] == ranks[1]["weights_digest"]  # identical weights
    ckpt = load_checkpoint(latest_checkpoint(tmp_path / "run" / "ae" / "checkpoints"))
    assert len(ckpt.state["rng"]) == 2  # every rank's RNG state, for exact resumption


def test_cli_export_generate_and_errors(trained: Path, data: Path, tmp_path: Path,
                                        capsys) -> None:
    from mlct.cli import main

    model = tmp_path / "model"
    assert main(["export", str(trained), "--out", str(model)]) == 0
    out = tmp_path / "walk.npy"
    assert main(["generate", "a person walks forward", "--model", str(model), "--seconds", "2",
                 "--nfe", "2", "--seed", "0", "--out", str(out)]) == 0
    joints = np.load(out)
    assert joints.shape == (40, 22, 3) and np.isfinite(joints).all()  # 2 s at 20 fps
    assert main(["generate", "a person walks forward", "--model", str(model), "--seconds", "2",
                 "--nfe", "2", "--seed", "0", "--features", "--out", str(out)]) == 0
    assert np.load(out).shape == (40, 263)
    gif = tmp_path / "walk.gif"
    assert main(["generate", "a person walks forward", "--model", str(model), "--length", "24",
                 "--out", str(gif)]) == 0
    assert gif.stat().st_size > 1000
    capsys.readouterr()
    bad = [
        (["generate", "walk", "--model", str(model), "--nfe", "0", "--out", str(out)], "nfe"),
        (["generate", "walk", "--model", str(model), "--seconds", "60", "--out", str(out)],
         "outside 1..64"),
        (["generate", "walk", "--model", str(model), "--out", str(tmp_path / "x.txt")],
         "must end in .gif"),
        (["generate", "  ", "--model", str(model), "--out", str(out)], "prompt is empty"),
        (["generate", "walk", "--model", str(tmp_path / "none"), "--out", str(out)],
         "no such model directory"),
        (["train", "ae", "--data", str(data), "--out", str(tmp_path / "r"), "--config", "tiny",
          "ae.nope=1"], "unknown config key 'ae.nope'"),
        (["train", "ae", "--data", str(tmp_path / "nodata"), "--out", str(tmp_path / "r2"),
          "--config", "tiny"], "no such directory"),
        (["export", str(tmp_path / "norun"), "--out", str(tmp_path / "m2")], "no checkpoint"),
    ]
    for argv, message in bad:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1, err
    assert np.load(out).shape == (40, 263)  # the failed calls left the earlier output intact


def test_torchrun_runs_the_same_command(data: Path, cache: str, tmp_path: Path) -> None:
    """`torchrun --nproc_per_node 2 -m mlct.cli train ...`: the CLI command, under DDP (gloo)."""
    import subprocess
    import sys

    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2",
         "--master_port", str(_free_port()), "-m", "mlct.cli", "train", "ae", "--data",
         str(data), "--out", str(tmp_path / "run"), "--config", "tiny", "--device", "cpu",
         "--quiet", cache, "train.ae.max_steps=4", "train.ae.batch_size=4"],
        capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.count("ae: step 4") == 1  # only rank 0 reports
    ckpt = load_checkpoint(latest_checkpoint(tmp_path / "run" / "ae" / "checkpoints"))
    assert ckpt.meta["step"] == 4 and len(ckpt.state["rng"]) == 2


def test_ae_path_may_name_a_run_a_stage_or_a_checkpoint(trained: Path) -> None:
    from mlct.train.stages import find_autoencoder

    latest = latest_checkpoint(trained / "ae" / "checkpoints")
    for given in (trained, trained / "ae", latest):
        assert find_autoencoder(Path("/elsewhere"), given) == latest
    assert find_autoencoder(trained, None) == latest


def test_init_starts_from_a_model_for_fine_tuning(trained: Path, data: Path, cache: str,
                                                   tmp_path: Path) -> None:
    """--init MODEL_DIR: the model's config, normalization and weights are where a run starts."""
    from safetensors.torch import load_file, save_file

    from mlct.generate.bundle import read_bundle
    from mlct.train.export import export_run

    model_dir = export_run(trained, tmp_path / "model")
    _, tensors = read_bundle(model_dir)
    assert any(k.startswith("ae_encoder.") for k in tensors)  # shipped for fine-tuning
    run = tmp_path / "fine"
    still = ["train.{}.max_steps=1", "train.{}.lr=1e-12", "train.{}.lr_min=0"]  # one no-op step
    train("ae", data, run, None, overrides=[cache, *(s.format("ae") for s in still)],
          progress=False, init=model_dir)
    ckpt = load_checkpoint(latest_checkpoint(run / "ae" / "checkpoints"), with_state=False)
    ae = ckpt.module_state("ae")
    for key, value in tensors.items():
        for prefix in ("decoder.", "ae_encoder."):
            if key.startswith(prefix):
                torch.testing.assert_close(ae[key[len(prefix):]], value, rtol=0, atol=1e-6)
    assert set(ae) == {k.split(".", 1)[1] for k in tensors if k.startswith(("decoder.", "ae_"))}
    assert torch.equal(ckpt.tensors["norm.mean"], tensors["norm.mean"])
    assert ckpt.meta["config"]["ae"] == load_checkpoint(
        latest_checkpoint(trained / "ae" / "checkpoints"), with_state=False).meta["config"]["ae"]

    train("cm", data, run, None, overrides=[cache, *(s.format("cm") for s in still)],
          progress=False, init=model_dir)
    ckpt = load_checkpoint(latest_checkpoint(run / "cm" / "checkpoints"), with_state=False)
    denoiser = ckpt.module_state("denoiser")
    for key, value in tensors.items():
        if key.startswith("denoiser."):
            torch.testing.assert_close(denoiser[key[len("denoiser."):]], value, rtol=0, atol=1e-6)

    with pytest.raises(MlctError, match="consistency model cannot start `train diffusion`"):
        train("diffusion", data, run, None, overrides=[cache], progress=False, init=model_dir)
    with pytest.raises(MlctError, match="--init starts a new run"):
        train("cm", data, run, None, resume=True, progress=False, init=model_dir)
    old = tmp_path / "old"  # a model exported before the encoder was shipped
    old.mkdir()
    (old / "config.json").write_text((model_dir / "config.json").read_text())
    weights = load_file(str(model_dir / "model.safetensors"))
    save_file({k: v for k, v in weights.items() if not k.startswith("ae_encoder.")},
              str(old / "model.safetensors"))
    with pytest.raises(MlctError, match="ships no autoencoder encoder"):
        train("ae", data, tmp_path / "again", None, overrides=[cache], progress=False, init=old)


def test_init_from_an_autoencoder_run_continues_it_with_other_options(
        trained: Path, data: Path, cache: str, tmp_path: Path) -> None:
    """train ae --init RUN: a second AE stage (here with latent noise) starts from the first's
    latest weights, config and normalization; stage 2 does not have to exist yet."""
    first = load_checkpoint(latest_checkpoint(trained / "ae" / "checkpoints"), with_state=False)
    run = tmp_path / "noisy"
    still = ["train.ae.max_steps=1", "train.ae.lr=1e-12", "train.ae.lr_min=0"]
    train("ae", data, run, None, overrides=[cache, "ae.latent_noise=0.1", *still],
          progress=False, init=trained / "ae")
    ckpt = load_checkpoint(latest_checkpoint(run / "ae" / "checkpoints"), with_state=False)
    for key, value in first.module_state("ae").items():
        torch.testing.assert_close(ckpt.module_state("ae")[key], value, rtol=0, atol=1e-6)
    assert torch.equal(ckpt.tensors["norm.mean"], first.tensors["norm.mean"])
    assert ckpt.meta["config"]["ae"]["latent_noise"] == 0.1
    assert ckpt.meta["config"]["preset"] == first.meta["config"]["preset"]
    with pytest.raises(MlctError, match="not an autoencoder run"):
        train("ae", data, tmp_path / "bad", None, overrides=[cache], progress=False,
              init=latest_checkpoint(trained / "cm" / "checkpoints"))
    with pytest.raises(MlctError, match="not with ae.temporal or ae.bottleneck"):
        train("ae", data, tmp_path / "grow", None, progress=False, init=trained / "ae",
              overrides=[cache, "ae.architecture=conv", "ae.temporal=true",
                         f"ae.n_tokens={first.meta['config']['ae']['n_tokens'] + 1}"])


def test_resume_survives_a_killed_write_and_a_broken_latest(data: Path, cache: str, tiny,
                                                            tmp_path: Path, capsys) -> None:
    """Partial folders are removed on the next start; a broken `latest` falls back to
    the newest intact checkpoint, saying so; `latest` is never joined to a path unchecked."""
    run = tmp_path / "run"
    common = [cache, "train.ae.max_steps=12", "train.ae.ckpt_every=4", "train.ae.val_every=6"]
    train("ae", data, run, tiny, overrides=common, progress=False, stop_at=8)
    checkpoints = run / "ae" / "checkpoints"
    leftover = checkpoints / ".step-00000012.partial-abc123"  # a kill during a write
    leftover.mkdir()
    (leftover / "model.safetensors").write_bytes(b"half")
    (checkpoints / "step-00000008" / "model.safetensors").write_bytes(b"\x00" * 64)  # corrupt
    capsys.readouterr()
    resumed = train("ae", data, run, resume=True, progress=False)
    assert "resuming from step-00000004" in capsys.readouterr().err
    assert resumed["step"] == 12 and not leftover.exists()
    (checkpoints / "latest").write_text("../../../etc\n")
    with pytest.raises(MlctError, match="not a checkpoint name.*newest intact checkpoint is"):
        latest_checkpoint(checkpoints)


def test_latent_scale_is_undone_before_decoding(trained: Path, tmp_path: Path) -> None:
    """schedule.latent_scale: stage 2 samples in a scaled latent space; decode divides by it
    (and the clamp of the quantized latent grows with it)."""
    from mlct.config import config_from_dict
    from mlct.nn.build import latent_clamp
    from mlct.train.export import export_run

    gen = mlct.load(export_run(trained, tmp_path / "model"))
    z = torch.rand(2, *gen.ae.latent_shape) * 2 - 1
    plain = gen.decode(z, [20, 30])
    settings = gen.config.to_dict()
    settings["schedule"]["latent_scale"] = 2.5
    scaled = config_from_dict(settings)
    gen.networks.config = scaled  # what the backend decodes with
    again = gen.decode(2.5 * z, [20, 30])
    assert all(np.allclose(a, b, atol=1e-5) for a, b in zip(plain, again))
    assert latent_clamp(scaled) == 2.5


def test_a_decoder_trained_with_the_encoder_frozen_swaps_into_the_model(
        trained: Path, data: Path, cache: str, tmp_path: Path) -> None:
    """ae.freeze_encoder + ae.hold_extension: only the decoder learns (the denoiser's latents
    stay valid), decoding past a clip's end towards its held last pose; `mlct export
    --decoder-from` puts that decoder beside the run's denoiser, and refuses another encoder."""
    from mlct.generate.bundle import read_bundle
    from mlct.train.export import export_run

    model_dir = export_run(trained, tmp_path / "model")
    run = tmp_path / "hold"
    train("ae", data, run, None, progress=False, init=model_dir,
          overrides=[cache, "ae.freeze_encoder=true", "ae.hold_extension=1.0",
                     "train.ae.max_steps=3", "train.ae.lr=1e-2"])
    _, before = read_bundle(model_dir)
    ae = load_checkpoint(latest_checkpoint(run / "ae" / "checkpoints"),
                         with_state=False).module_state("ae")
    encoder = {k[len("ae_encoder."):]: v for k, v in before.items() if k.startswith("ae_encoder.")}
    decoder = {k[len("decoder."):]: v for k, v in before.items() if k.startswith("decoder.")}
    assert all(torch.equal(ae[k], v) for k, v in encoder.items())
    assert any(not torch.allclose(ae[k], v) for k, v in decoder.items())
    swapped = export_run(trained, tmp_path / "swapped", decoder_from=run)
    _, after = read_bundle(swapped)
    for key, value in ae.items():
        name = ("ae_encoder." if f"ae_encoder.{key}" in after else "decoder.") + key
        torch.testing.assert_close(after[name], value)
    assert all(torch.equal(after[k], before[k]) for k in before if k.startswith("denoiser."))
    other = tmp_path / "other"  # an autoencoder whose encoder moved
    train("ae", data, other, None, progress=False, init=model_dir,
          overrides=[cache, "train.ae.max_steps=2", "train.ae.lr=1e-2"])
    with pytest.raises(MlctError, match="its encoder is not the run's"):
        export_run(trained, tmp_path / "refused", decoder_from=other)
    assert not (tmp_path / "refused").exists()


def test_holding_the_last_pose_zeroes_the_velocities(tiny) -> None:
    from mlct.motion.skeleton import FeatureLayout
    from mlct.train.stages import AutoencoderStage

    mean, std = torch.randn(263), torch.rand(263) + 0.5
    stage = AutoencoderStage(tiny, torch.device("cpu"), mean, std, "humanml3d")
    last = torch.randn(2, 263)
    held = stage.norm.denormalize(stage._held_pose(last))
    raw = stage.norm.denormalize(last)
    groups = FeatureLayout(22).groups
    for name in ("root_rot_velocity", "root_linear_velocity", "local_velocity"):
        assert torch.allclose(held[:, groups[name]], torch.zeros(1), atol=1e-5)
    assert torch.allclose(held[:, groups["foot_contact"]], torch.ones(1), atol=1e-5)
    for name in ("root_height", "ric", "rotations"):
        torch.testing.assert_close(held[:, groups[name]], raw[:, groups[name]])


def test_latent_noise_is_decoded_in_training_only(tiny) -> None:
    """ae.latent_noise: the training loss decodes z + noise (the autoencoder's forward adds it),
    validation the clean z."""
    from mlct.config import config_from_dict
    from mlct.nn.conv_autoencoder import ConvMotionAutoencoder
    from mlct.train.stages import AutoencoderStage

    torch.manual_seed(0)
    ae = ConvMotionAutoencoder(263, n_tokens=2, latent_dim=8, channels=16, max_len=40).eval()
    x, lengths = torch.randn(2, 40, 263), torch.tensor([40, 25])
    with torch.no_grad():
        clean, latent = ae(x, lengths)
        torch.manual_seed(5)
        noisy, _ = ae(x, lengths, None, 0.5)
        torch.manual_seed(5)
        expected = ae.decode(latent.z + 0.5 * torch.randn_like(latent.z), lengths, 40)
        torch.testing.assert_close(clean, ae.decode(latent.z, lengths, 40))
        torch.testing.assert_close(noisy, expected)
        assert not torch.equal(noisy, clean)

    config = tiny.to_dict()
    config["ae"]["latent_noise"] = 0.5
    stage = AutoencoderStage(config_from_dict(config), torch.device("cpu"), torch.zeros(263),
                             torch.ones(263), "humanml3d")
    seen = []
    forward = stage.model.forward
    stage.model.forward = lambda *a: seen.append(a[3]) or forward(*a)  # what the loss asks for
    batch = {"motion": torch.randn(2, 40, 263), "length": torch.tensor([40, 30])}
    for training in (True, False):
        stage.model.train(training)
        stage.loss(stage.model, batch)
    assert seen == [0.5, 0.0]


def test_trajectory_term_reads_the_turned_angle(tiny) -> None:
    """ae.trajectory_weight: the integrated heading is the angle the joints' read-out turns, and
    a reconstruction that turns 10 % short costs exactly the smooth-L1 of that shortfall."""
    from mlct.config import config_from_dict
    from mlct.eval.readouts import heading_change
    from mlct.motion.features import features_to_joints
    from mlct.train.stages import AutoencoderStage, _root_trajectory

    frames = 40
    target = torch.zeros(1, frames, 263)
    target[..., 0] = 0.02  # half-angle velocity: 2 x 0.02 x 39 = 1.56 rad by the last frame
    target[..., 2] = 0.03  # walking forward, so the ground path bends with the heading
    target[..., 3] = 0.9
    target[..., 4:67] = torch.randn(63) * 0.2  # a fixed pose relative to the root
    heading = _root_trajectory(target)[0, :, 0]
    assert heading[-1].item() == pytest.approx(
        heading_change(features_to_joints(target[0].numpy())), abs=0.02)

    config = tiny.to_dict()
    config["ae"]["trajectory_weight"] = 1.0
    config["ae"]["hold_extension"] = 0.0
    stage = AutoencoderStage(config_from_dict(config), torch.device("cpu"), torch.zeros(263),
                             torch.ones(263), "humanml3d")
    short = target.clone()
    short[..., 0] *= 0.9
    _, latent = stage.model(target, torch.tensor([frames]))
    stage.model.forward = lambda *a: (short, latent)
    out = stage.loss(stage.model, {"motion": target, "length": torch.tensor([frames])})
    expected = torch.nn.functional.smooth_l1_loss(_root_trajectory(short),
                                                  _root_trajectory(target))
    torch.testing.assert_close(out["trajectory"], expected)
    assert out["trajectory"] > 1e-3


def test_joint_beta_makes_a_missed_hand_cost_its_size(tiny) -> None:
    """ae.joint_beta: the joint term's smooth-L1 beta in metres. With the default 1 a wrist
    15 cm off costs 0.5 x 0.15^2; with 0.02 it costs 0.15 - 0.01, its size."""
    from mlct.config import config_from_dict
    from mlct.motion.features import recover_from_ric
    from mlct.motion.skeleton import FeatureLayout
    from mlct.train.stages import AutoencoderStage

    frames = 20
    target = torch.zeros(1, frames, 263)
    target[..., 3] = 0.9
    moved = target.clone()
    wrist = 20  # left wrist: its root-relative position is ric joint 20 - 1
    ric = FeatureLayout(22).groups["ric"]
    moved[..., ric.start + 3 * (wrist - 1)] += 0.15
    gap = (recover_from_ric(moved) - recover_from_ric(target)).abs()
    assert gap.max().item() == pytest.approx(0.15, abs=1e-5)  # one coordinate of one joint
    costs = {}
    for beta in (1.0, 0.02):
        config = tiny.to_dict()
        config["ae"].update(joint_beta=beta, hold_extension=0.0)
        stage = AutoencoderStage(config_from_dict(config), torch.device("cpu"), torch.zeros(263),
                                 torch.ones(263), "humanml3d")
        _, latent = stage.model(target, torch.tensor([frames]))
        stage.model.forward = lambda *a: (moved, latent)
        costs[beta] = stage.loss(stage.model, {"motion": target, "length": torch.tensor([frames])}
                                 )["joint"].item()
    per_value = 1 / (22 * 3)  # the term averages over the joints' coordinates
    assert costs[1.0] == pytest.approx(0.5 * 0.15**2 * per_value, rel=1e-3)
    assert costs[0.02] == pytest.approx((0.15 - 0.01) * per_value, rel=1e-3)


def test_auto_precision_is_bf16_for_the_autoencoder_on_cuda_only():
    """Stage 2 in bf16 on a GPU diverged (docs/training.md): 'auto' keeps it in fp32."""
    from mlct.train.loop import autocast_precision

    cuda, cpu = torch.device("cuda"), torch.device("cpu")
    assert autocast_precision("auto", "ae", cuda) == "bf16"
    assert autocast_precision("auto", "cm", cuda) == "fp32"
    assert autocast_precision("auto", "diffusion", cuda) == "fp32"
    assert autocast_precision("auto", "ae", cpu) == "fp32"
    assert autocast_precision("bf16", "cm", cuda) == "bf16"  # asked for by name
    assert autocast_precision("bf16", "cm", cpu) == "bf16"
    assert autocast_precision("fp32", "ae", cuda) == "fp32"


def test_a_diverging_norm_is_warned_about_or_stops_the_run(data: Path, cache: str, tiny,
                                                           tmp_path: Path, monkeypatch,
                                                           capsys) -> None:
    """The watch (train/divergence.py) in the loop, made to trip at once: a factor of 1e-9
    times the first logged norm. The warning goes to stderr and log.jsonl and the run goes on;
    with stop_on_divergence it stops there, naming its last checkpoint."""
    import mlct.train.divergence as divergence

    monkeypatch.setattr(divergence, "FACTOR", 1e-9)
    monkeypatch.setattr(divergence, "EARLY_LOGS", 1)
    common = [cache, "train.ae.max_steps=6", "train.ae.log_every=2", "train.ae.ckpt_every=2"]
    train("ae", data, tmp_path / "warn", tiny, progress=False, overrides=common)
    warnings = [r for r in _log(tmp_path / "warn", "ae") if "warning" in r]
    assert [r["step"] for r in warnings] == [4]  # step 2 sets the range; said once
    assert "probably diverging" in capsys.readouterr().err
    assert latest_checkpoint(tmp_path / "warn" / "ae" / "checkpoints").name.endswith("6")
    with pytest.raises(MlctError, match=r"step 4.*stop_on_divergence.*step-00000002"):
        train("ae", data, tmp_path / "stop", tiny, progress=False,
              overrides=[*common, "train.ae.stop_on_divergence=true"])
