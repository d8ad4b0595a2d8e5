"""Samplers (Algorithm 2, DDIM) and stage-2 objectives (Algorithm 1) against closed forms."""

from __future__ import annotations

import pytest
import torch

from mlct.diffusion.consistency import pseudo_huber
from mlct.diffusion.losses import consistency_training_loss, diffusion_training_loss
from mlct.diffusion.samplers import ddim_times, draw_noise, sample_consistency, sample_ddim
from mlct.diffusion.schedule import VPSchedule, append_dims, karras_time_grid, sampling_times

SCHEDULE = VPSchedule()
GRID = karras_time_grid(50, dtype=torch.float64)


def _oracle(x0: torch.Tensor, calls: list):
    def model(x: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        calls.append(float(t[0]))
        return x0.expand_as(x)
    return model


def test_consistency_sampler_one_pass_per_step_and_exact_with_oracle() -> None:
    x0 = torch.rand(2, 3, 4, dtype=torch.float64) * 2 - 1
    for k in (1, 2, 5, 10):
        calls: list = []
        times = sampling_times(GRID, k)
        gen = torch.Generator().manual_seed(0)
        out = sample_consistency(_oracle(x0, calls), draw_noise(x0.shape, gen, times), times,
                                 SCHEDULE, gen)
        assert torch.equal(out, x0)
        assert len(calls) == k and calls[0] == 1.0 and calls == sorted(calls, reverse=True)


def test_consistency_sampler_clamps_and_renoises_with_fresh_noise() -> None:
    seen: list[torch.Tensor] = []

    def model(x: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        seen.append(x.clone())
        return torch.full_like(x, 3.0)  # out of range: must be clamped to 1

    times = sampling_times(GRID, 3)
    gen = torch.Generator().manual_seed(1)
    out = sample_consistency(model, draw_noise((1, 2, 2), gen, times), times, SCHEDULE, gen)
    assert torch.equal(out, torch.ones(1, 2, 2, dtype=out.dtype))
    # Between steps: x = alpha_s * clamp(x0) + sigma_s * z with a fresh z each time.
    z1 = (seen[1] - SCHEDULE.alpha(times[1])) / SCHEDULE.sigma(times[1])
    z2 = (seen[2] - SCHEDULE.alpha(times[2])) / SCHEDULE.sigma(times[2])
    assert not torch.allclose(z1, z2)
    assert not torch.allclose(seen[0], z1)


def test_same_seed_same_sample() -> None:
    model = lambda x, t: torch.tanh(x * t[:, None, None])  # noqa: E731
    times = sampling_times(GRID, 4)
    def sample(seed: int) -> torch.Tensor:
        gen = torch.Generator().manual_seed(seed)
        return sample_consistency(model, draw_noise((2, 3, 4), gen, times), times, SCHEDULE, gen)

    a, b, c = sample(7), sample(7), sample(8)
    assert torch.equal(a, b) and not torch.equal(a, c)


def test_ddim_sampler_exact_with_oracle_and_lands_on_x0() -> None:
    x0 = torch.rand(2, 3, 4) * 2 - 1
    calls: list = []
    times = ddim_times(50)
    assert times.shape == (51,) and times[0] == 1.0 and times[-1] == 0.0
    noise = draw_noise(x0.shape, torch.Generator().manual_seed(0), times)
    out = sample_ddim(_oracle(x0, calls), noise, times, SCHEDULE)
    assert len(calls) == 50
    assert torch.equal(out, x0)


def _recorder(value: torch.Tensor | None = None):
    record: dict = {}

    def fn(x: torch.Tensor, t: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        record.setdefault("x", []).append(x.clone())
        record.setdefault("t", []).append(t.clone())
        return torch.zeros_like(x) if value is None else value.expand_as(x)
    return fn, record


def test_consistency_loss_weights_and_trajectory() -> None:
    batch, c = 64, 0.001
    x0 = torch.rand(batch, 3, 4, dtype=torch.float64) * 1.6 - 0.8
    cond, null = torch.randn(batch, 5, dtype=torch.float64), torch.zeros(5, dtype=torch.float64)
    online, on_rec = _recorder()  # S_online == 0
    target, tg_rec = _recorder(torch.ones((), dtype=torch.float64))  # S_target == 1
    gen = torch.Generator().manual_seed(3)
    out = consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID, guidance=0.0,
                                    huber_c=c, generator=gen)
    # Replay the generator: the time index, then the noise.
    replay = torch.Generator().manual_seed(3)
    index = torch.randint(1, 50, (batch,), generator=replay)
    z = torch.randn(x0.shape, generator=replay, dtype=x0.dtype)
    t_i, t_prev = GRID[index], GRID[index - 1]
    # Eq. 15: 1/(t_i - t_{i-1}) * d(0, 1), averaged over the batch; d(0, x0) unconditional.
    per = (1 + c**2) ** 0.5 - c
    assert torch.allclose(out["consistency"], (1 / (t_i - t_prev)).mean() * per)
    assert torch.allclose(out["unconditional"], pseudo_huber(torch.zeros_like(x0), x0, c))
    assert torch.allclose(out["loss"], out["consistency"] + out["unconditional"])
    # The online network saw x_t = alpha x0 + sigma z, conditional and null in one batch.
    x_t = append_dims(SCHEDULE.alpha(t_i), 3) * x0 + append_dims(SCHEDULE.sigma(t_i), 3) * z
    assert torch.allclose(on_rec["x"][0], torch.cat([x_t, x_t]))
    # With w = 0 the guided target is x0 and the DPM-Solver step is exact: x_prev lies on the
    # same noising trajectory at t_{i-1} (Eq. 12 with a known x0).
    x_prev = append_dims(SCHEDULE.alpha(t_prev), 3) * x0 + \
        append_dims(SCHEDULE.sigma(t_prev), 3) * z
    assert torch.allclose(tg_rec["x"][0], x_prev, atol=1e-10)
    assert torch.equal(tg_rec["t"][0], t_prev)


def test_guidance_moves_the_target_away_from_the_unconditional_estimate() -> None:
    x0 = torch.full((4, 2, 2), 0.2, dtype=torch.float64)
    cond, null = torch.randn(4, 3, dtype=torch.float64), torch.zeros(3, dtype=torch.float64)
    online, _ = _recorder()  # u = S(x_t, t, null) = 0
    target, rec = _recorder()
    gen = torch.Generator().manual_seed(0)
    consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID, guidance=2.0,
                              generator=gen)
    replay = torch.Generator().manual_seed(0)
    index = torch.randint(1, 50, (4,), generator=replay)
    z = torch.randn(x0.shape, generator=replay, dtype=x0.dtype)
    t_prev = GRID[index - 1]
    # x_phi = clamp((1 + w) x0 - w u) = 0.6: the step lands on alpha x_phi + sigma z-hat.
    x_t = append_dims(SCHEDULE.alpha(GRID[index]), 3) * x0 + \
        append_dims(SCHEDULE.sigma(GRID[index]), 3) * z
    eps_hat = (x_t - append_dims(SCHEDULE.alpha(GRID[index]), 3) * 0.6) / \
        append_dims(SCHEDULE.sigma(GRID[index]), 3)
    expected = append_dims(SCHEDULE.alpha(t_prev), 3) * 0.6 + \
        append_dims(SCHEDULE.sigma(t_prev), 3) * eps_hat
    assert torch.allclose(rec["x"][0], expected, atol=1e-10)


def test_denoise_term_regresses_the_conditional_branch_on_the_guided_latent() -> None:
    x0 = torch.full((8, 2, 2), 0.2, dtype=torch.float64)
    cond, null = torch.randn(8, 3, dtype=torch.float64), torch.zeros(3, dtype=torch.float64)
    online, _ = _recorder()  # S(x_t, t, c) = S(x_t, t, null) = 0
    target, _ = _recorder()
    c = 0.001
    plain = consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID,
                                      guidance=2.0, huber_c=c,
                                      generator=torch.Generator().manual_seed(0))
    assert "denoise" not in plain  # weight 0 = the paper's Eq. 15 alone
    out = consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID,
                                    guidance=2.0, huber_c=c, denoise_weight=0.5,
                                    generator=torch.Generator().manual_seed(0))
    # x_phi = (1 + 2) 0.2 - 2 * 0 = 0.6; the conditional output 0 is that far from it.
    per = (0.6**2 + c**2) ** 0.5 - c
    assert torch.allclose(out["denoise"], torch.tensor(per, dtype=torch.float64))
    assert torch.allclose(out["loss"], plain["loss"] + 0.5 * out["denoise"])
    # denoise_max_t: only the items drawn at t_i <= it carry the term (over the whole batch)
    replay = torch.Generator().manual_seed(0)
    t_i = GRID[torch.randint(1, 50, (8,), generator=replay)]
    cut = float(t_i.median())
    low = consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID,
                                    guidance=2.0, huber_c=c, denoise_weight=0.5,
                                    denoise_max_t=cut, generator=torch.Generator().manual_seed(0))
    share = float((t_i <= cut).double().mean())
    assert 0 < share < 1
    assert torch.allclose(low["denoise"], torch.tensor(per * share, dtype=torch.float64))
    assert torch.allclose(low["loss"], plain["loss"] + 0.5 * low["denoise"])


