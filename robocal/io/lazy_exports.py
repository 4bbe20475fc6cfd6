"""The public names of a subpackage, loaded on first use (PEP 562).

Subpackages import each other's modules (io.config needs estimation's options, model writes through
io.text_files), so eager imports in their `__init__` would close circles between packages; a name listed
here is imported from its module only when first asked for.
"""
from __future__ import annotations

from importlib import import_module


def lazy_exports(package: str, modules: dict[str, str]):
    """(`__getattr__`, `__all__`) for `package` from {module (relative to it): "Name name ..."}."""
    where = {name: f"{package}.{module}" for module, names in modules.items() for name in names.split()}

    def __getattr__(name):
        if name in where:
            return getattr(import_module(where[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    return __getattr__, sorted(where)
