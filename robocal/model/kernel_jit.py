"""numba's jit applied in place to the functions of a kernel module (robocal.model.closure_kernels,
arrow_kernels, sensitivity_kernels): they stay plain Python, importable without numba, until the closed-chain
pass asks for the compiled path (robocal.model.closed_chain_compiled)."""
from __future__ import annotations


def jit_in_place(namespace: dict, kernels) -> None:
    """Replace each function named in `kernels` (callees first: a jitted caller needs them jitted) in the
    module `namespace` by its numba-compiled version (cache=True; numpy's error model, so 1/0 gives inf or NaN
    as the numpy path does). numba is imported here only; ImportError without it."""
    from numba import njit
    jit = njit(cache=True, error_model="numpy")
    for name in kernels:
        namespace[name] = jit(getattr(namespace[name], "py_func", namespace[name]))
