"""The plain per-sample evaluation, kept as the reference the batched path is compared with.

This is Problem.evaluate as it was before the batched path (tests/test_batched_evaluation.py): one
SampleState per sample, one Term per measurement, Jacobian rows stacked with vstack; a session's measurement-frame
correction enters its six columns through the same formula as the per-sample path of Problem.evaluate.
"""
import numpy as np

from robocal.estimation.problem import Evaluation
from robocal.estimation.sessions import correction_jacobian, exp_jacobians
from robocal.residuals.prior import prior_rows


def reference_evaluate(problem, jacobian: bool = True) -> Evaluation:
    problem.blocks = problem.layout()
    states = problem.states()
    col = problem.params.column_map()
    n_free = len(problem.params.free_names)
    # each session's measurement-frame correction: its six columns, as the problem names them
    session_cols = problem.session_columns(col)
    Jexp = exp_jacobians(problem.sessions, problem.params) if session_cols else None
    rs, raws, Js, groups = [], [], [], []
    gid = 0
    for res in problem.residuals:
        scale = res.row_scale()
        keep = scale != 0
        aux_names = [p.name for p in res.aux_parameters()]
        aux = np.array([problem.params[n].value for n in aux_names])
        aux_cols = [(j, c, w) for j, n in enumerate(aux_names) for c, w in col.get(n, [])]
        for k in range(res.n_terms):
            t = res.evaluate(k, states, aux)
            raws.append(t.r[keep])
            rs.append((t.r * scale)[keep])
            groups.append(np.full(int(keep.sum()), gid))
            gid += 1
            if jacobian:
                Jt = np.zeros((res.dim, n_free))
                for i, frame, D in t.frames:
                    Jt += D @ states[i].frame_parameter_jacobian(frame)
                    if session_cols:
                        s = int(problem.sessions.of_sample[i])
                        cj = correction_jacobian(D, states.raw[i].pose(frame), Jexp[s])
                        for comp, pairs in enumerate(session_cols[s]):
                            for c, w in pairs:
                                Jt[:, c] += w * cj[:, comp]
                for j, c, w in aux_cols:
                    Jt[:, c] += w * t.aux[:, j]
                Js.append((Jt * scale[:, None])[keep])
    pr, pJ, _ = prior_rows(problem.params)
    if len(pr):
        rs.append(pr)
        raws.append(pr)
        groups.append(np.arange(gid, gid + len(pr)))
        if jacobian:
            Js.append(pJ)
    r = np.concatenate(rs) if rs else np.zeros(0)
    J = (np.vstack(Js) if Js else np.zeros((0, n_free))) if jacobian else None
    return Evaluation(r, J, np.concatenate(raws) if raws else np.zeros(0),
                      np.concatenate(groups) if groups else np.zeros(0, int))
