"""The first motion of a fresh process imports nothing it does not need (bench/cold_start.py).

Each of these libraries once cost `mlct generate` from 0.1 s to seconds of start-up; a stray
module-level import would bring the cost back silently, so the generate paths are checked in a
fresh interpreter."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

# Not needed to write a .npy: torch (the onnx backend, the default, runs the shipped graphs
# with numpy around them: a light install has no torch), Hugging Face stacks, scientific
# extras, plotting, the web server; the typed config's pydantic and yaml (~0.1 s: the bundled
# model's config is read without them, config_view.py).
HEAVY = ("torch", "sentence_transformers", "transformers", "sklearn", "scipy", "matplotlib",
         "fastapi", "uvicorn", "plotly", "pydantic", "yaml")

_CHILD = """
import sys
import mlct
from mlct.cli import main
mlct.load().generate(["a person walks forward"], seconds=1, nfe=1, seed=0)
assert main(["generate", "a person walks forward", "--seconds", "1", "--nfe", "1",
             "--out", sys.argv[1], "--quiet"]) == 0
print("heavy:", *sorted(m for m in {HEAVY} if m in sys.modules))
"""


@pytest.mark.slow
def test_api_and_cli_generate_import_no_heavy_library(tmp_path: Path) -> None:
    src = str(Path(__file__).resolve().parent.parent / "src")
    path = os.pathsep.join(p for p in (src, os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "PYTHONPATH": path, "OMP_NUM_THREADS": "1"}
    env.pop("MLCT_BACKEND", None)  # the suite pins torch (conftest.py); the default is asked
    done = subprocess.run([sys.executable, "-c", _CHILD.format(HEAVY=HEAVY),
                           str(tmp_path / "x.npy")], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    heavy = done.stdout.strip().splitlines()[-1]  # after the CLI's line naming the file
    assert heavy == "heavy:", f"imported on the generate path: {heavy}"
    assert (tmp_path / "x.npy").is_file()


# A rig file (generated, or a .npy retargeted) needs none of these: roma brought torch._dynamo
# (~1 s) and the twist's filter scipy.signal (~0.7 s) to every one-off .bvh / .glb / .npz export,
# scipy's Rotation and ndimage (the rotations, the fit's moving average) scipy.spatial and
# scipy.sparse (~0.4 s), and the .npy reader matplotlib (docs/performance.md, "Cold start").
RIG_HEAVY = ("roma", "torch", "scipy", "matplotlib", "sentence_transformers", "transformers")

_RIG_CHILD = """
import sys
from mlct.cli import main
for out in sys.argv[1:]:
    assert main(["generate", "a person walks forward", "--seconds", "1", "--nfe", "1",
                 "--out", out, "--quiet"]) == 0
assert main(["retarget", sys.argv[-1], "--out", sys.argv[-1] + ".bvh"]) == 0  # draws nothing
print("heavy:", *sorted(m for m in {HEAVY} if m in sys.modules))
"""


@pytest.mark.slow
def test_rig_exports_import_no_heavy_library(tmp_path: Path) -> None:
    pytest.importorskip("pygltflib")  # the .glb writer's (the export extra)
    src = str(Path(__file__).resolve().parent.parent / "src")
    path = os.pathsep.join(p for p in (src, os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "PYTHONPATH": path, "OMP_NUM_THREADS": "1"}
    env.pop("MLCT_BACKEND", None)
    outs = [str(tmp_path / f"x.{ext}") for ext in ("bvh", "glb", "npz", "fbx", "g1.csv", "npy")]
    done = subprocess.run([sys.executable, "-c", _RIG_CHILD.format(HEAVY=RIG_HEAVY), *outs],
                          capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    heavy = done.stdout.strip().splitlines()[-1]
    assert heavy == "heavy:", f"imported on the rig export path: {heavy}"
    assert all(Path(out).stat().st_size > 0 for out in outs)
