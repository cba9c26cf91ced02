"""The package's layout (docs/development.md, "Layout"): each package imports only itself and the packages listed
below it, and no module imports itself back through others at import time (no import circles).  Read from the
source with :mod:`ast`, imports inside functions included for the layers (a lazy import is still a dependency)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

# top to bottom: a package may import the packages after it, never those before it
LAYERS = [
    ["<entry points>"],          # predict.py export.py collect.py datasets.py: `python -m inbetweening.<name>`
    ["blender"],
    ["retarget"],                # the retargeting task, its command line included
    ["cli"],
    ["api"],
    ["training"],
    ["rendering"],
    ["dcc"],                     # the host-independent part of a DCC front end (Blender's, a Maya one's)
    ["runtime"],
    ["predictor"],
    ["evaluation"],
    ["models"],
    ["representation"],
    ["data"],
    ["atomic"],
    ["geometry"],
]
RANK = {name: i for i, names in enumerate(LAYERS) for name in names}
ENTRY_POINTS = {"predict", "export", "collect", "datasets"}


def modules() -> dict[str, Path]:
    found = {}
    for f in sorted((SRC / "inbetweening").rglob("*.py")):
        parts = list(f.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = f
    return found


def imports(name: str, file: Path, top_level_only: bool) -> set[str]:
    """The ``inbetweening`` modules ``name`` imports (relative imports resolved)."""
    tree = ast.parse(file.read_text(), str(file))
    package = name if file.name == "__init__.py" else name.rsplit(".", 1)[0]
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    if top_level_only:  # also those under a module-level `if` / `try` (not inside functions)
        todo, nodes = list(tree.body), []
        while todo:
            n = todo.pop()
            nodes.append(n)
            if isinstance(n, (ast.If, ast.Try)):
                todo += [*n.body, *getattr(n, "orelse", []), *getattr(n, "finalbody", []),
                         *(s for h in getattr(n, "handlers", []) for s in h.body)]
    out = set()
    for n in nodes:
        if isinstance(n, ast.Import):
            out |= {a.name for a in n.names}
        elif isinstance(n, ast.ImportFrom):
            if n.level:
                base = package.split(".")[: len(package.split(".")) - (n.level - 1)]
                target = ".".join(base + ([n.module] if n.module else []))
                out.add(target)
                out |= {f"{target}.{a.name}" for a in n.names}  # `from . import x`: the module x
            else:
                out.add(n.module)
                out |= {f"{n.module}.{a.name}" for a in n.names}
    return {t for t in out if t and t.split(".")[0] == "inbetweening"}


def layer(module: str) -> str:
    parts = module.split(".")
    if len(parts) == 1:
        return "<package>"
    return "<entry points>" if parts[1] in ENTRY_POINTS else parts[1]


def test_every_package_has_a_layer():
    missing = {layer(m) for m in modules()} - set(RANK) - {"<package>"}
    assert not missing, f"packages without a place in LAYERS (and docs/development.md): {sorted(missing)}"


def test_no_upward_imports():
    mods = modules()
    upward = []
    for name, file in mods.items():
        a = layer(name)
        if a == "<package>":
            continue
        for target in imports(name, file, top_level_only=False):
            b = layer(target)
            if b != "<package>" and target in mods and RANK[b] < RANK[a]:
                upward.append(f"{name} imports {target} ({a} -> {b})")
    assert not upward, "\n".join(upward)


def test_no_import_circles():
    mods = modules()
    graph = {m: {t for t in imports(m, f, top_level_only=True) if t in mods and t != m} for m, f in mods.items()}
    # a package's __init__ imported by its own modules is Python's normal order, not a circle
    for m in graph:
        graph[m] = {t for t in graph[m] if not m.startswith(t + ".")}
    state: dict[str, int] = {}
    circles = []

    def visit(m: str, path: list[str]):
        state[m] = 1
        for t in sorted(graph[m]):
            if state.get(t) == 1:
                circles.append(" -> ".join(path[path.index(t):] + [t]) if t in path else f"{m} -> {t}")
            elif t not in state:
                visit(t, [*path, t])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not circles, "\n".join(circles)


@pytest.mark.parametrize("source, expected", [
    ("from .rig import TargetRig\n", {"inbetweening.retarget.rig", "inbetweening.retarget.rig.TargetRig"}),
    ("from .. import runtime\n", {"inbetweening", "inbetweening.runtime"}),
    ("def f():\n    import inbetweening.training.train\n", set()),
])
def test_imports_are_read_as_python_resolves_them(tmp_path, source, expected):
    f = tmp_path / "task.py"
    f.write_text(source)
    assert imports("inbetweening.retarget.task", f, top_level_only=True) == expected


def test_the_layout_doc_names_every_package_and_module():
    """docs/development.md's Layout lists every package and every module (by file name) of src/inbetweening."""
    doc = (SRC.parent / "docs" / "development.md").read_text()
    layout = doc[doc.index("## Layout"):doc.index("## Extending")]
    missing = []
    for file in modules().values():
        if file.name == "__init__.py":
            if f"{file.parent.name}/" not in layout:
                missing.append(f"package {file.parent.name}/")
        elif file.name not in layout:
            missing.append(str(file.relative_to(SRC)))
    assert not missing, f"docs/development.md's Layout does not name: {missing}"


def test_the_code_passes_the_linter():
    """``ruff check`` (configured in pyproject.toml; a dev dependency) finds nothing in the package, the tests and the
    benchmarks: a newcomer's change is held to the same rules."""
    import subprocess
    import sys

    pytest.importorskip("ruff")
    root = SRC.parent
    out = subprocess.run([sys.executable, "-m", "ruff", "check", "--quiet", "src", "tests", "benchmarks"], cwd=root,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, (out.stdout + out.stderr)[-3000:]
