"""The layering of the package, checked on its source (docs/architecture.md, "Layers").

Oracle: the import statements themselves, read with :mod:`ast`.  Each top-level part of
``ftnav`` sits on one layer and imports only from lower layers (or from inside itself);
no module imports itself back through others; ``import ftnav`` loads neither matplotlib
nor the CLI; and function-local imports of ftnav are allowed only where they are lazy
loading on purpose (the CLI and ``plot``).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"
PACKAGE = SRC / "ftnav"

#: Lowest first.  A part imports only parts of lower layers (same-layer parts are
#: independent of each other).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("parallel", "version"),  # standard library only; ``import ftnav`` uses both
    ("__init__", "types", "scenarios", "recordings"),
    ("core",),
    ("nav",),
    ("model",),
    ("sensors", "fdi"),
    ("sim", "recorded", "fusion"),
    ("engine",),
    ("eval",),
    ("io",),
    ("training",),
    ("pipeline", "sweep"),  # a recording's parse -> run -> score; a grid of campaigns
    ("plot", "report"),
    ("cli",),
)
LAYER = {part: i for i, parts in enumerate(LAYERS) for part in parts}
LAZY = ("cli", "plot")  # function-local imports here defer matplotlib and the trainers
#: ``ftnav.<name>`` (PEP 562 ``__getattr__``) loads these top-level names on first use;
#: ``__init__`` imports nothing else above it
EXPORTS = {"process_recording": "ftnav.pipeline", "run_scenario": "ftnav.eval.montecarlo"}


def _modules() -> dict[str, Path]:
    out = {}
    for p in PACKAGE.rglob("*.py"):
        name = ".".join(p.relative_to(SRC).with_suffix("").parts)
        out[name.removesuffix(".__init__")] = p
    return out


MODULES = _modules()


def _part(module: str) -> str:
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def _imports(module: str, path: Path) -> list[tuple[str, int, bool]]:
    """(imported ftnav module, line, inside a function) of every import in the file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    local: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            local.update(id(n) for n in ast.walk(node) if n is not node)
    out = []
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                keep = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(keep + ([base] if base else []))
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        for name in names:
            if name in MODULES and name != module:
                out.append((name, node.lineno, id(node) in local))
    return out


EDGES = {m: _imports(m, p) for m, p in MODULES.items()}


def test_every_part_has_a_layer():
    parts = {_part(m) for m in MODULES}
    assert parts - set(LAYER) == set(), "a new part of ftnav needs its place in LAYERS"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_point_down(module):
    here = _part(module)
    wrong = [
        f"{MODULES[module].relative_to(SRC)}:{line} imports {target} "
        f"(layer {LAYER[_part(target)]} '{_part(target)}' above layer {LAYER[here]} '{here}')"
        for target, line, inside in EDGES[module]
        if _part(target) != here
        and LAYER[_part(target)] >= LAYER[here]
        and not (module == "ftnav" and inside and target in EXPORTS.values())
    ]
    assert wrong == []


def test_function_local_imports_only_where_lazy():
    wrong = [
        f"{MODULES[m].relative_to(SRC)}:{line} imports {target} inside a function"
        for m, edges in EDGES.items()
        for target, line, inside in edges
        if inside and _part(m) not in LAZY and not (m == "ftnav" and target in EXPORTS.values())
    ]
    assert wrong == []


def test_no_module_loops():
    """Tarjan's strongly connected components of the module graph: all singletons."""
    graph = {
        m: {t for t, _, inside in e if not (m == "ftnav" and inside and t in EXPORTS.values())}
        for m, e in EDGES.items()
    }
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    loops: list[list[str]] = []
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph)))

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                loops.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert loops == []


def test_the_checker_sees_a_violation():
    """The layer rule is not vacuous: the engine really imports fusion and model."""
    targets = {_part(t) for m in MODULES if _part(m) == "engine" for t, _, _ in EDGES[m]}
    assert {"fusion", "model", "nav"} <= targets
    assert LAYER["engine"] < LAYER["eval"]  # so eval -> engine is down, engine -> eval would fail


def test_import_ftnav_loads_no_plotting():
    code = (
        "import sys, ftnav, ftnav.engine, ftnav.eval.montecarlo, ftnav.io.scenario_file;"
        "bad = [m for m in sys.modules if m.startswith(('matplotlib', 'ftnav.plot', 'ftnav.cli'))];"
        "print(bad); raise SystemExit(1 if bad else 0)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_top_level_exports_load_lazily():
    """``import ftnav`` stays light; ``ftnav.process_recording`` is the pipeline's, and
    ``dir(ftnav)`` (tab completion) lists the lazy names without importing them."""
    code = (
        "import sys, ftnav;"
        "shown = {'load_scenario', 'process_recording', 'run_scenario'} <= set(dir(ftnav));"
        "light = shown and 'ftnav.pipeline' not in sys.modules;"
        "from ftnav.pipeline import process_recording;"
        "from ftnav.eval.montecarlo import run_scenario;"
        "ok = ftnav.process_recording is process_recording and ftnav.run_scenario is run_scenario;"
        "raise SystemExit(0 if light and ok and set(ftnav.__all__) >= {'process_recording'} else 1)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
