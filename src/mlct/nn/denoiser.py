"""Consistency network F(x_t, t, c) of Eq. 11 (Sec. 4.2, Fig. 2): latent tokens -> latent tokens.

S = c_skip x_t + c_out F lives in ``mlct.diffusion.consistency``; this module is F alone.
Facts from the MLCT authors' code (``denoiser_net.py``), kept here:
- sequence = [condition token, n latent tokens projected d -> width] + a learned positional
  embedding (``nn.Parameter`` initialized N(0, 1)); the condition token starts at zero;
- time: the continuous t in [0, 1] goes into the sinusoid unscaled (``time_embed_scale = 1``),
  ``time_embed_dim = 256`` channels, cos first (flip_sin_to_cos), frequency shift 0, period 10^4;
- before every block i: cond_i = W_t,i sinusoid(t) + W_c,i text (separate Linear layers per block,
  no shared MLP), added to the condition token only;
- head: Linear(width -> d), GELU, Linear(d -> d), default (not zero) initialization.
The skip transformer uses Xavier-uniform initialization (the authors' denoiser keeps PyTorch's
default there; their autoencoder and MLD use Xavier).

Ours, off by default (``text_tokens = 0`` is the paper): with a "+tokens" text encoder the
condition is [pooled vector, K token states] (text/encoders.py), and `text_queries` learned
queries attend over the token states; their outputs join the pooled vector before the per-block
projections. Why: the pooled MiniLM vectors of "waves the left hand" and "... the right hand"
have cosine 0.976, so the side is a 2 % signal; attention can weight the one word that differs.
Also ours, off by default: ``condition_all_tokens`` adds each block's condition to every token,
not the condition token alone: a short CPU run learns the text far faster (docs/training.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from mlct.nn.skip_transformer import SkipTransformer


def timestep_embedding(t: Tensor, dim: int, max_period: float = 10000.0) -> Tensor:
    """Sinusoid [cos(t f_k), sin(t f_k)], f_k = max_period^(-2k / dim): (B,) -> (B, dim) fp32."""
    half = dim // 2
    k = torch.arange(half, device=t.device, dtype=torch.float32)
    freqs = torch.exp(-math.log(max_period) * k / half)  # (half,)
    args = t.float()[:, None] * freqs[None, :]  # (B, half)
    emb = torch.cat([torch.cos(args), torch.sin(args)], dim=-1)  # (B, 2 half)
    if dim % 2:
        emb = F.pad(emb, (0, 1))
    return emb  # (B, dim), float32


@dataclass(frozen=True)
class ConditionCache:
    """The condition's terms of one sampling run, computed once (Denoiser.condition_terms) and
    handed to every step's forward, rather than recomputed at each step (docs/performance.md)."""

    text_emb: Tensor  # (B, text_dim) the condition the terms were computed for
    text: list[Tensor]  # W_c,i LN(c) of every block i: `layers` x (B, width)
    times: dict[float, list[Tensor]]  # t -> W_t,i sinusoid(t), `layers` x (1, width); CPU only
    # On a GPU: the same terms of each of `times` in order, taken one per forward call (the
    # samplers evaluate the network once per time, in order): no read of t from the device,
    # which a CUDA graph could not do and which would otherwise stall every step.
    in_order: list[list[Tensor]] = field(default_factory=list)


