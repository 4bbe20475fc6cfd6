"""CalibrationResult: estimates, uncertainties, identifiability and fit statistics, as data and as text.

The library never prints; `summary()` returns the text that the CLI shows.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from robocal.estimation.identifiability import BaseSelection
from robocal.model.parameters import ParameterSet
from robocal.estimation.result_text import (FINDING_RULE, identifiability_dict, identifiability_statements,
                                            summary_text)
from robocal.estimation.solve import SolveResult

SHOWN = 6           # names shown per list on the terminal (summary.txt and result.json: all)
UNIT_SCALE = {"length": (1e3, "mm"), "angle": (1e3, "mrad"), "pixel": (1.0, "px"), "prior": (1.0, "sigma")}


NORM_LABEL = {"length": "3D position error", "angle": "3D orientation error", "pixel": "2D reprojection error"}
GROUP = {"pixel": 2}     # rows of one error vector per kind (a pixel has two; points and rotations three)


@dataclass
class BlockStats:
    """One measurement block's errors in report units (mm, mrad).

    norm_rms / norm_max: RMS and maximum of the error norm per unit kind: the 3D norm of each point
    (each triple of length rows of a term) or orientation (each triple of angle rows), else |row|;
    norm_label says which. rms / max: per component (per row), kept for comparison, labelled so."""

    name: str
    type_name: str
    rows: int
    rms: dict[str, float]
    max: dict[str, float]
    norm_rms: dict[str, float] = field(default_factory=dict)
    norm_max: dict[str, float] = field(default_factory=dict)
    norm_label: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"name": self.name, "type": self.type_name, "rows": self.rows,
                "rms_norm": self.norm_rms, "max_norm": self.norm_max, "norm_of": self.norm_label,
                "rms_per_component": self.rms, "max_per_component": self.max}

    def headline(self, which: str = "rms") -> str:
        """'1.43 mm (max 3.2)' per unit kind, for the norm figures."""
        return ", ".join(f"{v:.4g} {u} (max {self.norm_max[u]:.4g})" for u, v in self.norm_rms.items())


def term_norms(raw: np.ndarray, units: np.ndarray, group: np.ndarray, kind: str) -> tuple[np.ndarray, bool]:
    """Error norm of each point (triple of `kind` rows of one term; a pair for pixels) or |row|, terms in order of
    first appearance; True if every term has a nonzero multiple of three (two) `kind` rows. Whole-array: one pass,
    not one mask per term (which made a 10000-pose fit spend seconds here)."""
    g = GROUP.get(kind, 3)
    if not len(group):
        return np.zeros(0), True
    ids, first, inverse = np.unique(group, return_index=True, return_inverse=True)
    term = np.argsort(np.argsort(first))[inverse]        # each row's term, numbered by first appearance
    order = np.argsort(term, kind="stable")
    sel = (np.asarray(units) == kind)[order]
    v, t = raw[order][sel], term[order][sel]
    counts = np.bincount(t, minlength=len(ids))
    in_triples = (counts % g == 0) & (counts > 0)
    tri_row = in_triples[t]
    tri_pos, abs_pos = np.flatnonzero(tri_row)[::g], np.flatnonzero(~tri_row)
    values = np.concatenate([np.linalg.norm(v[tri_row].reshape(-1, g), axis=1), np.abs(v[~tri_row])])
    return values[np.argsort(np.concatenate([tri_pos, abs_pos]), kind="stable")], bool(in_triples.all())


def block_statistics(problem, ev) -> list[BlockStats]:
    out = []
    for b in problem.blocks:
        raw = ev.raw[b.rows]
        units = np.array(b.units)
        group = ev.group[b.rows]
        rms, mx, nrms, nmax, nlabel = {}, {}, {}, {}, {}
        for kind in dict.fromkeys(b.units):
            scale, label = UNIT_SCALE[kind]
            v = raw[units == kind] * scale
            rms[label] = float(np.sqrt(np.mean(v ** 2))) if len(v) else 0.0
            mx[label] = float(np.max(np.abs(v))) if len(v) else 0.0
            norms, triples = term_norms(raw, units, group, kind) if kind != "prior" else (np.abs(raw), False)
            norms = norms * scale
            nrms[label] = float(np.sqrt(np.mean(norms ** 2))) if len(norms) else 0.0
            nmax[label] = float(np.max(norms)) if len(norms) else 0.0
            nlabel[label] = NORM_LABEL[kind] if triples else ("prior residual" if kind == "prior" else
                                                              f"|{kind} error| per row")
        out.append(BlockStats(b.name, b.type_name, len(raw), rms, mx, nrms, nmax, nlabel))
    return out


@dataclass
class CalibrationResult:
    params: ParameterSet
    requested: list[str]           # free parameters asked for
    selection: BaseSelection       # identifiability at the start point, over `requested`
    covariance: np.ndarray         # over params.free_names (the identifiable ones)
    before: list[BlockStats]
    after: list[BlockStats]
    solve: SolveResult
    dof: int
    sigma2: float                  # residual variance factor (1 = the stated sigmas are right)
    condition: float
    ill_conditioned: bool
    condition_limit: float
    n_rows: int
    prior_only: list[str] = field(default_factory=list)   # kept only because a prior determines them
    determinacy: object | None = None      # robocal.estimation.determinacy.Determinacy
    default_prior: object | None = None    # robocal.estimation.registration.DefaultPrior
    registration: list[str] = field(default_factory=list)   # parameters fitted for the "before" figures
    sessions: list[dict] = field(default_factory=list)      # per-session figures (estimation.session_figures)
    registration_values: dict[str, float] = field(default_factory=dict)   # their values in the "before" model
    robot_size: float | None = None        # m, the length the physical scales are relative to
    refusals: list = field(default_factory=list)            # robocal.estimation.plausibility.Refusal
    findings: list = field(default_factory=list)            # robocal.estimation.findings.Finding
    scales: object | None = None           # robocal.estimation.physical_scale.PhysicalScales
    determined_thresholds: tuple[float, float] = (1e-4, 1e-4)   # m, rad: solver.determined_length / _angle
    weakest_direction: list[str] = field(default_factory=list)  # of an ill-conditioned fit

    @property
    def success(self) -> bool:
        return self.solve.success and not self.ill_conditioned and not self.refusals

    @property
    def status(self) -> str:
        if not self.solve.success:
            return "not converged"
        if self.ill_conditioned:
            return "ill-conditioned"
        return "implausible" if self.refusals else "converged"

    def refusal_lines(self, limit: int | None = None) -> list[str]:
        """What went wrong and how to fix it, one pair per refusal (empty for an accepted fit)."""
        return [line for k, r in enumerate(self.refusals, 1) for line in r.lines(k, limit)]

    @property
    def unidentifiable(self) -> list[str]:
        return [self.requested[j] for j in self.selection.dependent]

    @property
    def estimated(self) -> list[str]:
        return self.params.free_names

    def identifiability_statements(self, limit: int | None = None) -> list[str]:
        return identifiability_statements(self, limit)

    def registered_nominal(self, nominal):
        """A copy of the nominal ParameterSet with the registration frames at their "before" values: the
        model the "before" figures describe (the scene draws it as "before")."""
        before = nominal.copy()
        for name, value in self.registration_values.items():
            before[name].value = value
        return before

    def to_dict(self) -> dict:
        return {
            "status": self.status,
            **({"sessions": self.sessions} if self.sessions else {}),
            "success": self.success,
            "message": self.solve.message,
            "iterations": self.solve.nit,
            "rows": self.n_rows,
            "degrees_of_freedom": self.dof,
            "sigma_ratio": float(np.sqrt(self.sigma2)) if np.isfinite(self.sigma2) else None,
            "condition_number": self.condition,
            "identifiability": identifiability_dict(self),
            "refusals": [r.to_dict() for r in self.refusals],
            "findings": [f.to_dict() for f in self.findings],
            "finding_rule": FINDING_RULE,
            "default_prior": self.default_prior.to_dict() if self.default_prior is not None else None,
            "registration_before": {"parameters": self.registration, "values": self.registration_values,
                                    "meaning": "before = the nominal model with only these frames fitted"},
            "robot_size_m": self.robot_size,
            "parameters": self.params.to_list(),
            "residuals_before": [b.to_dict() for b in self.before],
            "residuals_after": [b.to_dict() for b in self.after],
            "convergence": [vars(h) for h in self.solve.history],
            "units": "SI (m, rad) for parameters; mm and mrad for residual statistics; rms_norm = RMS of the "
                     "3D error norm of each point / orientation",
        }

    def to_json(self) -> str:
        """Strict JSON: non-finite numbers (an infinite condition number, a missing standard error) are null."""
        return json.dumps(_finite(self.to_dict()), indent=2, default=_json_default, allow_nan=False)

    def summary(self, terminal: bool = False) -> str:
        """The text of summary.txt; terminal=True: long lists of names shown with their count."""
        return summary_text(self, SHOWN if terminal else None)


def _finite(o):
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    return o


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))
