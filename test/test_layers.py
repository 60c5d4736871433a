"""The package imports only downward: io → model → estimation → diagnosis/design →
application → report/cli → nodes, no import cycle, no private name used outside its module.

The graph is read from the source (an AST walk over every ``from .x import y``, at module
level and inside functions alike), so an import moved into a function to dodge a cycle is
still seen.  docs/architecture.md describes the layers.
"""
import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "rig_identification"

# the layer of every folder of the package (a new folder must be placed here); a module imports
# modules of its own folder or of a lower layer; within a folder, no cycle
LAYERS = {
    0: ["io"],                               # rig.yaml, recordings, bags, atomic output, result formats
    1: ["model"],                            # physics: dynamics, equilibrium, modes, effects, simulator
    2: ["estimation"],                       # tracker, preprocessor, fit, σ, errors in variables, validation
    3: ["statics", "diagnosis", "design"],   # CG from the static test; model error; experiment design
    4: ["pipeline"],                         # the offline pipeline
    5: ["report"],                           # HTML reports
    6: ["cli"],                              # rig-identify, rig-sim
    7: ["nodes"],                            # ROS 2 nodes
}
LAYER = {m: k for k, ms in LAYERS.items() for m in ms}


def module_name(path: Path) -> str:
    rel = path.relative_to(PKG).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in PKG.rglob("*.py") if module_name(p)}


def imports(name: str, path: Path, known: set[str]) -> list[tuple[str, list[str], int]]:
    """(target module, imported names, line) of every relative import of the module."""
    base = name.split(".")[:-1] if path.name != "__init__.py" else name.split(".")
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            pkg = base[:len(base) - node.level + 1]
            target = ".".join(pkg + ([node.module] if node.module else []))
            names = [a.name for a in node.names]
            if target in known:
                out.append((target, names, node.lineno))
            else:                                    # from . import module
                out += [(f"{target}.{n}".lstrip("."), [], node.lineno) for n in names
                        if f"{target}.{n}".lstrip(".") in known]
    return out


def layer(name: str) -> int:
    top = name.split(".")[0]
    if top not in LAYER:
        pytest.fail(f"rig_identification/{name.replace('.', '/')}.py has no layer: place it in test_layers.LAYERS")
    return LAYER[top]


def test_every_import_goes_downward_and_no_private_name_crosses_a_module():
    mods = modules()
    bad = []
    for name, path in mods.items():
        for target, names, line in imports(name, path, set(mods)):
            if layer(target) > layer(name):
                bad.append(f"{name}:{line} imports {target} (layer {layer(target)} above {layer(name)})")
            bad += [f"{name}:{line} uses {target}.{n}, private" for n in names if n.startswith("_")]
    assert not bad, "\n".join(bad)


def test_no_import_cycle():
    mods = modules()
    graph = {n: {t for t, _, _ in imports(n, p, set(mods))} for n, p in mods.items()}
    state, stack, cycles = {}, [], []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in graph[n]:
            if state.get(m) == 1:
                cycles.append(stack[stack.index(m):] + [m])
            elif m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in graph:
        if n not in state:
            visit(n)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


# modules allowed to import the package's own modules inside a function, and why
LAZY = {
    "cli.main": "rig-identify's sub-commands are imported when they run: --help loads no scipy",
    "cli.rig_model": "the report page (its figures, matplotlib) is imported only with --report, the static "
                     "test's saved result only with --cg",
    "statics": "its public names are imported when first used (PEP 562): reading a saved CG loads no fit",
}


def test_no_package_import_inside_a_function():
    """The package's own modules are imported at the top of a module (an import in a function
    hides the dependency, and is the usual way to dodge a cycle); only :data:`LAZY` may."""
    bad = []
    for name, path in modules().items():
        if name in LAZY:
            continue
        for f in ast.walk(ast.parse(path.read_text())):
            if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)):
                bad += [f"{name}:{n.lineno} in {f.name}()" for n in ast.walk(f)
                        if isinstance(n, ast.ImportFrom) and n.level]
    assert not bad, "package imports inside functions:\n" + "\n".join(bad)


def test_the_check_sees_an_upward_import(tmp_path):
    """The walk finds imports inside functions too (the usual way to hide a cycle)."""
    f = tmp_path / "x.py"
    f.write_text("def g():\n    from .pipeline import identify_recording\n")
    assert imports("x", f, {"pipeline"}) == [("pipeline", ["identify_recording"], 2)]
