"""The package's shape, as docs/architecture.md states it: checked on the source text (ast), nothing runs.

One test per rule; each names every offending file, so a change that breaks one says where.
"""
import ast
import importlib.util
from collections import defaultdict
from pathlib import Path


PACKAGE = Path(__file__).resolve().parents[1] / "robocal"
MAX_TOP_LEVEL = 13
#: the subpackages from the bottom of the flow to the top: a module may import its own package and those
#: below it, never one above (imports inside functions count too); cli and testing are peers at the top
LAYERS = ("errors", "io", "model", "residuals", "estimation", "design", "dynamics", "viz", "systems", "workflows",
          ("cli", "testing"))
#: where YAML is parsed: the file reader, and the workflows that turn configs into typed objects
YAML_READERS = ("robocal.io.yaml_files", "robocal.workflows")
MAX_LINES = 400
# imported inside functions on purpose: optional extras ([viz], [fast], [fleet], [test]) and the pages
# built on them, so a core install imports without them; and heavy libraries of one CLI command
OPTIONAL = ("numba", "meshcat", "matplotlib", "dask", "distributed", "pyarrow", "hypothesis", "cv2",
            "robocal.viz.meshcat_check", "robocal.viz.report", "robocal.viz.plots", "robocal.viz.fleet_plots",
            "robocal.workflows.fleet",
            # the dynamics stack (scipy.signal, scipy.stats) only for `robocal identify`: CLI start-up
            "robocal.workflows.identify_outputs", "robocal.workflows.identify", "robocal.workflows.identify_evaluate",
            # scipy.optimize (0.1-0.15 s with scipy.sparse, special, fft, spatial): only the camera's initial pose
            # (least_squares) and the laser/PSD set-up search use it, not the start-up of every command
            "scipy.optimize")


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


def test_top_level_holds_at_most_thirteen_entries():
    entries = [p.name for p in PACKAGE.iterdir() if p.name != "__pycache__" and not p.name.startswith(".")]
    assert len(entries) <= MAX_TOP_LEVEL, sorted(entries)


def test_no_module_over_400_lines():
    long = {str(path): n for path in MODULES.values()
            if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not long, long


def layer(module: str) -> int | None:
    """The rank of a robocal module's subpackage in LAYERS (None for the package root, robocal/__init__)."""
    parts = module.split(".")
    if len(parts) < 2:
        return None
    for rank, names in enumerate(LAYERS):
        if parts[1] in ((names,) if isinstance(names, str) else names):
            return rank
    raise AssertionError(f"{module}: its subpackage is not in LAYERS (add it where it belongs in the flow)")


def test_imports_run_one_way_between_packages():
    bad = []
    for me, path in MODULES.items():
        mine = layer(me)
        if mine is None:
            continue      # robocal/__init__: the public names, gathered from every layer
        for node, mod, _, _ in imports(path):
            if mod.startswith("robocal.") and mod.split(".")[1] != me.split(".")[1]:
                theirs = layer(mod)
                if theirs is not None and theirs >= mine:
                    bad.append(f"{path}:{node.lineno}: {me.split('.')[1]} imports {mod}")
    assert not bad, "imports against the order " + " <- ".join(map(str, LAYERS)) + ":\n" + "\n".join(bad)


#: the only __init__s that defer their names (PEP 562 __getattr__, from an explicit table): robocal.viz the
#: names that need the optional [viz] extra; the root, which Python runs before any module of robocal (the
#: `robocal` command's too), so that no command and no `import robocal.io.tables` imports the whole library
DEFERRING = ("robocal", "robocal.viz")
#: the only modules that import by name (importlib.import_module): those __init__s, and the command line,
#: which imports the module of the command asked for (robocal/cli/main.py: start-up of every command)
IMPORT_BY_NAME = DEFERRING + ("robocal.cli.main",)


def test_subpackages_export_names_by_explicit_imports():
    """No lazy-export helper: an __init__ imports what it exports; only DEFERRING ones defer."""
    bad = [str(path) for name, path in MODULES.items() if path.name == "__init__.py" and name not in DEFERRING
           and "__getattr__" in path.read_text(encoding="utf-8")]
    assert not bad, bad


def test_modules_are_imported_by_name_only_where_allowed():
    bad = [str(path) for name, path in MODULES.items() if name not in IMPORT_BY_NAME
           and any(s in path.read_text(encoding="utf-8") for s in ("import_module", "__import__("))]
    assert not bad, bad


def test_yaml_is_parsed_only_where_configs_are_read():
    bad = [str(path) for name, path in MODULES.items() if not name.startswith(YAML_READERS)
           and any(s in path.read_text(encoding="utf-8") for s in ("yaml.safe_load(", "yaml.load(", "read_yaml("))]
    assert not bad, bad


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


def test_architecture_page_lists_every_module_as_its_docstring_says():
    spec = importlib.util.spec_from_file_location("architecture_table", PACKAGE.parent / "scripts" / "architecture_table.py")
    table = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(table)
    assert table.PAGE.read_text(encoding="utf-8") == table.current_page(), \
        "docs/architecture.md's module table is stale: run python3 scripts/architecture_table.py"
