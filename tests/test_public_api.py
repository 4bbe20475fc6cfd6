"""The curated public API: every exported name resolves, and docs/api.md lists every one."""
import importlib
import re
from pathlib import Path

import pytest

PACKAGES = ["robocal", "robocal.model", "robocal.residuals", "robocal.estimation", "robocal.workflows.fleet",
            "robocal.design", "robocal.io", "robocal.workflows",
            "robocal.systems.stewart", "robocal.systems.laser_psd", "robocal.systems.floating_nut",
            "robocal.systems.pcmm", "robocal.dynamics", "robocal.viz", "robocal.testing"]
API_PAGE = (Path(__file__).resolve().parents[1] / "docs" / "api.md").read_text(encoding="utf-8")


def section(package: str) -> str:
    return API_PAGE.split(f"## `{package}`", 1)[1].split("\n## ", 1)[0]


@pytest.mark.parametrize("package", PACKAGES)
def test_every_exported_name_resolves_and_is_documented(package):
    module = importlib.import_module(package)
    missing = [name for name in module.__all__ if f"| `{name}` |" not in section(package)]
    assert not missing, f"docs/api.md, section {package}, does not list {missing}"
    for name in module.__all__:
        assert getattr(module, name) is not None


@pytest.mark.parametrize("package", PACKAGES)
def test_every_listed_name_exists(package):
    module = importlib.import_module(package)
    listed = re.findall(r"^\| `(\w+)` \|", section(package), re.M)
    assert listed, f"docs/api.md has no table for {package}"
    unknown = [name for name in listed if name not in module.__all__]
    assert not unknown, f"docs/api.md, section {package}, lists names {package} does not export: {unknown}"


def test_every_command_has_its_python_equivalent():
    from robocal.cli.main import build_parser
    commands = build_parser()._subparsers._group_actions[0].choices
    table = API_PAGE.split("## Commands and their Python equivalents", 1)[1].split("\n## ", 1)[0]
    missing = [c for c in commands if f"`robocal {c}" not in table]
    assert not missing, f"docs/api.md's command table misses {missing}"


def test_unknown_names_raise_attribute_error():
    import robocal.model
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        robocal.model.nope   # noqa: B018


def test_readme_and_examples_import_only_public_names():
    """README and examples import from the public packages only (`from robocal.model import Robot`), or take a
    documented module whole (`from robocal.systems.stewart import modes as sm`)."""
    root = Path(__file__).resolve().parents[1]
    texts = [root / "README.md", *sorted((root / "examples").rglob("*.py"))]
    deep = re.compile(r"^\s*from (robocal(?:\.\w+)+) import", re.M)
    public = set(PACKAGES)
    bad = [f"{p.relative_to(root)}: {m}" for p in texts for m in deep.findall(p.read_text(encoding="utf-8"))
           if m not in public]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("package", [p for p in PACKAGES if p != "robocal"])
def test_no_exported_name_is_also_a_submodule(package):
    """A submodule of the same name would shadow a lazily exported name once imported."""
    import pkgutil
    module = importlib.import_module(package)
    submodules = {m.name for m in pkgutil.iter_modules(module.__path__)}
    assert not submodules & set(module.__all__)
