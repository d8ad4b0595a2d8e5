"""The import architecture of src/mlct (docs/architecture.md): layers, and no cycles.

Every import statement under src/mlct is read with ast: at module level, inside functions (the
lazy ones) and under TYPE_CHECKING alike, since each is a dependency someone must keep in mind.
A package may import its own modules and any layer below its own; never a layer above, nor a
sibling of its own layer. A package that is in no layer fails the test until it is placed.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import mlct

SRC = Path(mlct.__file__).resolve().parent  # src/mlct

# Lowest first. A unit is a subpackage of mlct (motion) or a top-level module (errors);
# the units of one layer are siblings and do not import each other.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors",),  # MlctError and the one-line helper
    # files written atomically, device choice, the typed config, ONNX graphs written and run,
    # CUDA graphs captured and replayed
    # the package's shipped files by name
    ("io", "devices", "config", "onnx_io", "cuda_graphs", "shipped"),
    # a validated config read without pydantic (the bundled model's), latent_clamp
    ("config_view",),
    ("cpu_features",),  # what this CPU's kernels can run: the weights' precision
    ("motion",),  # skeletons, features <-> joints, BVH, rendering
    ("data",),  # the dataset layout, captions, statistics, torch datasets, the benchmark
    ("text",),  # frozen text encoders and their cache
    ("nn",),  # the networks, and building them from a config
    ("diffusion",),  # schedule, parameterization, losses, samplers as pure functions
    ("generate",),  # the inference wing: bundles, sampler objects, the pipeline, exports
    ("mlct",),  # the package root, the public API: mlct.load (generate's), __version__
    # training runs; measuring models; the HTTP API; writing the bundled model's ONNX graphs
    ("train", "eval", "serve", "onnx_assets"),
    ("cli",),  # the command line, over everything
)


# Inside generate, lowest first (docs/architecture.md, "generate"): a part imports its own
# modules and the parts below it. The core (text -> latents -> features) sits on the backends'
# networks; the composer (what generate() makes of prompts) on the core and the controls;
# load puts a backend's networks under a core under a composer.
GENERATE_LAYERS: tuple[tuple[str, ...], ...] = (
    ("output", "seeds"),  # GeneratedMotion and its writers; a seed's items and noise
    ("samplers",),  # the sampler objects and their registry
    ("bundle",),  # the bundle format
    ("backends",),  # the networks of one backend: torch, onnx/, cuda graphs; auto's choice
    ("core",),  # text -> latents -> features -> joints, one batch a call
    ("control",),  # paths, keyframes, edits, prefixes and how they are met
    ("compose",),  # the prompt composer: MotionGenerator and what it reads of a prompt
    ("files", "load"),  # `mlct generate`'s files for a request; mlct.load
)


@dataclass(frozen=True)
class Import:
    module: str  # the importing module, mlct.eval.run
    line: int
    target: str  # the imported module, mlct.generate.compose.generator


def rank(unit: str) -> int:
    return next(i for i, layer in enumerate(LAYERS) if unit in layer)


def unit_of(module: str) -> str:
    """mlct.eval.judge.evaluator -> eval; mlct.errors -> errors; mlct -> mlct."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def module_names(src: Path) -> dict[str, Path]:
    out = {}
    for path in sorted(src.rglob("*.py")):
        parts = (src.name, *path.relative_to(src).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def imports(src: Path) -> list[Import]:
    """Every import of an mlct module by an mlct module under src, resolved to the module
    (`from mlct.text import encoders` -> mlct.text.encoders; a name that is not a module ->
    the module that holds it)."""
    modules = module_names(src)
    found = []
    for module, path in modules.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: from .x import y
                    parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(parts + ([node.module] if node.module else []))
                targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                           for alias in node.names]
            else:
                continue
            for target in targets:
                while target and target not in modules:  # mlct.x.Name -> mlct.x
                    target = target.rpartition(".")[0]
                if target and target != module:
                    found.append(Import(module, node.lineno, target))
    return found


def layer_violations(src: Path) -> list[str]:
    """One line per import that points up the layers or across to a sibling."""
    out = []
    for imp in imports(src):
        here, there = unit_of(imp.module), unit_of(imp.target)
        if here != there and rank(there) >= rank(here):
            side = "a sibling of" if rank(there) == rank(here) else "above"
            out.append(f"{imp.module}:{imp.line} imports {imp.target}: {there} is {side} {here}")
    return out


def part_of(module: str) -> str | None:
    """mlct.generate.backends.onnx.networks -> backends; mlct.generate -> None."""
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[1] == "generate" else None


