"""Growing a trained latent from n to more tokens (nn/grow.py, `ae.grown_from`)."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from mlct.config import load_config
from mlct.data.synth.build import synthesize_dataset
from mlct.errors import MlctError
from mlct.nn.autoencoder import MotionAutoencoder
from mlct.nn.conv_autoencoder import ConvMotionAutoencoder
from mlct.nn.denoiser import Denoiser
from mlct.nn.grow import grow_tokens, old_token_rows
from mlct.train.checkpoint import latest_checkpoint, load_checkpoint
from mlct.train.loop import train

D = 8  # latent_dim of the small networks below


def _conv(n: int, latent_type: str = "quantized") -> ConvMotionAutoencoder:
    torch.manual_seed(n)
    return ConvMotionAutoencoder(263, latent_type, n, D, channels=16, max_len=40).eval()


@pytest.mark.parametrize("latent_type", ["quantized", "vae", "plain"])
def test_a_grown_autoencoder_encodes_and_decodes_as_before(latent_type: str) -> None:
    old, new = _conv(2, latent_type), _conv(4, latent_type)
    new.load_state_dict(grow_tokens(old.state_dict(), new.state_dict(), 2, 4, D))
    x, lengths = torch.randn(3, 40, 263), torch.tensor([40, 25, 9])
    with torch.no_grad():
        z_old, z_new = old.encode(x, lengths).z, new.encode(x, lengths).z
        torch.testing.assert_close(z_new[:, :2], z_old)
        assert z_new[:, 2:].abs().sum() > 0  # the new tokens say something from the start
        anything = torch.cat([z_old, torch.randn(3, 2, D)], dim=1)  # the decoder ignores them
        torch.testing.assert_close(new.decode(anything, lengths), old.decode(z_old, lengths))


def test_a_grown_denoiser_keeps_its_old_positions() -> None:
    small, big = (Denoiser(D, n, 16, width=32, layers=3, heads=2, ff_dim=64) for n in (2, 5))
    grown = grow_tokens(small.state_dict(), big.state_dict(), 2, 5, D)
    torch.testing.assert_close(grown["pos"][:, :3], small.pos.detach())
    torch.testing.assert_close(grown["pos"][:, 3:], big.pos.detach()[:, 3:])
    big.load_state_dict(grown)


def test_growth_refuses_to_shrink_and_the_transformer_autoencoder() -> None:
    with pytest.raises(MlctError, match="grow, not shrink"):
        grow_tokens(_conv(3).state_dict(), _conv(2).state_dict(), 3, 2, D)
    small, big = (MotionAutoencoder(263, "quantized", n, D, layers=1, heads=2, ff_dim=16,
                                    max_len=40) for n in (2, 3))
    with pytest.raises(MlctError, match="cannot grow"):
        grow_tokens(small.state_dict(), big.state_dict(), 2, 3, D)


def test_old_token_rows_mark_the_first_tokens_of_each_group() -> None:
    mask = old_token_rows(2 * 3 * D, 1, 3, D)  # a VAE: mean and log-variance groups
    expected = torch.zeros(2, 3, D, dtype=torch.bool)
    expected[:, 0] = True
    assert torch.equal(mask, expected.view(-1))


@pytest.fixture(scope="module")
def conv_model(tmp_path_factory) -> tuple[Path, Path, str]:
    """A tiny conv-autoencoder model (2 latent tokens), exported, and its data."""
    from mlct.train.export import export_run

    root = tmp_path_factory.mktemp("grow")
    data = root / "data"
    synthesize_dataset(data, num=32, seed=5, progress=False)
    cache = f"text.cache_dir={root / 'cache'}"
    conv = ["ae.architecture=conv", "ae.channels=16", "ae.latent_dim=8"]
    train("ae", data, root / "run", load_config("tiny"), progress=False,
          overrides=[cache, *conv, "train.ae.max_steps=4"])
    train("cm", data, root / "run", load_config("tiny"), progress=False,
          overrides=[cache, "train.cm.max_steps=2"])
    return export_run(root / "run", root / "model"), data, cache


def test_train_ae_grows_the_latent_with_the_old_tokens_frozen(
        conv_model: tuple[Path, Path, str], tmp_path: Path) -> None:
    """`train ae --init MODEL ae.n_tokens=3 ae.freeze_encoder=true`: the old token's encoder
    rows and the convolutions stay as shipped, the new token's rows and the decoder learn; a
    resumed run keeps them frozen; `train cm --init MODEL --ae RUN` grows the denoiser, and
    the exported model generates with 3 tokens."""
    import mlct
    from mlct.cli import main
    from mlct.generate.bundle import read_bundle
    from mlct.train.export import export_run

    model, data, cache = conv_model
    run = tmp_path / "grown"
    grow = [cache, "ae.n_tokens=3", "ae.freeze_encoder=true", "train.ae.lr=1e-2"]
    train("ae", data, run, None, progress=False, init=model, stop_at=2,
          overrides=[*grow, "train.ae.max_steps=4"])
    train("ae", data, run, None, progress=False, resume=True)
    ckpt = load_checkpoint(latest_checkpoint(run / "ae" / "checkpoints"), with_state=False)
    assert ckpt.meta["config"]["ae"]["grown_from"] == 2
    assert int(ckpt.meta["step"]) == 4
    after = ckpt.module_state("ae")
    _, before = read_bundle(model)
    old = {k[len("ae_encoder."):]: v for k, v in before.items() if k.startswith("ae_encoder.")}
    for key, value in old.items():
        if key.startswith("to_tokens."):
            assert torch.equal(after[key][: 2 * D], value)  # the old rows, unmoved
            assert not torch.allclose(after[key][2 * D:], torch.zeros(1))
        else:
            assert torch.equal(after[key], value)  # the convolutions, unmoved
    decoder = {k[len("decoder."):]: v for k, v in before.items() if k.startswith("decoder.")}
    assert after["from_tokens.weight"][:, 2 * D:].abs().sum() > 0  # the new columns learned
    assert any(not torch.allclose(after[k], v) for k, v in decoder.items()
               if k != "from_tokens.weight")

    train("cm", data, run, None, progress=False, init=model, ae_path=run,
          overrides=[cache, "train.cm.max_steps=2"])
    grown = export_run(run, tmp_path / "grown_model")
    _, tensors = read_bundle(grown)
    assert tensors["denoiser.pos"].shape[1] == 1 + 3
    torch.testing.assert_close(tensors["denoiser.pos"][:, :3].float(),
                               before["denoiser.pos"].float(), atol=0.05, rtol=0)
    generator = mlct.load(grown)
    motion = generator.generate("a person walks forward", seconds=2.0, seed=0)
    joints = torch.as_tensor(motion.joints)
    assert joints.shape[-2:] == (22, 3) and joints.shape[-3] == 40 and torch.isfinite(joints).all()


def test_growing_needs_the_conv_autoencoder_and_refuses_fewer_tokens(
        conv_model: tuple[Path, Path, str], tmp_path: Path) -> None:
    model, data, cache = conv_model
    with pytest.raises(MlctError, match="grow, not shrink"):
        train("ae", data, tmp_path / "a", None, progress=False, init=model,
              overrides=[cache, "ae.n_tokens=1"])
    with pytest.raises(MlctError, match="weight_decay"):
        train("ae", data, tmp_path / "b", None, progress=False, init=model,
              overrides=[cache, "ae.n_tokens=3", "ae.freeze_encoder=true",
                         "train.ae.weight_decay=0.01", "train.ae.max_steps=1"])
    checkpoints = tmp_path / "b" / "ae" / "checkpoints"
    assert not checkpoints.is_dir() or latest_checkpoint(checkpoints) is None


def test_train_ae_adds_an_arm_pair_keeping_the_encoder_and_the_body(
        conv_model: tuple[Path, Path, str], tmp_path: Path) -> None:
    """`train ae --init MODEL ae.n_tokens=3 ae.arm_tokens=1 ae.freeze_encoder=true`: the old
    encoder and its 2 tokens stay exactly as shipped, the decoder draws the body's columns as
    before at step 0, the arm pair trains; stage 2 then grows its positions to 3 tokens."""
    import mlct
    from mlct.generate.bundle import read_bundle
    from mlct.nn.build import build_autoencoder
    from mlct.config import config_from_dict
    from mlct.train.export import export_run

    model, data, cache = conv_model
    run = tmp_path / "arms"
    arms = [cache, "ae.n_tokens=3", "ae.arm_tokens=1", "ae.arm_channels=8",
            "ae.freeze_encoder=true", "train.ae.lr=1e-2", "train.ae.max_steps=3"]
    train("ae", data, run, None, progress=False, init=model, overrides=arms)
    ckpt = load_checkpoint(latest_checkpoint(run / "ae" / "checkpoints"), with_state=False)
    after, config = ckpt.module_state("ae"), config_from_dict(ckpt.meta["config"], "run")
    assert config.ae.grown_from == 2 and config.ae.arm_tokens == 1
    meta, before = read_bundle(model)
    for key, value in before.items():
        if key.startswith("ae_encoder."):
            assert torch.equal(after[key[len("ae_encoder."):]], value)  # old encoder, unmoved
    assert after["arm_to_tokens.weight"].abs().sum() > 0
    # at step 0 the body's columns decode as the shipped decoder drew them
    from mlct.nn.grow import add_arm_pair

    old_config = config_from_dict(meta["config"], "model")
    old_ae = build_autoencoder(old_config, 263).eval()
    old_ae.load_state_dict({**{k[len("decoder."):]: v.float() for k, v in before.items()
                               if k.startswith("decoder.")},
                            **{k[len("ae_encoder."):]: v.float() for k, v in before.items()
                               if k.startswith("ae_encoder.")}})
    new_ae = build_autoencoder(config, 263).eval()
    new_ae.load_state_dict(add_arm_pair(old_ae.state_dict(), new_ae.state_dict(),
                                        new_ae.body_columns))
    x, lengths = torch.randn(2, 40, 263), torch.tensor([40, 17])
    with torch.no_grad():
        z_old, z_new = old_ae.encode(x, lengths).z, new_ae.encode(x, lengths).z
        torch.testing.assert_close(z_new[:, :2], z_old)
        body = new_ae.body_columns
        torch.testing.assert_close(new_ae.decode(z_new, lengths)[..., body],
                                   old_ae.decode(z_old, lengths)[..., body])

    train("cm", data, run, None, progress=False, init=model, ae_path=run,
          overrides=[cache, "train.cm.max_steps=2"])
    exported = export_run(run, tmp_path / "arms_model")
    motion = mlct.load(exported).generate("a person waves", seconds=2.0, seed=0)
    assert torch.isfinite(torch.as_tensor(motion.joints)).all()
    with pytest.raises(MlctError, match="needs ae.n_tokens=3"):
        train("ae", data, tmp_path / "bad", None, progress=False, init=model,
              overrides=[cache, "ae.n_tokens=4", "ae.arm_tokens=1", "train.ae.max_steps=1"])


def test_a_narrower_body_decoder_trains_beside_a_frozen_arm_decoder(
        conv_model: tuple[Path, Path, str], tmp_path: Path) -> None:
    """`ae.freeze_arm_decoder=true` with `ae.decoder_channels=8`: the body's decoder narrows
    and learns, the arm pair's decoder (and every encoder) stays exactly as loaded; without
    an arm pair the option is refused."""
    model, data, cache = conv_model
    arms = tmp_path / "arms"
    train("ae", data, arms, None, progress=False, init=model,
          overrides=[cache, "ae.n_tokens=3", "ae.arm_tokens=1", "ae.arm_channels=8",
                     "ae.freeze_encoder=true", "train.ae.lr=1e-2", "train.ae.max_steps=2"])
    run = tmp_path / "narrow_body"
    train("ae", data, run, None, progress=False, init=arms,
          overrides=[cache, "ae.freeze_encoder=true", "ae.freeze_arm_decoder=true",
                     "ae.decoder_channels=8", "train.ae.lr=1e-2", "train.ae.max_steps=3"])

    def weights(path: Path) -> dict[str, torch.Tensor]:
        return load_checkpoint(latest_checkpoint(path / "ae" / "checkpoints"),
                               with_state=False).module_state("ae")

    before, after = weights(arms), weights(run)
    frozen = [k for k in before if k.startswith(("arm_decoder.", "arm_from_tokens.",
                                                 "encoder.", "arm_encoder."))]
    assert any(k.startswith("arm_decoder.") for k in frozen)
    assert all(torch.equal(after[k], before[k]) for k in frozen)
    assert after["decoder.1.weight"].shape[:2] == (8, 8)  # the body's, narrowed
    from mlct.nn.narrow import narrow_decoders  # where the narrowed decoder started

    start = narrow_decoders(before, after)
    assert not torch.equal(after["decoder.1.weight"], start["decoder.1.weight"])  # it learned
    with pytest.raises(MlctError, match="freeze_arm_decoder needs an arm pair"):
        train("ae", data, tmp_path / "no_arms", None, progress=False, init=model,
              overrides=[cache, "ae.freeze_encoder=true", "ae.freeze_arm_decoder=true",
                         "train.ae.max_steps=1"])


def test_an_arm_pair_started_from_the_body_draws_the_arms_as_the_old_pair() -> None:
    """`ae.arm_init=body` (nn/grow.py arm_pair_from_body): the arm pair is the old pair
    restricted to the arms' columns, so on a motion whose other features are zero (the mean
    pose's) its tokens are the old encoder's and its decoder draws the arm columns as the old
    decoder drew them; a pair of another width cannot be copied and says so."""
    from mlct.motion.features import arm_feature_columns
    from mlct.nn.grow import add_arm_pair

    torch.manual_seed(0)
    arms = arm_feature_columns(263)
    old = ConvMotionAutoencoder(263, "plain", n_tokens=2, latent_dim=8, channels=16,
                                max_len=40).eval()
    new = ConvMotionAutoencoder(263, "plain", n_tokens=4, latent_dim=8, channels=16,
                                max_len=40, arm_tokens=2, arm_channels=16,
                                arm_columns=arms).eval()
    new.load_state_dict(add_arm_pair(old.state_dict(), new.state_dict(), new.body_columns,
                                     new.arm_columns))
    x, lengths = torch.zeros(2, 40, 263), torch.tensor([40, 23])
    x[..., arms] = torch.randn(2, 40, len(arms))
    with torch.no_grad():
        z_old, z_new = old.encode(x, lengths).z, new.encode(x, lengths).z
        torch.testing.assert_close(z_new[:, 2:], z_old)  # the arm tokens: the old ones
        drawn_old, drawn_new = old.decode(z_old, lengths), new.decode(z_new, lengths)
        torch.testing.assert_close(drawn_new[..., arms], drawn_old[..., arms])
        body = new.body_columns  # and the body draws its own columns as before
        torch.testing.assert_close(drawn_new[..., body], drawn_old[..., body])
    narrow = ConvMotionAutoencoder(263, "plain", n_tokens=4, latent_dim=8, channels=16,
                                   max_len=40, arm_tokens=2, arm_channels=8, arm_columns=arms)
    with pytest.raises(MlctError, match="arm_channels"):
        add_arm_pair(old.state_dict(), narrow.state_dict(), narrow.body_columns,
                     narrow.arm_columns)


def test_a_narrower_decoder_trains_on_the_frozen_encoder_and_serves_the_old_stage_two(
        conv_model: tuple[Path, Path, str], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """`train ae --init MODEL ae.freeze_encoder=true ae.decoder_channels=8`: the encoder loads
    and stays as shipped, the decoder is 8 channels wide (the model's, pruned: nn/narrow.py,
    tested in test_narrow.py); the model's stage 2
    exported with it (`--decoder-from`) generates, its latents unchanged."""
    import mlct
    from mlct.cli import main
    from mlct.generate.bundle import read_bundle
    from mlct.train.export import export_run

    model, data, cache = conv_model
    run = tmp_path / "narrow"
    train("ae", data, run, None, progress=False, init=model,
          overrides=[cache, "ae.freeze_encoder=true", "ae.decoder_channels=8",
                     "train.ae.lr=1e-2", "train.ae.max_steps=3"])
    ckpt = load_checkpoint(latest_checkpoint(run / "ae" / "checkpoints"), with_state=False)
    after = ckpt.module_state("ae")
    assert ckpt.meta["config"]["ae"]["decoder_channels"] == 8
    assert after["decoder.1.weight"].shape[:2] == (8, 8)  # the first conv after the upsampling
    assert after["encoder.0.weight"].shape[0] == 16  # the encoder keeps its width
    _, before = read_bundle(model)
    encoder = [k for k in before if k.startswith("ae_encoder.")]
    assert encoder and all(torch.equal(after[k[len("ae_encoder."):]], before[k])
                           for k in encoder)
    # the old model's stage 2 (the tiny run's cm) with the narrow decoder
    exported = export_run(model.parent / "run", tmp_path / "narrow_model", decoder_from=run)
    motion = mlct.load(exported).generate("a person walks forward", seconds=2.0, seed=0)
    assert torch.isfinite(torch.as_tensor(motion.joints)).all()
    # the same decoder swapped into the model itself (`mlct convert MODEL --decoder-from RUN
    # --out DIR`): every other tensor as stored, the decoder's widths in its config, and the
    # same motion as the stage-2 run exported with it
    swapped = tmp_path / "swapped"
    assert main(["convert", str(model), "--decoder-from", str(run), "--out", str(swapped)]) == 0
    _, changed = read_bundle(swapped)
    assert set(changed) == set(before)
    assert all(torch.equal(changed[k], before[k]) for k in before if not k.startswith("decoder."))
    assert changed["decoder.decoder.1.weight"].shape[:2] == (8, 8)
    assert mlct.load(swapped).config.ae.decoder_channels == 8
    again = mlct.load(swapped).generate("a person walks forward", seconds=2.0, seed=0)
    assert torch.allclose(torch.as_tensor(again.joints), torch.as_tensor(motion.joints),
                          atol=1e-4)
    assert main(["convert", str(model), "--decoder-from", str(run)]) == 2  # no --out
    assert "give it --out DIR" in capsys.readouterr().err
    other = tmp_path / "other_encoder"
    train("ae", data, other, load_config("tiny"), progress=False,  # the model's shapes
          overrides=[cache, "ae.architecture=conv", "ae.channels=16", "ae.latent_dim=8",
                     "train.ae.max_steps=1"])
    assert main(["convert", str(model), "--decoder-from", str(other), "--out",
                 str(tmp_path / "refused")]) == 2
    assert "its encoder is not the run's" in capsys.readouterr().err
    assert not (tmp_path / "refused").exists()
    with pytest.raises(MlctError, match="keep ae.n_tokens"):
        train("ae", data, tmp_path / "bad", None, progress=False, init=model,
              overrides=[cache, "ae.decoder_channels=8", "ae.n_tokens=3",
                         "train.ae.max_steps=1"])
