"""The package's shape: imports run one way, from the ground floor up, with no cycle, every
third-party module the code imports is a declared dependency (a fresh install has nothing else), and
imports sit at the top of their module but for the few that have a measured reason to wait."""
import ast
import re
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "twin"

# the layout of docs/method/architecture.md, floor by floor: a module may import from its own floor or below
FLOORS = {
    0: ("errors", "files", "geodesy", "references", "progress", "threads"),
    1: ("physics",),
    2: ("vessel", "recording", "run", "drive", "effects"),
    3: ("formats",),
    4: ("engine", "analytic", "prepare"),
    5: ("fit", "verify", "replay", "viz", "outputs", "simulation"),
    6: ("ident", "synth", "sitl"),
    7: ("diagnose",),
    8: ("api", "__init__", "scale"),
    9: ("cli", "__main__"),
}
FLOOR_OF = {name: floor for floor, names in FLOORS.items() for name in names}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules=frozenset()) -> list[str]:
    """Every module a file imports, at the top or inside a function, as absolute names; for
    `from pkg import x` the submodule pkg.x where `modules` knows it, else pkg."""
    tree = ast.parse(path.read_text())
    here = _module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            subs = [f"{module}.{a.name}" for a in node.names if f"{module}.{a.name}" in modules]
            out += subs if len(subs) == len(node.names) else [module] + subs
    return out


def _graph() -> dict[str, set[str]]:
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    return {name: {m for m in _imports(path, frozenset(modules)) if m in modules and m != name}
            for name, path in modules.items()}


def _floor(module: str) -> int:
    parts = module.split(".")
    key = parts[1] if len(parts) > 1 else "__init__"
    if key not in FLOOR_OF:
        pytest.fail(f"{module}: its folder or file '{key}' is not on a floor of the layout (docs/method/architecture.md)")
    return FLOOR_OF[key]


def test_no_module_imports_from_a_floor_above():
    wrong = [f"{m} (floor {_floor(m)}) imports {d} (floor {_floor(d)})"
             for m, deps in _graph().items() for d in deps if _floor(d) > _floor(m)]
    assert not wrong, "\n".join(wrong)



# the modules that word results for a reader (text, HTML, plots); what computes them must not need them
PRESENTATION = {"twin.diagnose.report"}


def test_analysis_does_not_import_its_presentation():
    graph = _graph()
    wrong = [f"{m} imports {d}" for m, deps in graph.items() if m.startswith("twin.diagnose.")
             and m not in PRESENTATION for d in deps & PRESENTATION]
    assert not wrong, "\n".join(wrong)

def test_no_import_cycle():
    graph = _graph()
    # a package's __init__ imports its own modules by design; a cycle through it is still a cycle
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(graph[m]):
            if state.get(d) == "open":
                cycles.append(" -> ".join(stack[stack.index(d):] + [d]))
            elif d not in state:
                visit(d)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m)
    cycles = [c for c in cycles if not _parent_init_only(c)]
    assert not cycles, "\n".join(cycles)


def _parent_init_only(cycle: str) -> bool:
    """`pkg` (its __init__) importing `pkg.mod` that imports `pkg` by a relative `from . import x`:
    Python resolves the submodule, not the package body, so only a cycle between modules counts."""
    names = cycle.split(" -> ")
    return any(b.startswith(a + ".") for a, b in zip(names, names[1:])) and len(set(names)) == 2


def _declared() -> set[str]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    requirements = project["dependencies"] + sum(project.get("optional-dependencies", {}).values(), [])
    dists = {re.split(r"[<>=!~\[; ]", r, maxsplit=1)[0].strip().lower().replace("_", "-") for r in requirements}
    # a declared distribution that is not installed here (an optional extra) still declares the
    # module of its own name: the check must not depend on which extras this machine installed
    modules = {d.replace("-", "_") for d in dists}
    for module, owners in metadata.packages_distributions().items():
        if any(o.lower().replace("_", "-") in dists for o in owners):
            modules.add(module)
    return modules


