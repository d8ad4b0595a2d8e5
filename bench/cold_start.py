"""Cold start: wall time of a fresh process to its first motion file, against the 1.0 s goal.

    python bench/cold_start.py [--repeat 5] [--model DIR] [--cli PATH] [--source]
                               [--against OLD/src]

Each case runs as a new process, --repeat times, the cases interleaved so that a busy machine
slows them alike; one untimed round first fills the OS file cache (a first run after a reboot
also reads torch's libraries from disk, which this does not time) and compiles mlct's modules to
bytecode, as `pip install` does: into a cache of the run's own (PYTHONPYCACHEPREFIX), also where
$PYTHONDONTWRITEBYTECODE is set, which would otherwise make every run compile them from source
(~0.08 s more here). --source times that instead: the environment as it is. Cases:
  - `python -c pass` and `python -c "import numpy"`: the interpreter, and the floor any numpy
    program sets; compare against these when the machine is busy (the goal is on 2 cores);
  - `python -c "import torch"` where torch is installed: what the onnx path no longer pays;
  - the CLI: `mlct generate "a person walks forward" --out x.npy`, through the console script
    next to this interpreter (not a pyenv shim, which adds its own start-up) or --cli;
  - the same to a rig file, `--out x.bvh` (the rig fit and the BVH writer: their imports too);
  - the Python API's first call: `import mlct; mlct.load().generate([...])`.
Prints min / median / max seconds per case, the median beside `import numpy`'s, and whether the
median meets the goal. --against OLD/src also times the three goal cases with another checkout's
package first on the path (PYTHONPATH; e.g. `git worktree add /tmp/old COMMIT`), taking turns
with this one's: a change's before and after under the same load.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from importlib.util import find_spec
from pathlib import Path

GOAL_S = 1.0
PROMPT = "a person walks forward"
GOAL_CASES = ("cli generate", "cli to .bvh", "api first call")


def cli_command(cli: str | None) -> list[str]:
    """The `mlct` console script installed with this interpreter, else `python -m mlct.cli`."""
    if cli:
        return [cli]
    script = Path(sys.executable).parent / "mlct"
    if script.is_file():
        return [str(script)]
    found = shutil.which("mlct")
    return [found] if found else [sys.executable, "-m", "mlct.cli"]


def cases(out_dir: Path, model: str | None, cli: str | None) -> dict[str, list[str]]:
    model_args = ["--model", model] if model else []
    api = (f"import mlct; g = mlct.load({model!r}); "
           f"assert g.generate([{PROMPT!r}])[0].joints.shape[0] > 0")
    torch = {"import torch": [sys.executable, "-c", "import torch"]} if find_spec("torch") else {}
    return {
        "python -c pass": [sys.executable, "-c", "pass"],
        "import numpy": [sys.executable, "-c", "import numpy"],
        **torch,
        "cli generate": [*cli_command(cli), "generate", PROMPT, "--out",
                         str(out_dir / "x.npy"), *model_args],
        "cli to .bvh": [*cli_command(cli), "generate", PROMPT, "--out",
                        str(out_dir / "x.bvh"), *model_args],
        "api first call": [sys.executable, "-c", api],
    }


def child_env(tmp: Path, source: bool) -> dict[str, str]:
    """The cases' environment: as it is with `source`, else with a bytecode cache in tmp."""
    env = dict(os.environ)
    if not source:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
    return env


def run_once(command: list[str], env: dict[str, str] | None = None) -> float:
    start = time.perf_counter()
    done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          env=env)
    wall = time.perf_counter() - start
    if done.returncode:
        raise SystemExit(f"{' '.join(command)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timed runs per case (default 5)")
    parser.add_argument("--model", default=None, help="model directory (default: the bundled)")
    parser.add_argument("--cli", default=None, help="the mlct executable to time")
    parser.add_argument("--source", action="store_true",
                        help="no bytecode cache of the run's own: the environment as it is")
    parser.add_argument("--against", default=None,
                        help="another checkout's src/ to time the goal cases of, in turns")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        commands = cases(Path(tmp), args.model, args.cli)
        env = child_env(Path(tmp), args.source)
        runs = [(name, command, env) for name, command in commands.items()]
        if args.against:
            old = {**env, "PYTHONPATH": os.pathsep.join(
                p for p in (str(Path(args.against).resolve()), env.get("PYTHONPATH")) if p)}
            runs += [(f"{name} (against)", commands[name], old) for name in GOAL_CASES]
        for _, command, case_env in runs:  # warm-up: the OS file cache, .pyc files
            run_once(command, case_env)
        times: dict[str, list[float]] = {name: [] for name, _, _ in runs}
        for _ in range(args.repeat):
            for name, command, case_env in runs:
                times[name].append(run_once(command, case_env))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"cold start, {args.repeat} runs per case; {os.cpu_count()} CPUs, load average "
          f"{load:.2f}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")
    print(f"cli: {' '.join(commands['cli generate'][:1])}; bytecode: "
          + ("as the environment has it (--source; PYTHONDONTWRITEBYTECODE="
             f"{os.environ.get('PYTHONDONTWRITEBYTECODE', 'unset')})" if args.source
             else "cached by the warm-up round, as an installed package has it"))
    numpy = statistics.median(times["import numpy"])
    if args.against:
        print(f"against: {Path(args.against).resolve()}")
    print(f"{'case':<26} {'min s':>7} {'median s':>9} {'max s':>7} {'- numpy s':>9}")
    for name, walls in times.items():
        median = statistics.median(walls)
        verdict = ""
        if name in GOAL_CASES:
            verdict = f"  {'meets' if median <= GOAL_S else 'MISSES'} the {GOAL_S} s goal"
        print(f"{name:<26} {min(walls):7.2f} {median:9.2f} {max(walls):7.2f} "
              f"{median - numpy:9.2f}{verdict}")


if __name__ == "__main__":
    main()
