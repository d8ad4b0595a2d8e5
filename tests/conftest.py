from __future__ import annotations

import os

import pytest
import torch


@pytest.fixture(scope="module")
def one_thread():
    """One intra-op thread: small ops on a busy 2-core machine are far slower with two.

    Opt in per module: `pytestmark = pytest.mark.usefixtures("one_thread")`."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


# mlct.load's default backend is "auto" (onnx when onnxruntime is installed, its graphs made once
# into the cache). The suite pins torch, so that tests which swap or count the torch networks and
# tests of models without graphs neither convert models nor write to ~/.cache; the onnx and auto
# paths have their own tests (test_onnx*.py, test_auto_backend.py), which set the backend.
os.environ["MLCT_BACKEND"] = "torch"
