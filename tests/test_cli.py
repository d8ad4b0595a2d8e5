"""The command line as a user calls it: one-line errors with exit 2, never a traceback (the
bad-input tables are in test_bad_inputs.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from mlct.cli import main
from mlct.data.layout import DatasetLayout


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mlct.cli", *args], capture_output=True,
                          text=True, timeout=120)


_BLAS = """
import os, sys
from mlct.cli import main
main(sys.argv[1:])
print(os.environ.get("OPENBLAS_NUM_THREADS"))
"""


def test_the_one_off_commands_run_numpy_on_one_blas_thread(tmp_path):
    """generate, render and retarget load numpy with OpenBLAS on one thread (cli/__init__.py's
    ONE_BLAS_THREAD), unless the user set it; the other commands keep its default."""
    missing = str(tmp_path / "missing.npy")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}

    def blas(*args: str, **extra: str) -> str:
        done = subprocess.run([sys.executable, "-c", _BLAS, *args], capture_output=True,
                              text=True, timeout=120, env={**env, **extra})
        return done.stdout.strip().splitlines()[-1]

    assert blas("render", missing, "--out", str(tmp_path / "x.png")) == "1"
    assert blas("render", missing, "--out", str(tmp_path / "x.png"),
                OPENBLAS_NUM_THREADS="2") == "2"
    assert blas("data", "check", missing) == "None"


@pytest.mark.slow
def test_unwritable_output_is_one_line_exit_2(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    result = _run("data", "synth", "--out", str(blocker / "sub" / "data"), "--num", "1")
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mlct: error:")


def test_demo_prints_a_caption_and_a_gif(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--num", "2"]) == 0
    caption, path = capsys.readouterr().out.strip().splitlines()
    assert caption.endswith(".") and path.endswith(".gif")
    assert (out / "000000.gif").stat().st_size > 1000
    assert Path(path) == out / "000000.gif"  # the motion --index names (default 0)
    # the caption printed is the first line's caption (caption#tokens#start#end) of the
    # motion's texts file in the dataset the demo wrote
    data = DatasetLayout(out / "data")
    first_line = (data.texts_dir / "000000.txt").read_text(encoding="utf-8").splitlines()[0]
    assert caption == first_line.split("#")[0]
    # a real animated GIF: one frame per frame of that motion, and the figure moves
    frames = len(np.load(data.features_path("000000")))
    with Image.open(path) as gif:
        assert gif.format == "GIF" and gif.n_frames == frames > 1
        first = np.asarray(gif.convert("RGB"))
        gif.seek(frames - 1)
        last = np.asarray(gif.convert("RGB"))
    assert first.shape == last.shape and not np.array_equal(first, last)


@pytest.mark.slow
def test_a_closed_pipe_is_not_an_error(tmp_path):
    """`mlct data stats DIR --no-write | head -1` had ended in 'mlct: error: Broken pipe'."""
    assert _run("data", "synth", "--out", str(tmp_path / "d"), "--num", "2").returncode == 0
    command = [sys.executable, "-m", "mlct.cli", "data", "stats", str(tmp_path / "d"),
               "--no-write"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               bufsize=0)
    process.stdout.read(1)  # the reader takes one byte and leaves, as head does
    process.stdout.close()
    _, err = process.communicate(timeout=120)
    assert process.returncode == 0 and b"error" not in err, err


def test_a_status_line_while_the_model_loads_on_a_terminal(tmp_path, capsys, monkeypatch):
    """Seconds of loading show a status line on a terminal; pipes stay clean."""
    out = tmp_path / "x.npy"
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["generate", "a man jogs straight ahead", "--seconds", "1", "--out",
                 str(out)]) == 0
    assert "mlct: loading the model and the text encoder" in capsys.readouterr().err
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    assert main(["generate", "a man jogs straight ahead", "--seconds", "1", "--out",
                 str(out)]) == 0
    assert capsys.readouterr().err == ""