def generate_violations(src: Path) -> list[str]:
    """One line per import inside generate that points up GENERATE_LAYERS or across."""
    rank_of = {part: i for i, layer in enumerate(GENERATE_LAYERS) for part in layer}
    out = []
    for imp in imports(src):
        here, there = part_of(imp.module), part_of(imp.target)
        if here is None or there is None or here == there:
            continue
        if rank_of[there] >= rank_of[here]:
            side = "a sibling of" if rank_of[there] == rank_of[here] else "above"
            out.append(f"{imp.module}:{imp.line} imports {imp.target}: {there} is {side} {here}")
    return out


def import_floors(src: Path, package: str) -> int:
    """The longest chain of imports between the modules of `package` (mlct.generate): how many
    floors its modules stand on."""
    inside = [m for m in module_names(src) if m.startswith(package + ".")]
    graph: dict[str, set[str]] = {m: set() for m in inside}
    for imp in imports(src):
        if imp.module in graph and imp.target in graph:
            graph[imp.module].add(imp.target)
    floor: dict[str, int] = {}

    def height(m: str) -> int:
        if m not in floor:
            floor[m] = 1 + max((height(t) for t in graph[m]), default=0)
        return floor[m]

    return max(height(m) for m in inside)


def cycles(src: Path) -> list[list[str]]:
    """The import cycles between modules (strongly connected components of 2 or more)."""
    graph: dict[str, set[str]] = {m: set() for m in module_names(src)}
    for imp in imports(src):
        graph[imp.module].add(imp.target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(v: str) -> None:  # Tarjan
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while not component or component[-1] != v:
                component.append(stack.pop())
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_every_package_is_in_a_layer() -> None:
    placed = {unit for layer in LAYERS for unit in layer}
    units = {unit_of(m) for m in module_names(SRC)}
    assert units - placed == set(), "place the new package in LAYERS and docs/architecture.md"
    assert placed - units == set()  # and no layer names a package that is gone


def test_no_import_points_up_or_across_the_layers() -> None:
    assert layer_violations(SRC) == []


def test_no_import_cycle_between_modules() -> None:
    assert cycles(SRC) == []


def test_generate_parts_import_down_their_layers() -> None:
    placed = {part for layer in GENERATE_LAYERS for part in layer}
    parts = {part_of(m) for m in module_names(SRC)} - {None}
    assert parts == placed, "place the new part of generate in GENERATE_LAYERS"
    assert generate_violations(SRC) == []


def test_generate_stays_a_few_modules_a_folder_on_few_floors() -> None:
    """Past a dozen modules a folder wants grouping; past 8 floors the imports tangle (the flat
    generate/ of 29 modules stood on 10)."""
    per_folder: dict[Path, int] = {}
    for path in (SRC / "generate").rglob("*.py"):
        if path.name != "__init__.py":
            per_folder[path.parent] = per_folder.get(path.parent, 0) + 1
    assert max(per_folder.values()) <= 15
    assert import_floors(SRC, "mlct.generate") <= 8


def largest_classes(src: Path, count: int = 3) -> list[tuple[int, str]]:
    """The `count` longest class definitions under src, in lines, with where they are."""
    found = []
    for path in src.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                found.append((node.end_lineno - node.lineno + 1,
                              f"{path.relative_to(src)}:{node.name}"))
    return sorted(found, reverse=True)[:count]


def test_no_class_holds_two_ideas() -> None:
    """Past ~300 lines a class usually does two jobs (the generator once held the sampling core
    and the prompt composer in 719): split it, as core.py and compose/ are."""
    assert largest_classes(SRC, 1)[0][0] <= MAX_CLASS_LINES, largest_classes(SRC)


MAX_CLASS_LINES = 300


def test_the_checks_catch_an_upward_import_and_a_cycle(tmp_path: Path) -> None:
    src = tmp_path / "mlct"
    for package in ("motion", "generate"):
        (src / package).mkdir(parents=True)
        (src / package / "__init__.py").write_text("")
    (src / "__init__.py").write_text("__version__ = '0'\n")
    (src / "motion" / "a.py").write_text("def f():\n    from mlct.generate import b\n")
    (src / "generate" / "b.py").write_text("from mlct.motion.a import f\n")
    assert layer_violations(src) == [
        "mlct.motion.a:2 imports mlct.generate.b: generate is above motion"]
    assert cycles(src) == [["mlct.generate.b", "mlct.motion.a"]]
