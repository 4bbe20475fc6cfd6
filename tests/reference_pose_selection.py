"""Plain reference of `robocal.design.selection.select_poses` (greedy start + exchange): every candidate's
criterion from the eigenvalues (or the solve, for I) of its own information matrix, no bounds, no block
updates. Kept only to check the fast search chooses the same poses (tests/test_pose_selection_reference.py)."""
import numpy as np

from robocal.design import criteria as dc
from robocal.design.selection import FULL_RANK, RIDGE


def best_candidate(design, criterion, M, m, W, candidates):
    """(index, value) of the best candidate to add to M, first maximum (lowest index) on ties."""
    best_k, best = -1, -np.inf
    for k in candidates:
        B = design.blocks[k]
        value = dc.evaluate(criterion, M + B.T @ B, m + design.rows[k], W)
        if value > best:
            best_k, best = int(k), value
    return best_k, best


def reference_select(design, n, criterion, W=None, max_sweeps=50, rtol=1e-9):
    """Chosen candidate indices, in selection order."""
    Ws = design.scaled_weight(W) if W is not None else None
    ridge = RIDGE * np.eye(len(design.base.independent))
    chosen, M, full_rank = [], design.information([]), False
    for _ in range(n):
        free = [k for k in range(design.n_candidates) if k not in chosen]
        k, _ = best_candidate(design, criterion if full_rank else "D", M + ridge, design.n_rows(chosen), Ws, free)
        chosen.append(k)
        M = design.information(chosen)
        lam = np.linalg.eigvalsh(M)
        full_rank = full_rank or (lam[-1] > 0 and lam[0] > FULL_RANK * lam[-1])
    current = dc.evaluate(criterion, design.information(chosen) + ridge, design.n_rows(chosen), Ws)
    for _ in range(max_sweeps):
        improved = False
        for pos in range(n):
            rest = chosen[:pos] + chosen[pos + 1:]
            outside = [k for k in range(design.n_candidates) if k not in chosen]
            k, value = best_candidate(design, criterion, design.information(rest) + ridge, design.n_rows(rest),
                                      Ws, outside)
            if value > current + rtol * abs(current) + 1e-300:
                chosen[pos], current, improved = k, value, True
        if not improved:
            break
    return np.array(chosen)