def test_motion_term_compares_the_decoded_estimate_with_the_decoded_target() -> None:
    """consistency.motion_weight: smooth-L1 of D(S(x_t, t, c)) against D(x_phi), the target
    decoded without gradient; a decoder blind to a direction makes that direction free."""
    x0 = torch.full((8, 2, 2), 0.2, dtype=torch.float64)
    cond, null = torch.randn(8, 3, dtype=torch.float64), torch.zeros(3, dtype=torch.float64)
    online, _ = _recorder()  # S(x_t, t, c) = 0
    target, _ = _recorder()
    seen = []
    weights = torch.tensor([3.0, 0.0], dtype=torch.float64)  # the decoder ignores the 2nd dim

    def decode(z):
        seen.append((z.detach().clone(), torch.is_grad_enabled()))
        return z * weights

    kwargs = dict(guidance=2.0, huber_c=0.001, denoise_weight=0.5)
    plain = consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID,
                                      generator=torch.Generator().manual_seed(0), **kwargs)
    out = consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID,
                                    generator=torch.Generator().manual_seed(0), decode=decode,
                                    motion_weight=2.0, **kwargs)
    (target_z, target_grad), (online_z, online_grad) = seen
    assert torch.allclose(target_z, torch.full_like(x0, 0.6))  # x_phi = 3 x 0.2 - 2 x 0
    assert not target_grad and online_grad
    assert torch.equal(online_z, torch.zeros_like(x0))
    # |3 x 0.6 - 0| = 1.8 on half the entries (smooth-L1: 1.3), 0 on the ignored ones.
    assert torch.allclose(out["motion"], torch.tensor(0.65, dtype=torch.float64))
    assert torch.allclose(out["loss"], plain["loss"] + 2.0 * out["motion"])
    seen.clear()  # motion_items: the term on the first items only
    consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID,
                              generator=torch.Generator().manual_seed(0), decode=decode,
                              motion_weight=2.0, motion_items=3, **kwargs)
    assert [len(z) for z, _ in seen] == [3, 3]
    with pytest.raises(ValueError, match="decode"):
        consistency_training_loss(online, target, x0, cond, null, SCHEDULE, GRID,
                                  motion_weight=1.0)


