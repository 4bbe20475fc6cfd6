"""numba for robocal's optional compiled kernels (the closed-chain pass: robocal.model.closure_kernels,
arrow_kernels, sensitivity_kernels; the floating-nut FK: robocal.systems.floating_nut.fk_compiled): the kernels
stay plain Python, importable without numba, until a caller wants the compiled path."""
from __future__ import annotations

import os


def jit_in_place(namespace: dict, kernels) -> None:
    """Replace each function named in `kernels` (callees first: a jitted caller needs them jitted) in the
    module `namespace` by its numba-compiled version (cache=True, so later processes load the machine code;
    numpy's error model, so 1/0 gives inf or NaN as the numpy path does); names already compiled stay as they
    are. numba is imported here only; ImportError without it."""
    from numba import njit
    jit = njit(cache=True, error_model="numpy")
    for name in kernels:
        if not hasattr(namespace[name], "py_func"):
            namespace[name] = jit(namespace[name])


def numba_chosen(use_numba: bool | None, compile_kernels) -> bool:
    """Whether to take a compiled path: `use_numba`, or for None: the environment variable ROBOCAL_NO_NUMBA is
    unset (or 0) and `compile_kernels()` succeeds (numba imports). True compiles too (ImportError without numba)."""
    if use_numba is None:
        if os.environ.get("ROBOCAL_NO_NUMBA", "0").strip() not in ("", "0"):
            return False
        try:
            compile_kernels()
        except ImportError:
            return False
        return True
    if use_numba:
        compile_kernels()
    return bool(use_numba)
