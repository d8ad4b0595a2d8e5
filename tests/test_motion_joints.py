"""motion/joints.py (numpy) against features.recover_from_ric (torch): the same joints."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.errors import MlctError
from mlct.motion.joints import features_to_joints, n_joints_for_dim

torch = pytest.importorskip("torch")


@pytest.mark.parametrize("dim, shape", [(263, (40,)), (251, (3, 17)), (263, (1,))])
def test_numpy_joints_are_the_torch_recovery(dim, shape):
    from mlct.motion.features import recover_from_ric

    rng = np.random.default_rng(dim)
    features = rng.normal(size=shape + (dim,)) * 0.3
    features[..., 0] *= 0.2  # half-angle velocities: turns of a few degrees a frame
    expected = recover_from_ric(torch.from_numpy(features)).numpy()
    got = features_to_joints(features)
    assert got.shape == shape + (n_joints_for_dim(dim), 3) and got.dtype == np.float64
    assert np.abs(got - expected).max() < 1e-12
    assert features_to_joints(features.astype(np.float32)).dtype == np.float32


def test_a_width_that_is_no_skeletons_is_refused():
    with pytest.raises(MlctError, match="standard feature width"):
        features_to_joints(np.zeros((4, 100)))
