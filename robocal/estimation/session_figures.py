"""Per-session figures of a fit: each session's errors after the fit, and how far its measurement frame moved
from the reference session's (docs/validation.md, "Sessions")."""
from __future__ import annotations

import numpy as np

from robocal.estimation.prediction_errors import UNITS, norm_errors, term_errors


def session_figures(problem) -> list[dict]:
    """Per session: its samples, the RMS of the error norm per block and unit (mm, mrad) at the problem's
    current values, and for a re-registered session the size of its frame correction (mm, mrad) with the
    standard errors of its components."""
    sessions = problem.sessions
    if sessions is None:
        return []
    errors = term_errors(problem)
    out = []
    for s, name in enumerate(sessions.names):
        rows = {}
        for block, e in errors.items():
            first = e.samples if e.samples.ndim == 1 else e.samples[:, 0]
            mine = sessions.of_sample[first] == s
            for kind, norms in norm_errors(e).items():
                v = norms[mine].reshape(-1)
                if len(v):
                    rows[f"{block} ({UNITS.get(kind, (1, kind))[1]})"] = float(np.sqrt(np.mean(v ** 2)))
        entry = {"session": name, "samples": int(np.sum(sessions.of_sample == s)), "rms_norm_after": rows}
        names = sessions.parameter_names(s) if sessions.corrected else []
        if names:
            p = [problem.params[n] for n in names]
            entry["frame_correction"] = {
                "translation_mm": float(1e3 * np.linalg.norm([q.value for q in p[:3]])),
                "rotation_mrad": float(1e3 * np.linalg.norm([q.value for q in p[3:]])),
                "stderr_mm": [None if q.stderr is None else 1e3 * q.stderr for q in p[:3]],
                "stderr_mrad": [None if q.stderr is None else 1e3 * q.stderr for q in p[3:]]}
        out.append(entry)
    return out


def session_lines(figures: list[dict]) -> list[str]:
    """The summary's session table."""
    if not figures:
        return []
    lines = ["", "Sessions (RMS of the error norm after the fit; the frame correction of a re-registered session "
                 "against the first, with the largest standard error of its components):"]
    for f in figures:
        rms = ", ".join(f"{k} {v:.4g}" for k, v in f["rms_norm_after"].items())
        line = f"  {f['session']:<20}{f['samples']:>5} samples   {rms}"
        c = f.get("frame_correction")
        if c:
            se_t = max((v for v in c["stderr_mm"] if v is not None), default=float("nan"))
            se_r = max((v for v in c["stderr_mrad"] if v is not None), default=float("nan"))
            line += (f"   frame moved {c['translation_mm']:.3g} mm (+- {se_t:.2g}), "
                     f"{c['rotation_mrad']:.3g} mrad (+- {se_r:.2g})")
        lines.append(line)
    return lines
