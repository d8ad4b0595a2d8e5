"""Best-of-N sampling: the latent text-motion critic (nn/critic.py), its file beside a model
(generate/compose/critic.py), `mlct train critic` (train/critic.py) and the pipeline's `candidates`."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import mlct
from mlct.errors import MlctError
from mlct.generate.compose.critic import (DEFAULT_MARGIN, FILE, Critic, check_candidates,
                                          check_margin, pick, read_critic, save_critic)
from mlct.generate.bundle import bundled_model_dir
from mlct.nn.critic import LatentCritic

pytestmark = pytest.mark.usefixtures("one_thread")


def test_scores_are_cosines_and_margin_zero_picks_the_argmax_per_prompt() -> None:
    torch.manual_seed(0)
    net = LatentCritic(latent_size=12, text_dim=8, max_frames=196, hidden=32, width=16)
    z, text = torch.randn(6, 3, 4), torch.randn(2, 8)
    frames = torch.tensor([40, 80, 120, 40, 80, 120])
    rows = text.repeat_interleave(3, dim=0)
    scores = net.score(z, frames, rows)
    assert scores.shape == (6,) and bool((scores.abs() <= 1 + 1e-6).all())
    best = Critic(net, {"candidates": 3, "margin": 0}).best(z, frames[::3], text, candidates=3)
    assert best.tolist() == scores.view(2, 3).argmax(1).tolist()
    # with a margin: the first candidate within it of the best, on tensors as on arrays
    within = Critic(net, {"candidates": 3, "margin": 2}).best(z, frames[::3], text, candidates=3)
    assert isinstance(within, torch.Tensor) and within.tolist() == [0, 0]
    # a latent's score depends on its length too (the horizon fraction is an input)
    assert not torch.allclose(net.score(z[:1], torch.tensor([20]), text[:1]),
                              net.score(z[:1], torch.tensor([190]), text[:1]))


def test_pick_is_the_first_candidate_within_the_margin_of_the_best() -> None:
    scores = np.array([[0.50, 0.58, 0.60, 0.20],   # 0.50 is 0.10 short: not within 0.05
                       [0.61, 0.70, 0.64, 0.10],   # 0.64 is within, but 0.70 comes first
                       [0.40, 0.30, 0.44, 0.10],   # the seed's own sample is within
                       [0.30, 0.30, 0.10, 0.30]])  # ties: the first
    assert pick(scores, 0.05).tolist() == [1, 1, 0, 0]
    assert pick(scores, 0.0).tolist() == [2, 1, 2, 0]
    assert pick(scores, 2.0).tolist() == [0, 0, 0, 0]  # any margin past the range: the seed's


def test_the_file_round_trips_in_float16_and_refuses_what_does_not_fit(tmp_path: Path) -> None:
    net = LatentCritic(192, 384, 196, hidden=64, width=32)
    path = save_critic(tmp_path, net, {"steps": 1}, "minilm+sides", candidates=4, margin=0.02)
    assert path.name == FILE
    critic = read_critic(tmp_path, "minilm+sides", 384, 192)
    assert critic is not None and critic.candidates == 4 and critic.info["training"] == {"steps": 1}
    assert critic.margin == 0.02
    for name, value in critic.network.state_dict().items():
        torch.testing.assert_close(value, net.state_dict()[name].half().float())
    assert read_critic(tmp_path / "none", "minilm+sides", 384, 192) is None
    with pytest.raises(MlctError, match="text encoder 'minilm\\+sides'"):
        read_critic(tmp_path, "minilm", 384, 192)
    with pytest.raises(MlctError, match="192-number latent"):
        read_critic(tmp_path, "minilm+sides", 384, 768)
    (tmp_path / FILE).write_bytes(b"not safetensors")
    with pytest.raises(MlctError, match="not a critic"):
        read_critic(tmp_path, "minilm+sides", 384, 192)


@pytest.mark.parametrize("value", [-0.1, 2.5, "0.05", True, None])
def test_bad_margins_are_named(value: object) -> None:
    with pytest.raises(MlctError, match="margin must be a number in 0..2"):
        check_margin(value)
    with pytest.raises(MlctError, match="margin must be a number in 0..2"):
        Critic(None, {"margin": value})


@pytest.mark.parametrize("value", [0, -1, 65, 2.5, "8", True, None])
def test_bad_candidate_counts_are_named(value: object) -> None:
    with pytest.raises(MlctError, match="candidates must be a whole number in 1..64"):
        check_candidates(value)


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the bundled model with a critic trained for a few steps on a tiny benchmark."""
    from mlct.data.synth.build import synthesize_dataset
    from mlct.train.critic import train_critic

    root = tmp_path_factory.mktemp("critic")
    synthesize_dataset(root / "synth", num=16, seed=0, progress=False)
    model = root / "model"
    shutil.copytree(bundled_model_dir(), model)
    (model / FILE).unlink(missing_ok=True)
    (model / "onnx").exists() and shutil.rmtree(model / "onnx")
    summary = train_critic(root / "synth", model, steps=20, batch_size=16, candidates=4,
                           log=lambda _: None)
    assert summary["steps"] == 20 and summary["motions"] > 0
    assert 0 <= summary["train"]["label_top1"] <= 1
    return model


