"""CheapDropout (mlct.nn.dropout): nn.Dropout's function with PCG64's random numbers."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from mlct.nn.dropout import CheapDropout, keep_mask, use_cheap_dropout


def test_the_mask_drops_at_the_rate_and_rescales_the_kept():
    torch.manual_seed(0)
    keep = keep_mask(torch.Size([64, 8, 1024]), 0.1)
    assert keep.dtype == torch.bool and keep.shape == (64, 8, 1024)
    dropped = 1.0 - keep.float().mean().item()
    assert abs(dropped - 0.1) < 0.002  # 524,288 draws: the standard error is 0.0004
    x = torch.ones(64, 8, 1024)
    y = CheapDropout(0.1).train()(x)
    assert torch.all((y == 0) | torch.isclose(y, torch.tensor(1 / 0.9)))
    assert abs(y.mean().item() - 1.0) < 0.003  # the expectation is kept


def test_a_seed_repeats_the_masks_and_another_changes_them():
    torch.manual_seed(5)
    a = keep_mask(torch.Size([1000]), 0.3)
    torch.manual_seed(5)
    b = keep_mask(torch.Size([1000]), 0.3)
    c = keep_mask(torch.Size([1000]), 0.3)  # the generator moved on
    assert torch.equal(a, b) and not torch.equal(a, c)


def test_the_module_trains_like_dropout_and_is_the_identity_in_eval():
    torch.manual_seed(1)
    layer = CheapDropout(0.5)
    x = torch.randn(4, 300, requires_grad=True)
    y = layer(x)
    kept = y != 0
    torch.testing.assert_close(y[kept], 2 * x[kept])
    y.sum().backward()  # the gradient flows through the kept elements only, scaled
    torch.testing.assert_close(x.grad, kept.float() * 2)
    assert torch.equal(layer.eval()(x), x)
    assert torch.equal(CheapDropout(0.0).train()(x), x)
    bf = layer.train()(x.detach().bfloat16())
    assert bf.dtype == torch.bfloat16
    kept_bf = bf != 0  # the scale applied in bfloat16 arithmetic, rounded per element
    torch.testing.assert_close(bf[kept_bf], (x.detach().bfloat16() * 2)[kept_bf])
    with pytest.raises(ValueError, match="dropout probability"):
        CheapDropout(1.0)


def test_the_swap_reaches_a_transformer_layers_dropouts_and_keeps_its_weights():
    layer = nn.TransformerEncoderLayer(16, 2, 32, dropout=0.2, batch_first=True)
    before = {k: v.clone() for k, v in layer.state_dict().items()}
    assert use_cheap_dropout(layer) == 3  # after attention, inside and after the feed-forward
    assert all(isinstance(m, CheapDropout) and m.p == 0.2
               for m in (layer.dropout, layer.dropout1, layer.dropout2))
    after = layer.state_dict()
    assert after.keys() == before.keys() and all(torch.equal(after[k], before[k]) for k in after)
    layer.eval()
    x = torch.randn(2, 5, 16)
    with torch.no_grad():
        plain = nn.TransformerEncoderLayer(16, 2, 32, dropout=0.2, batch_first=True).eval()
        plain.load_state_dict(before)
        torch.testing.assert_close(layer(x), plain(x))