class Denoiser(nn.Module):
    """F(x_t, t, c): skip transformer over [condition token, latent tokens] (Eq. 11)."""

    def __init__(
        self,
        latent_dim: int = 256,
        n_tokens: int = 3,
        text_dim: int = 384,
        width: int = 512,
        layers: int = 11,
        heads: int = 8,
        ff_dim: int = 2048,
        dropout: float = 0.1,
        time_embed_dim: int = 256,
        time_embed_scale: float = 1.0,
        text_tokens: int = 0,
        text_queries: int = 2,
        text_heads: int = 4,
        condition_all_tokens: bool = False,
    ) -> None:
        super().__init__()
        if text_tokens < 0 or (text_tokens and text_dim % (text_tokens + 1)):
            raise ValueError(f"text_dim {text_dim} is not (1 + text_tokens {text_tokens}) rows")
        self.latent_dim = latent_dim
        self.n_tokens = n_tokens
        self.text_dim = text_dim
        self.width = width
        self.time_embed_dim = time_embed_dim
        self.time_embed_scale = time_embed_scale
        self.condition_all_tokens = condition_all_tokens
        self.in_proj = nn.Linear(latent_dim, width)
        self.pos = nn.Parameter(torch.randn(1, 1 + n_tokens, width))
        self.time_proj = nn.ModuleList(nn.Linear(time_embed_dim, width) for _ in range(layers))
        # Text encoders differ in scale (MiniLM is unit-norm, ~0.05 per component; CLIP's pooled
        # features are ~10x larger): a LayerNorm makes the condition as loud as the time
        # embedding whatever the encoder. Without it a MiniLM-conditioned model learned the text
        # so slowly that its samples ignored it. (Not in the authors' code, which uses CLIP.)
        self.text_tokens = text_tokens
        cond_dim = text_dim
        if text_tokens:
            token_dim = text_dim // (text_tokens + 1)
            self.token_norm = nn.LayerNorm(token_dim)
            self.text_query = nn.Parameter(0.02 * torch.randn(1, text_queries, token_dim))
            self.text_attention = nn.MultiheadAttention(token_dim, text_heads, batch_first=True)
            cond_dim = token_dim * (1 + text_queries)
        self.text_norm = nn.LayerNorm(cond_dim)
        self.text_proj = nn.ModuleList(nn.Linear(cond_dim, width) for _ in range(layers))
        self.backbone = SkipTransformer(width, layers, heads, ff_dim, dropout, "gelu")
        self.head = nn.Sequential(
            nn.Linear(width, latent_dim), nn.GELU(), nn.Linear(latent_dim, latent_dim)
        )

    def text_terms(self, text_emb: Tensor) -> list[Tensor]:
        """W_c,i LN(c) of every block i: `layers` tensors (B, width)."""
        if self.text_tokens:
            text_emb = self._attend_tokens(text_emb)
        text_emb = self.text_norm(text_emb)
        return [cp(text_emb) for cp in self.text_proj]

    def _attend_tokens(self, text_emb: Tensor) -> Tensor:
        """[pooled, K token states] (B, (1 + K) D) -> [pooled, Q attended] (B, (1 + Q) D)."""
        b = text_emb.shape[0]
        rows = text_emb.view(b, self.text_tokens + 1, -1)  # (B, 1 + K, D)
        pooled, states = rows[:, 0], rows[:, 1:]
        padding = states.abs().sum(-1) == 0  # (B, K) the zero rows past the caption's end
        padding[:, 0] = False  # [CLS] always counts (and an all-zero row cannot empty the softmax)
        query = self.text_query.expand(b, -1, -1).to(states.dtype)
        attended, _ = self.text_attention(query, self.token_norm(states), self.token_norm(states),
                                          key_padding_mask=padding, need_weights=False)
        return torch.cat([pooled, attended.flatten(1)], dim=1)

    def time_terms(self, t: Tensor, dtype: torch.dtype = torch.float32) -> list[Tensor]:
        """W_t,i sinusoid(t) of every block i: `layers` tensors (B, width), t (B,)."""
        t_emb = timestep_embedding(t * self.time_embed_scale, self.time_embed_dim)  # (B, 256)
        t_emb = t_emb.to(dtype)
        return [tp(t_emb) for tp in self.time_proj]

    def condition_terms(self, text_emb: Tensor, times: Tensor) -> ConditionCache:
        """The text terms of text_emb and the time terms of each of `times` (the times a
        sampler evaluates the network at), for forward's `cache`. Inference only: the terms
        carry no gradient. On the CPU the time terms are looked up by t; on a GPU, where reading
        t would wait for the device at every step, they are taken in the order of `times`."""
        times = times.reshape(-1)
        with torch.no_grad():
            text = self.text_terms(text_emb)
            terms = self.time_terms(times, text[0].dtype)  # `layers` x (K, width)
            rows = [[term[k : k + 1] for term in terms] for k in range(len(times))]
        if times.device.type == "cpu":
            return ConditionCache(text_emb, text, dict(zip(times.tolist(), rows)))
        return ConditionCache(text_emb, text, {}, rows)

    def forward(self, x_t: Tensor, t: Tensor, text_emb: Tensor,
                cache: ConditionCache | None = None) -> Tensor:
        """x_t (B, n, d), t (B,) or scalar in [0, 1], text_emb (B, text_dim) -> F (B, n, d).

        cache: condition_terms(text_emb, times), whose terms are used instead of computed: the
        text terms, and the time terms when every item's t is one of `times`."""
        if x_t.ndim != 3 or tuple(x_t.shape[1:]) != (self.n_tokens, self.latent_dim):
            raise ValueError(
                f"x_t must be (B, {self.n_tokens}, {self.latent_dim}), got {tuple(x_t.shape)}"
            )
        b = x_t.shape[0]
        if text_emb.shape != (b, self.text_dim):
            raise ValueError(
                f"text_emb must be ({b}, {self.text_dim}), got {tuple(text_emb.shape)}"
            )
        if cache is not None and cache.text_emb is not text_emb:
            raise ValueError("the condition cache was computed for another text_emb")
        t = torch.as_tensor(t, device=x_t.device).reshape(-1).expand(b)  # (B,)
        text = cache.text if cache is not None else self.text_terms(text_emb.to(x_t.dtype))
        time = None
        if cache is not None and cache.in_order:
            time = cache.in_order.pop(0)  # this call's time, by the samplers' order
        elif cache is not None and cache.times and bool((t == t[0]).all()):
            time = cache.times.get(float(t[0]))  # (1, w) each, broadcast over the batch
        if time is None:
            time = self.time_terms(t, x_t.dtype)
        if self.condition_all_tokens:
            # Ours: every token gets the block's condition, so the latent tokens read the text
            # directly rather than only through attention to the condition token.
            conds = [(a + c).unsqueeze(1) for a, c in zip(time, text)]  # (B, 1, w) broadcast
        else:
            # the authors': one condition per block, on the condition token only (position 0)
            conds = [
                F.pad((a + c).unsqueeze(1), (0, 0, 0, self.n_tokens))  # (B, 1+n, w)
                for a, c in zip(time, text)
            ]
        h = torch.cat([x_t.new_zeros(b, 1, self.width), self.in_proj(x_t)], dim=1)  # (B, 1+n, w)
        h = self.backbone(h + self.pos, cond=conds)  # (B, 1+n, w)
        return self.head(h[:, 1:])  # (B, n, d)