def test_training_writes_a_critic_the_model_loads(trained: Path) -> None:
    gen = mlct.load(trained, backend="torch")
    assert gen.critic is not None and gen.candidates == 4 and gen.critic.margin == DEFAULT_MARGIN
    info = json.loads((trained / "config.json").read_text())
    assert gen.critic.info["text_encoder"] == info["text_encoder"]


def test_best_of_n_keeps_the_critics_choice_and_replays(trained: Path) -> None:
    gen = mlct.load(trained, backend="torch")
    gen.foot_lock = None  # the features as decoded, to compare with decode() below
    text, frames = "a person jumps twice", 60
    picked = gen.generate(text, lengths=frames, seed=5, candidates=4)[0]
    again = gen.generate(text, lengths=frames, seed=5, candidates=4)[0]
    np.testing.assert_array_equal(picked.joints, again.joints)
    plain = gen.generate(text, lengths=frames, seed=5, candidates=1)[0]
    # candidate 0 is the plain sample of the seed; the pick is the first of the 4 within the
    # critic's margin of the best
    cond = gen.encode_text([text]).repeat(4, 1)
    from mlct.generate.seeds import SEED_STRIDE, MAX_SEED
    seeds = [(5 + k * SEED_STRIDE) % (MAX_SEED + 1) for k in range(4)]
    z = gen.sample_latents(cond, None, seeds)
    scores = gen.critic.network.score(z / gen.config.schedule.latent_scale,
                                      torch.full((4,), frames), cond)
    made = gen.decode(z, [frames] * 4)
    np.testing.assert_allclose(made[0], plain.features, atol=1e-4)
    chosen = int(pick(scores.detach().numpy()[None], gen.critic.margin)[0])
    np.testing.assert_allclose(made[chosen], picked.features, atol=1e-4)
    # margin 0 is the best of the 4
    gen.critic.margin = 0.0
    best = gen.generate(text, lengths=frames, seed=5, candidates=4)[0]
    np.testing.assert_allclose(made[int(scores.argmax())], best.features, atol=1e-4)


def test_candidates_need_a_critic(trained: Path, tmp_path: Path) -> None:
    bare = tmp_path / "bare"
    shutil.copytree(trained, bare)
    (bare / FILE).unlink()
    gen = mlct.load(bare, backend="torch")
    assert gen.critic is None and gen.candidates == 1
    with pytest.raises(MlctError, match="no critic"):
        gen.generate("a person walks", seconds=2, candidates=4)
    assert len(gen.generate("a person walks", seconds=2, candidates=1)) == 1


def test_cli_generate_candidates(trained: Path, tmp_path: Path) -> None:
    base = [sys.executable, "-m", "mlct.cli", "generate", "a person bows", "--model", str(trained),
            "--seconds", "2", "--seed", "1", "--backend", "torch"]

    def run(option: str, value: str, out: str) -> subprocess.CompletedProcess:
        return subprocess.run(base + [option, value, "--out", str(tmp_path / out)],
                              capture_output=True, text=True)

    for option, good, bad, message in (("--candidates", "1", "0", "candidates must be"),
                                       ("--critic-margin", "0", "-1",
                                        "margin must be a number in 0..2")):
        done = run(option, good, f"{option}-good.npy")
        assert done.returncode == 0, done.stderr
        refused = run(option, bad, f"{option}-bad.npy")
        assert refused.returncode == 2 and message in refused.stderr
        assert "Traceback" not in refused.stderr
        assert not (tmp_path / f"{option}-bad.npy").exists()