def test_diffusion_loss_drops_the_condition_at_the_given_rate() -> None:
    seen: dict = {}

    def net(x, t, c):
        seen["c"], seen["t"] = c, t
        return torch.zeros_like(x)

    x0 = torch.zeros(4000, 1, 1)
    cond, null = torch.ones(4000, 2), torch.zeros(2)
    out = diffusion_training_loss(net, x0, cond, null, SCHEDULE, cond_dropout=0.1,
                                  generator=torch.Generator().manual_seed(0))
    dropped = (seen["c"] == 0).all(1).float().mean().item()
    assert 0.08 < dropped < 0.12
    assert seen["t"].min() >= 1e-3 and seen["t"].max() <= 1
    assert abs(out["mse"].item() - 1.0) < 0.1  # predicting 0 for unit Gaussian noise


# ------------------------------------------------------------------------ the sampler objects


def _config():
    from mlct.config import load_config

    return load_config("tiny")


class _Net(torch.nn.Module):
    """F(x_t, t, c) = tanh(x_t + t + c.mean()): depends on every input, records its calls."""

    def __init__(self) -> None:
        super().__init__()
        self.calls: list[int] = []

    def forward(self, x: torch.Tensor, t: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        self.calls.append(x.shape[0])
        return torch.tanh(x + t[:, None, None] + c.mean(1)[:, None, None])


def test_sampler_objects_wrap_the_pure_functions() -> None:
    from mlct.diffusion.consistency import consistency_output
    from mlct.diffusion.parameterization import x0_from_eps
    from mlct.generate.samplers import ConsistencySampler, DDIMSampler

    config = _config()
    s = config.schedule
    cond, null = torch.randn(2, 5), torch.zeros(1, 5)
    net = _Net()
    cm = ConsistencySampler(config)
    assert (cm.default_steps, cm.max_steps, cm.passes_per_step) == (
        config.consistency.nfe, s.num_steps, 1)
    x = cm.noise((2, 3, 4), torch.Generator().manual_seed(0))
    got = cm.sample(net, x, cond, 3, generator=torch.Generator().manual_seed(1))
    want = sample_consistency(
        lambda x_t, t: consistency_output(x_t, net(x_t, t, cond), t, s.eta, s.time_scale), x,
        cm.times(3), cm.schedule, torch.Generator().manual_seed(1), cm.clamp)
    assert torch.equal(got, want) and net.calls == [2] * 6
    ddim = DDIMSampler(config)
    assert ddim.cfg and ddim.passes_per_step == 2 and ddim.guidance() == config.diffusion.guidance
    net.calls.clear()
    got = ddim.sample(net, x, cond, 4, guidance=3.0, uncond=null)

    def guided(x_t: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        eps_c, eps_u = net(x_t, t, cond), net(x_t, t, null.expand_as(cond))
        return x0_from_eps(x_t, eps_u + 3.0 * (eps_c - eps_u), t, ddim.schedule)

    want = sample_ddim(guided, x, ddim.times(4), ddim.schedule, ddim.clamp)
    assert torch.allclose(got, want, atol=1e-6) and net.calls[:4] == [4] * 4  # 2B a step
    assert ddim.times(4).shape == (5,) and ddim.max_steps == 1000


def test_a_sampler_starts_from_the_latent_it_is_given() -> None:
    from mlct.generate.samplers import ConsistencySampler

    sampler = ConsistencySampler(_config())
    seen: list[torch.Tensor] = []

    def net(x: torch.Tensor, t: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        seen.append(x.clone())
        return torch.zeros_like(x)

    start = torch.full((1, 3, 4), 0.25)  # a partly known latent, not noise
    sampler.sample(net, start, torch.zeros(1, 5), 1)
    assert torch.equal(seen[0], start)


def test_the_registry_names_every_sampler_and_fails_loudly() -> None:
    import pytest

    from mlct.errors import MlctError
    from mlct.generate.samplers import SAMPLERS, sampler_class, sampler_for_stage

    assert set(SAMPLERS) == {"consistency", "ddim"}  # the names bundles record
    for name, cls in SAMPLERS.items():
        assert sampler_class(name) is cls and sampler_for_stage(cls.stage) is cls
    assert sampler_for_stage("ae") is None
    with pytest.raises(MlctError, match="unknown sampler 'euler' \\(consistency, ddim\\)"):
        sampler_class("euler")
    with pytest.raises(MlctError, match="nfe must be within 1..10, got 11"):
        sampler_class("consistency")(_config()).check_steps(11)  # tiny: 10
