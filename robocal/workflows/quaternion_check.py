"""Quaternion order of pose blocks: robocal reads x, y, z, w (scalar last); a file written scalar first (w, x,
y, z, as many trackers and Eigen's coefficient lists do) is detected before any fit.

The test asks which reading makes the measured rotations consistent with the nominal model. Reading the
four columns in another order is not a rotation of the data (the angle between two postures, |q_a . q_b|,
is the same under any order) but, up to fixed rotations, reads each rotation's inverse. So the test looks at
the axis of the rotation between consecutive sampled postures, expressed in the tool: log(R_a^T R_b). Under
the right reading the measured one is the model's turned by the fixed, unknown tool rotation T,
(B R_a T)^T (B R_b T) = T^T (R_a^T R_b) T, whatever the measurement frame B; a rotation fitted between
the two sets of rotation vectors (Kabsch) leaves milliradians, the model's error. Under a wrong reading the
measured ones follow the world-frame axes R_a R_b^T instead, which no fixed rotation maps onto the tool's:
radians are left. Rule (docs/config.md, "Bad input"): when the declared reading leaves more than MISMATCH
(RMS) and the scalar-first reading at least BETTER times less, the block is refused with the column order
that reads it right.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.model.lie_arrays import log3, quaternion_matrices
from robocal.workflows.data_check import MAX_SAMPLES

#: RMS disagreement (rad) of the rotations between postures beyond which a reading is wrong: a nominal model
#: off by milliradians stays well below it; a wrong quaternion order leaves about a radian
MISMATCH = 0.1
#: how much closer the scalar-first reading must agree to be named
BETTER = 10.0
#: the file's columns, in robocal's x, y, z, w order, if they hold w, x, y, z
SCALAR_FIRST = [4, 5, 6, 3]


def pair_rotations(R: np.ndarray) -> np.ndarray:
    """(n - 1, 3) rotation vectors of R[k]^T R[k + 1] (the rotation between consecutive postures, in the tool)."""
    return log3(np.einsum("kji,kjl->kil", R[:-1], R[1:]))[0]


def mismatch(quaternions: np.ndarray, model: np.ndarray) -> float:
    """RMS (rad) left between the measured rotations between postures and the model's (pair_rotations) once
    the best fixed rotation maps the model's onto the measured ones."""
    q = quaternions / np.linalg.norm(quaternions, axis=1, keepdims=True)
    measured = pair_rotations(quaternion_matrices(q))
    u, _, vt = np.linalg.svd(model.T @ measured)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    A = (u @ np.diag([1.0, 1.0, d]) @ vt).T          # measured ~ A model, A a rotation
    return float(np.sqrt(np.mean(np.sum((model @ A.T - measured) ** 2, axis=1))))


def quaternion_findings(setup, states) -> list[InputError]:
    """One InputError per pose block whose quaternions read right only scalar first."""
    findings = []
    for block, res in zip(setup.config.measurements, setup.problem.residuals):
        if res.type_name != "pose" or res.n_terms < 3:
            continue
        terms = np.unique(np.linspace(0, res.n_terms - 1, min(res.n_terms, MAX_SAMPLES)).astype(int))
        model = pair_rotations(np.array([states[int(res.samples[k])].pose(res.frame).rotation for k in terms]))
        raw = res.measurements[terms]
        declared, scalar_first = mismatch(raw[:, 3:7], model), mismatch(raw[:, SCALAR_FIRST], model)
        if declared <= MISMATCH or scalar_first * BETTER > declared:
            continue
        cols = list(res.columns)
        fixed = cols[:3] + [cols[i] for i in SCALAR_FIRST]
        findings.append(InputError(
            f"block '{res.name}': the quaternion columns {', '.join(cols[3:])} look scalar first (w, x, y, z): read "
            f"so, the rotations between postures agree with the nominal model's to {scalar_first * 1e3:.3g} mrad "
            f"RMS, read as robocal reads them (x, y, z, w: scalar last) they differ by {declared:.3g} rad; list the "
            f"columns scalar last: columns: [{', '.join(fixed)}]", source=setup.source, field=f"{block.path}.columns"))
    return findings