def test_a_bundles_meta_stays_json_and_points_at_its_own_folder(trained: Path,
                                                                 tmp_path: Path) -> None:
    """Tools write config.json from a read bundle's meta (bench/inference_speed.py does): it
    must serialize, and a copy must not borrow the critic of the folder it came from."""
    from mlct.generate.bundle import read_bundle

    meta, _ = read_bundle(trained)
    assert meta["model_dir"] == str(trained)
    copy = tmp_path / "copy"
    shutil.copytree(trained, copy)
    (copy / FILE).unlink()
    (copy / "config.json").write_text(json.dumps(meta))  # model_dir names the original
    gen = mlct.load(copy, backend="torch")
    assert gen.critic is None and gen.meta["model_dir"] == str(copy)


def test_the_ranking_term_orders_passing_candidates_first() -> None:
    """ranking_loss falls when a passing candidate scores above a failing one, and training on
    it makes the critic's best candidate a passing one."""
    from mlct.nn.critic import LatentCritic
    from mlct.train.critic_samples import SampledFoils, ranking_accuracy, ranking_loss

    torch.manual_seed(0)
    critic = LatentCritic(6, 5, 40)
    rows, k = 12, 4
    latents = torch.randn(rows, k, 2, 3)
    passed = torch.zeros(rows, k, dtype=torch.bool)
    passed[:, 0] = True  # candidate 0 passes, the rest fail
    latents[:, 0] += 2.0  # and lies apart, so that it can be told from them
    foils = SampledFoils(torch.randn(rows, 5), latents, torch.full((rows,), 30), passed, {})
    everything = torch.arange(rows)
    with torch.no_grad():
        before = float(ranking_loss(critic, foils, everything))
    optimizer = torch.optim.Adam(critic.parameters(), lr=1e-2)
    for _ in range(100):
        loss = ranking_loss(critic, foils, everything)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    with torch.no_grad():
        assert float(ranking_loss(critic, foils, everything)) < before / 4
    assert ranking_accuracy(critic, foils) == 1.0


def test_training_with_samples_ranks_the_models_own_candidates(tmp_path: Path) -> None:
    """`--samples K` samples the model for the one-action training motions, judges each
    candidate with the read-outs (here a stand-in that passes every other candidate, so that
    every motion has some to rank) and records how often its best one passes."""
    import itertools

    from mlct.data.synth.build import synthesize_dataset
    from mlct.train.critic import train_critic

    verdicts = itertools.cycle([[("check", True)], [("check", False)]])
    judged = []

    def alternate(joints, label):
        judged.append((joints.shape, label["actions"][0]["family"]))
        return next(verdicts)

    synthesize_dataset(tmp_path / "synth", num=40, seed=0, progress=False)
    model = tmp_path / "model"
    shutil.copytree(bundled_model_dir(), model)
    (model / FILE).unlink(missing_ok=True)
    summary = train_critic(tmp_path / "synth", model, steps=10, batch_size=16, candidates=4,
                           samples=4, judge=alternate, eval_split=None, log=lambda _: None)
    info = summary["samples"]
    assert info["samples"] == 4 and info["mixed"] == info["motions_sampled"] > 0
    assert len(judged) == 4 * info["motions_sampled"]  # every candidate judged, as joints
    assert all(len(shape) == 3 and shape[1:] == (22, 3) for shape, _ in judged)
    assert info["train_random_passes"] == 0.5 and 0 <= info["train_best_passes"] <= 1
    assert mlct.load(model, backend="torch").critic is not None


def test_samples_needs_candidates_to_rank(tmp_path: Path) -> None:
    from mlct.train.critic_samples import sample_foils

    with pytest.raises(MlctError, match="--samples must be >= 2"):
        sample_foils(bundled_model_dir(), None, [], {}, 1, 0, 196,  # type: ignore[arg-type]
                     lambda joints, label: [])


def test_samples_without_labels_say_what_is_missing(tmp_path: Path) -> None:
    """Imported data has captions but no benchmark labels: --samples names what it needs."""
    from mlct.data.synth.build import synthesize_dataset
    from mlct.train.critic import train_critic

    synthesize_dataset(tmp_path / "synth", num=16, seed=0, progress=False)
    (tmp_path / "synth" / "labels.jsonl").unlink()
    model = tmp_path / "model"
    shutil.copytree(bundled_model_dir(), model)
    (model / FILE).unlink(missing_ok=True)
    with pytest.raises(MlctError, match="no one-action motions with a benchmark label"):
        train_critic(tmp_path / "synth", model, steps=5, batch_size=8, samples=4,
                     judge=lambda joints, label: [], eval_split=None, log=lambda _: None)
    assert not (model / FILE).exists()  # nothing half-written
