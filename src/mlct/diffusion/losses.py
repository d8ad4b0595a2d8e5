"""Training objectives of stage 2: guided consistency training (Algorithm 1) and, for the
baseline, the standard denoising objective with condition dropout (as MLD).

Randomness (time index, noise, dropout of the condition) comes from `generator` when given, so
validation losses are reproducible; training passes None and uses the global, seeded RNG.
"""

from __future__ import annotations

from typing import Callable

import torch
from torch import Tensor

from mlct.diffusion.consistency import guided_target, pseudo_huber
from mlct.diffusion.schedule import VPSchedule, append_dims
from mlct.diffusion.solver import dpm_solver_1_step

ConsistencyFn = Callable[[Tensor, Tensor, Tensor], Tensor]  # S(x_t, t, c) -> (B, n, d)


def _randn(like: Tensor, generator: torch.Generator | None) -> Tensor:
    return torch.randn(like.shape, generator=generator, device=like.device, dtype=like.dtype)


def consistency_training_loss(
    online: ConsistencyFn,
    target: ConsistencyFn,
    x0: Tensor,
    cond: Tensor,
    null: Tensor,
    schedule: VPSchedule,
    grid: Tensor,
    guidance: float = 1.0,
    uncond_weight: float = 1.0,
    huber_c: float = 0.001,
    clamp: float | None = 1.0,
    denoise_weight: float = 0.0,
    denoise_max_t: float | None = None,
    generator: torch.Generator | None = None,
    decode: Callable[[Tensor], Tensor] | None = None,
    motion_weight: float = 0.0,
    motion_items: int | None = None,
) -> dict[str, Tensor]:
    """One step of conditionally guided consistency training (Algorithm 1, Eq. 13-15).

    x0 (B, n, d) are the AE latents, cond (B, c) the text embeddings, null (c,) the embedding
    of "". `target` is the EMA network (or the online one: the caller wraps it in no_grad).
    Returns the total loss and its two terms (Eq. 15), each a scalar.

    denoise_weight > 0 (ours; 0 = the paper) adds d(S(x_t, t_i, c), x_phi): the consistency
    condition taken over the whole way down to t = 0, where S is the identity, i.e. the
    conditional branch regresses the guided clean latent directly. Eq. 15 alone passes the
    text's information up the 50-point grid one interval at a time; a short run (thousands of
    steps, not the authors' ~200k) then samples near the mean latent for every prompt. The
    direct term is the large-interval end of easy consistency tuning (ECT, Geng et al. 2024).
    denoise_max_t (ours; None = every t): the direct term only on items with t_i at most this
    (averaged over the whole batch). Why: from an x_t that has forgotten most of x0, the best
    regression of x_phi is the text's median latent, so at large t the term pulls every noise
    of a prompt to one latent and the seeds of a prompt to one motion; where x_t still holds
    x0 it agrees with what a sample should be.

    motion_weight > 0 (ours) with `decode` (latents -> motion features, differentiable, the
    frozen decoder) adds the smooth-L1 of D(S(x_t, t_i, c)) against D(x_phi): the direct term
    measured where the motion is judged; on the first `motion_items` items only (all if None),
    `decode` taking that many.
    """
    batch = x0.shape[0]
    n = grid.shape[0]
    # i ~ U{2..N} (1-based): t_i and its lower neighbour t_{i-1} on the Karras grid.
    index = torch.randint(1, n, (batch,), generator=generator, device=grid.device)
    index = index.to(x0.device)
    grid = grid.to(device=x0.device, dtype=x0.dtype)
    t_i, t_prev = grid[index], grid[index - 1]  # (B,), (B,)
    z = _randn(x0, generator)
    x_t = append_dims(schedule.alpha(t_i), 3) * x0 + append_dims(schedule.sigma(t_i), 3) * z

    # Online passes, conditional and unconditional, batched into one call of 2B.
    nulls = null.to(cond).expand_as(cond)
    both = online(torch.cat([x_t, x_t]), torch.cat([t_i, t_i]), torch.cat([cond, nulls]))
    s_cond, s_uncond = both.chunk(2)  # (B, n, d) each

    with torch.no_grad():
        # Conditional trajectory simulation (Eq. 14): the guided clean estimate; u is detached.
        x_phi = guided_target(x0, s_uncond.detach(), guidance, clamp)
        x_prev = dpm_solver_1_step(x_t, x_phi, t_i, t_prev, schedule)  # Eq. 12
        s_target = target(x_prev, t_prev, cond)

    weight = 1.0 / (t_i - t_prev)  # (B,) the 1/(t_i - t_{i-1}) of Eq. 15
    consistency = (weight * pseudo_huber(s_cond, s_target, huber_c, per_sample=True)).mean()
    unconditional = pseudo_huber(s_uncond, x0, huber_c)
    out = {
        "loss": consistency + uncond_weight * unconditional,
        "consistency": consistency.detach(),
        "unconditional": unconditional.detach(),
    }
    if denoise_weight > 0:
        denoise = pseudo_huber(s_cond, x_phi, huber_c, per_sample=True)
        if denoise_max_t is not None:
            denoise = denoise * (t_i <= denoise_max_t).to(denoise)
        denoise = denoise.mean()
        out["loss"] = out["loss"] + denoise_weight * denoise
        out["denoise"] = denoise.detach()
    if motion_weight > 0:
        if decode is None:
            raise ValueError("motion_weight needs decode")
        k = batch if motion_items is None else min(motion_items, batch)
        with torch.no_grad():
            reference = decode(x_phi[:k])
        motion = torch.nn.functional.smooth_l1_loss(decode(s_cond[:k]), reference)
        out["loss"] = out["loss"] + motion_weight * motion
        out["motion"] = motion.detach()
    return out


def diffusion_training_loss(
    net: Callable[[Tensor, Tensor, Tensor], Tensor],
    x0: Tensor,
    cond: Tensor,
    null: Tensor,
    schedule: VPSchedule,
    cond_dropout: float = 0.1,
    t_min: float = 1e-3,
    generator: torch.Generator | None = None,
) -> dict[str, Tensor]:
    """Denoising objective of the latent diffusion baseline: MSE of the predicted noise (as MLD),
    t ~ U(t_min, 1), the condition replaced by the null embedding with prob. cond_dropout."""
    batch = x0.shape[0]
    t = t_min + (1 - t_min) * torch.rand(batch, generator=generator, device=x0.device,
                                         dtype=x0.dtype)
    eps = _randn(x0, generator)
    x_t = append_dims(schedule.alpha(t), 3) * x0 + append_dims(schedule.sigma(t), 3) * eps
    drop = torch.rand(batch, generator=generator, device=x0.device) < cond_dropout
    cond = torch.where(drop[:, None], null.to(cond).expand_as(cond), cond)
    mse = ((net(x_t, t, cond) - eps) ** 2).mean()
    return {"loss": mse, "mse": mse.detach()}
