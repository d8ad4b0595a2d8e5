"""The light install (`pip install mlct`: no torch): generation runs on the shipped ONNX graphs,
and what does need torch says which extra brings it, in one line (exit 2). Torch is made
unimportable in a fresh interpreter (this one has it loaded: conftest.py); that the default
paths import no torch where it is installed is tests/test_cold_start.py's."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

HEAVY = ("torch", "transformers", "sentence_transformers")

# Runs the snippet and prints the heavy modules it loaded, as JSON, on the last line.
WRAPPER = textwrap.dedent("""
    import json, sys
    {block}
    exec(compile(sys.argv[1], "<case>", "exec"))
    print(json.dumps(sorted({{m.split(".")[0] for m in sys.modules}} & set({heavy!r}))))
""")

# Torch made unimportable, as on a light install: its import raises ModuleNotFoundError.
NO_TORCH = textwrap.dedent("""
    class _NoTorch:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {heavy!r}:
                raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
            return None
    sys.meta_path.insert(0, _NoTorch())
""").format(heavy=HEAVY)


def _run(case: str, tmp_path, torch_absent: bool = False) -> subprocess.CompletedProcess:
    code = WRAPPER.format(block=NO_TORCH if torch_absent else "", heavy=HEAVY)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    env.pop("MLCT_BACKEND", None)  # the suite pins torch (conftest.py); auto is the default
    return subprocess.run([sys.executable, "-c", code, textwrap.dedent(case)], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=300)


def _heavy(done: subprocess.CompletedProcess) -> list[str]:
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_without_torch_generation_runs_and_torch_features_name_the_extra(tmp_path):
    case = """
        from mlct.cli import main
        import mlct

        mlct.load().generate("a person waves", seconds=2, seed=0).save("api.bvh")
        assert main(["generate", "a person walks forward", "--out", "w.npy", "--seed", "0",
                     "--quiet"]) == 0
        assert main(["render", "w.npy", "--out", "w.png"]) == 0
        assert main(["retarget", "w.npy", "--out", "w.g1.csv"]) == 0
        for argv in (["generate", "a person walks", "--backend", "torch", "--out", "t.npy"],
                     ["generate", "a person walks", "--device", "cuda", "--out", "t.npy"],
                     ["convert", "bundled", "--onnx", "--out", "t"]):
            assert main(argv) == 2, argv
    """
    done = _run(case, tmp_path, torch_absent=True)
    assert _heavy(done) == []
    errors = [line for line in done.stderr.splitlines() if line.startswith("mlct: error:")]
    assert len(errors) == 3 and all("pip install 'mlct[train]'" in e for e in errors), errors
    assert (tmp_path / "w.npy").is_file() and not (tmp_path / "t.npy").exists()
    assert (tmp_path / "w.png").is_file() and (tmp_path / "api.bvh").is_file()
