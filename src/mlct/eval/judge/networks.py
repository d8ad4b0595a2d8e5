"""The three networks of the standard text-motion matching evaluator (Guo et al. 2022).

Layer names, sizes and the order of the layers follow EricGuo5513/text-to-motion
networks/modules.py, so the official `text_mot_match/model/finest.tar` state dicts load with
strict=True:

- MovementConvEncoder: two Conv1d(k=4, s=2, p=1) + Dropout(0.2) + LeakyReLU(0.2) in `main`
  (indices 0 and 3 carry weights), then the per-step Linear `out_net`: T frames -> T // 4 steps.
- TextEncoderBiGRUCo / MotionEncoderBiGRUCo: `pos_emb` (text only), `input_emb`, one
  bidirectional `gru`, a learned initial state `hidden` (2, 1, H), and `output_net` =
  Linear(2H, H), LayerNorm(H), LeakyReLU(0.2), Linear(H, out) on the two final GRU states.

Unlike the reference, the GRU encoders take sequences in any length order (the packing sorts
and unsorts internally), and no module holds a device.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn
from torch.nn.utils.rnn import pack_padded_sequence

LEAK = 0.2  # LeakyReLU slope of every evaluator block
DROPOUT = 0.2  # only active in train mode; the evaluator always runs in eval mode


def _init_weight(module: nn.Module) -> None:
    """Xavier-normal weights and zero biases, as the reference's init_weight."""
    if isinstance(module, (nn.Conv1d, nn.Linear)):
        nn.init.xavier_normal_(module.weight)
        if module.bias is not None:
            nn.init.zeros_(module.bias)


def _co_embedding_head(hidden_size: int, output_size: int) -> nn.Sequential:
    """Linear(2H, H), LayerNorm, LeakyReLU, Linear(H, out): keys output_net.{0,1,3}."""
    return nn.Sequential(
        nn.Linear(hidden_size * 2, hidden_size),
        nn.LayerNorm(hidden_size),
        nn.LeakyReLU(LEAK),
        nn.Linear(hidden_size, output_size),
    )


def _lengths_cpu(lengths: Tensor | list[int]) -> Tensor:
    """pack_padded_sequence wants int64 lengths on the CPU."""
    return torch.as_tensor(lengths, dtype=torch.long).detach().cpu()


def _bigru_last(gru: nn.GRU, inputs: Tensor, lengths: Tensor | list[int], hidden: Tensor) -> Tensor:
    """Concatenated final forward/backward states (B, 2H) of a packed bidirectional GRU."""
    batch = inputs.shape[0]
    h0 = hidden.expand(-1, batch, -1).contiguous()  # (2, B, H), as hidden.repeat(1, B, 1)
    # enforce_sorted=False: torch sorts by length and returns h_n in input order, so callers
    # need not sort (the reference sorts each batch by hand and returns sorted embeddings).
    packed = pack_padded_sequence(inputs, _lengths_cpu(lengths), batch_first=True,
                                  enforce_sorted=False)
    _, last = gru(packed, h0)  # (2, B, H)
    return torch.cat([last[0], last[1]], dim=-1)


class MovementConvEncoder(nn.Module):
    """Motion features (B, T, D-4) -> movement codes (B, T // 4, output_size)."""

    def __init__(self, input_size: int, hidden_size: int, output_size: int) -> None:
        super().__init__()
        self.main = nn.Sequential(
            nn.Conv1d(input_size, hidden_size, 4, 2, 1),
            nn.Dropout(DROPOUT),
            nn.LeakyReLU(LEAK),
            nn.Conv1d(hidden_size, output_size, 4, 2, 1),
            nn.Dropout(DROPOUT),
            nn.LeakyReLU(LEAK),
        )
        self.out_net = nn.Linear(output_size, output_size)
        self.main.apply(_init_weight)
        self.out_net.apply(_init_weight)

    def forward(self, inputs: Tensor) -> Tensor:
        """(B, T, input_size) -> (B, T // 4, output_size)."""
        outputs = self.main(inputs.permute(0, 2, 1)).permute(0, 2, 1)
        return self.out_net(outputs)


class TextEncoderBiGRUCo(nn.Module):
    """GloVe word vectors + POS one-hots (B, L, .) -> text co-embedding (B, output_size)."""

    def __init__(self, word_size: int, pos_size: int, hidden_size: int, output_size: int) -> None:
        super().__init__()
        self.pos_emb = nn.Linear(pos_size, word_size)
        self.input_emb = nn.Linear(word_size, hidden_size)
        self.gru = nn.GRU(hidden_size, hidden_size, batch_first=True, bidirectional=True)
        self.output_net = _co_embedding_head(hidden_size, output_size)
        self.input_emb.apply(_init_weight)
        self.pos_emb.apply(_init_weight)
        self.output_net.apply(_init_weight)
        self.hidden_size = hidden_size
        self.hidden = nn.Parameter(torch.randn(2, 1, hidden_size))  # learned initial GRU state

    def forward(self, word_embs: Tensor, pos_onehot: Tensor,
                cap_lens: Tensor | list[int]) -> Tensor:
        """word_embs (B, L, word_size), pos_onehot (B, L, pos_size), cap_lens (B,) -> (B, out)."""
        # The POS one-hot is embedded into word space and added to the word vector.
        inputs = self.input_emb(word_embs + self.pos_emb(pos_onehot))  # (B, L, H)
        return self.output_net(_bigru_last(self.gru, inputs, cap_lens, self.hidden))


class MotionEncoderBiGRUCo(nn.Module):
    """Movement codes (B, T', input_size) -> motion co-embedding (B, output_size)."""

    def __init__(self, input_size: int, hidden_size: int, output_size: int) -> None:
        super().__init__()
        self.input_emb = nn.Linear(input_size, hidden_size)
        self.gru = nn.GRU(hidden_size, hidden_size, batch_first=True, bidirectional=True)
        self.output_net = _co_embedding_head(hidden_size, output_size)
        self.input_emb.apply(_init_weight)
        self.output_net.apply(_init_weight)
        self.hidden_size = hidden_size
        self.hidden = nn.Parameter(torch.randn(2, 1, hidden_size))

    def forward(self, inputs: Tensor, m_lens: Tensor | list[int]) -> Tensor:
        """inputs (B, T', input_size), m_lens (B,) in movement steps (frames // 4) -> (B, out)."""
        embedded = self.input_emb(inputs)  # (B, T', H)
        return self.output_net(_bigru_last(self.gru, embedded, m_lens, self.hidden))
