"""The package's shape, as docs/architecture.md states it: checked on the source text (ast), nothing runs.

Each rule names the offending file, so a change that breaks one says where.
"""
import ast
from collections import defaultdict
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "robocal"
MAX_TOP_LEVEL = 12
MAX_LINES = 400
# imported inside functions on purpose: optional extras ([viz], [fast], [fleet], [test]) and the pages
# built on them, so a core install imports without them; and heavy libraries of one CLI command
OPTIONAL = ("numba", "meshcat", "matplotlib", "dask", "distributed", "pyarrow", "hypothesis",
            "robocal.viz.meshcat_check", "robocal.viz.report", "robocal.viz.plots", "robocal.viz.fleet_plots",
            "robocal.estimation.fleet",
            # the dynamics stack (scipy.signal, scipy.stats) only for `robocal identify`: CLI start-up
            "robocal.dynamics.identify_report", "robocal.dynamics.identify_run")


def modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


MODULES = modules()


def imports(path: Path):
    """(node, absolute module, imported names, inside a function) of every import of a robocal module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    in_function = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            in_function |= {id(sub) for sub in ast.walk(node)}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            yield node, node.module, [a.name for a in node.names], id(node) in in_function
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield node, a.name, [], id(node) in in_function


def test_top_level_holds_at_most_twelve_entries():
    entries = [p.name for p in PACKAGE.iterdir() if p.name != "__pycache__" and not p.name.startswith(".")]
    assert len(entries) <= MAX_TOP_LEVEL, sorted(entries)


@pytest.mark.parametrize("name", sorted(MODULES))
def test_module_is_at_most_400_lines(name):
    n = len(MODULES[name].read_text(encoding="utf-8").splitlines())
    assert n <= MAX_LINES, f"{MODULES[name]}: {n} lines"


def test_no_private_name_crosses_a_module_boundary():
    bad = [f"{path}:{node.lineno}: {mod}.{name}" for me, path in MODULES.items()
           for node, mod, names, _ in imports(path) if mod.startswith("robocal") and mod != me
           for name in names if name.startswith("_")]
    assert not bad, "\n".join(bad)


def test_function_level_imports_only_for_optional_dependencies():
    bad = [f"{path}:{node.lineno}: {mod}" for path in MODULES.values()
           for node, mod, _, inside in imports(path) if inside and not mod.startswith(OPTIONAL)]
    assert not bad, "\n".join(bad)


def test_no_import_circle():
    graph = defaultdict(set)
    for me, path in MODULES.items():
        for _, mod, names, _ in imports(path):
            if not mod.startswith("robocal"):
                continue
            for target in [f"{mod}.{n}" for n in names if f"{mod}.{n}" in MODULES] or [mod]:
                if target in MODULES and target != me and not me.startswith(target + "."):
                    graph[me].add(target)   # a package's own __init__ is imported first anyway
    colour, stack = {}, []

    def visit(node):
        colour[node] = "grey"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if colour.get(nxt) == "grey":
                raise AssertionError("import circle: " + " -> ".join(stack[stack.index(nxt):] + [nxt]))
            if nxt not in colour:
                visit(nxt)
        stack.pop()
        colour[node] = "black"

    for node in sorted(MODULES):
        if node not in colour:
            visit(node)


def test_only_the_command_line_prints():
    bad = []
    for name, path in MODULES.items():
        if name.startswith("robocal.cli"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "print":
                bad.append(f"{path}:{node.lineno}")
    assert not bad, "print() outside robocal/cli: " + ", ".join(bad)


def test_docstrings_cite_docs_pages_not_source_document_clauses():
    bad = [f"{path}" for path in MODULES.values()
           if "seed-00" in path.read_text(encoding="utf-8") or "seed 00" in path.read_text(encoding="utf-8")]
    assert not bad, "cite docs/<page>.md instead of the source documents' clause numbers: " + ", ".join(bad)


def test_architecture_page_lists_every_module():
    page = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    tables = page.split("## Every module", 1)[1]
    missing = []
    for path in PACKAGE.rglob("*.py"):
        folder = "/".join(path.relative_to(PACKAGE).parent.parts)
        section = tables.split(f"**`robocal/{folder + '/' if folder else ''}`**", 1)
        if len(section) < 2 or f"| `{path.name}` |" not in section[1].split("**`robocal/", 1)[0]:
            missing.append(str(path.relative_to(PACKAGE)))
    assert not missing, "docs/architecture.md's module table misses " + ", ".join(sorted(missing))