@pytest.mark.parametrize("folder", ["twin", "tests", "scripts"])
def test_every_imported_module_is_declared(folder):
    declared = _declared()
    missing = {}
    for path in (ROOT / folder).rglob("*.py"):
        for name in _imports(path):
            top = name.split(".")[0]
            if not top or top in sys.stdlib_module_names or top in ("twin", "tests", "__future__"):
                continue
            if top not in declared and top not in {p.stem for p in (ROOT / folder).glob("*.py")}:
                missing.setdefault(top, str(path.relative_to(ROOT)))
    assert not missing, f"imported but not declared in pyproject.toml: {missing}"


# What a function of twin/ may import inside its body (outside twin/cli/, whose commands import their
# stack when they run): each module, with its submodules, for the reason measured (a cost is the
# import's time on top of what the importing module already loads); anything else goes at the top.
LATE_IMPORTS = {
    "ray": "the cluster extra (pyproject.toml), not installed by default",
    "matplotlib": "pyplot 0.25-0.3 s on top of its importers (twin.api too), only for a PNG or an HTML report",
    "rerun": "0.3 s on top of twin.api, only for an .rrd output",
    "trimesh": "0.12 s on top of twin.verify.validate (0.05 s on twin.api), only where hull meshes are read",
    "scipy.signal": "0.3 s on top of twin.prepare, twin.fit.windows (twin montecarlo), only to smooth, filter a lag",
    "pymavlink.mavutil": "sets MAVLINK_DIALECT in os.environ on import, which a SITL started before would inherit",
    "pymavlink.DFReader": "imports pymavlink.mavutil (above), only to read a DataFlash .bin",
    "twin.api": "twin/__init__.py loads it on first use: `import twin` 0.03 s, not 1.6 s",
    "twin.cli": "twin/__main__.py: a Ctrl-C while the command's libraries load ends in one line, not a traceback",
    "twin.engine.sim": "mujoco into twin.ident.relay, which `twin --help` loads: 0.2 s more at every command's start",
    "twin.engine.mjcf": "as twin.engine.sim",
    "twin.viz.rerun_log": "rerun, 0.25 s on top of twin.outputs and twin.scale.views, only for an .rrd",
    "twin.outputs": "the recording writers, 0.1 s on top of twin.simulation, only for Simulation.write",
    "twin.ident.identify": "0.44 s (the fitting stack) on top of twin.scale.montecarlo, only for evaluate --band",
}


def _late_imports(path: Path) -> list[tuple[int, list[list[str]]]]:
    """(line, modules) of every import inside a function of the file: for `import m` the module m;
    for `from m import a, b` each name as m.a or m (whichever an entry covers), absolute."""
    here = _module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    out = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit(child, True)
            elif isinstance(child, ast.Import) and in_function:
                out.append((child.lineno, [[a.name] for a in child.names]))
            elif isinstance(child, ast.ImportFrom) and in_function:
                base = package[: len(package) - child.level + 1] if child.level else []
                module = ".".join(base + ([child.module] if child.module else []))
                out.append((child.lineno, [[f"{module}.{a.name}", module] for a in child.names]))
            else:
                visit(child, in_function)

    visit(ast.parse(path.read_text()), False)
    return out


def _allowed(name: str) -> str | None:
    return next((key for key in LATE_IMPORTS if name == key or name.startswith(key + ".")), None)


def test_imports_are_at_the_top_but_for_the_late_imports_allowed():
    wrong, used = [], set()
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).parts[0] == "cli":
            continue
        for line, names in _late_imports(path):
            for forms in names:
                key = next((k for k in map(_allowed, forms) if k), None)
                if key is None:
                    wrong.append(f"{path.relative_to(ROOT)}:{line}: {forms[-1]} imported inside a function: "
                                 f"at the top, or in LATE_IMPORTS with its measured reason")
                used.add(key)
    assert not wrong, "\n".join(wrong)
    stale = sorted(set(LATE_IMPORTS) - used)
    assert not stale, f"in LATE_IMPORTS but imported inside no function: {stale}"
