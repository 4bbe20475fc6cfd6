"""CalibrationResult: estimates, uncertainties, identifiability and fit statistics, as data and as text.

The library never prints; `summary()` returns the text that the CLI shows.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from robocal.estimation.identifiability import BaseSelection
from robocal.model.parameters import ParameterSet
from robocal.estimation.solve import SolveResult

UNIT_SCALE = {"length": (1e3, "mm"), "angle": (1e3, "mrad"), "prior": (1.0, "sigma")}


@dataclass
class BlockStats:
    """RMS and maximum of one measurement block's rows, per unit kind, in report units (mm, mrad)."""

    name: str
    type_name: str
    rows: int
    rms: dict[str, float]
    max: dict[str, float]

    def to_dict(self) -> dict:
        return {"name": self.name, "type": self.type_name, "rows": self.rows,
                "rms": self.rms, "max": self.max}


def block_statistics(problem, ev) -> list[BlockStats]:
    out = []
    for b in problem.blocks:
        raw = ev.raw[b.rows]
        units = np.array(b.units)
        rms, mx = {}, {}
        for kind in dict.fromkeys(b.units):
            scale, label = UNIT_SCALE[kind]
            v = raw[units == kind] * scale
            rms[label] = float(np.sqrt(np.mean(v ** 2))) if len(v) else 0.0
            mx[label] = float(np.max(np.abs(v))) if len(v) else 0.0
        out.append(BlockStats(b.name, b.type_name, len(raw), rms, mx))
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

    @property
    def success(self) -> bool:
        return self.solve.success and not self.ill_conditioned

    @property
    def status(self) -> str:
        if not self.solve.success:
            return "not converged"
        return "ill-conditioned" if self.ill_conditioned else "converged"

    @property
    def unidentifiable(self) -> list[str]:
        return [self.requested[j] for j in self.selection.dependent]

    @property
    def estimated(self) -> list[str]:
        return self.params.free_names

    def identifiability_statements(self) -> list[str]:
        lines = [f"{self.selection.rank} of {len(self.requested)} requested parameters can be determined "
                 f"from these measurements."]
        lines += [s + "; fixed at its initial value." for s in self.selection.describe()]
        if self.prior_only:
            lines.append("Determined by their priors only, not by the data: " + ", ".join(self.prior_only) + ".")
        if self.ill_conditioned:
            lines.append(f"The fit is ill-conditioned: condition number {self.condition:.3g} exceeds "
                         f"{self.condition_limit:.3g}; estimates along the weakest directions are unreliable.")
        return lines

    def to_dict(self) -> dict:
        return {
            "status": self.status,
            "success": self.success,
            "message": self.solve.message,
            "iterations": self.solve.nit,
            "rows": self.n_rows,
            "degrees_of_freedom": self.dof,
            "sigma_ratio": float(np.sqrt(self.sigma2)) if np.isfinite(self.sigma2) else None,
            "condition_number": self.condition,
            "identifiability": {
                "requested": len(self.requested),
                "rank": self.selection.rank,
                "unidentifiable": self.unidentifiable,
                "prior_only": self.prior_only,
                "statements": self.identifiability_statements(),
                "rank_rtol": self.selection.rtol,
            },
            "parameters": self.params.to_list(),
            "residuals_before": [b.to_dict() for b in self.before],
            "residuals_after": [b.to_dict() for b in self.after],
            "convergence": [vars(h) for h in self.solve.history],
            "units": "SI (m, rad) for parameters; mm and mrad for residual statistics",
        }

    def to_json(self) -> str:
        """Strict JSON: non-finite numbers (an infinite condition number, a missing standard error) are null."""
        return json.dumps(_finite(self.to_dict()), indent=2, default=_json_default, allow_nan=False)

    def summary(self) -> str:
        lines = [f"Calibration {self.status}: {self.solve.message} after {self.solve.nit} iterations",
                 f"{self.n_rows} residual rows, {len(self.params.free_names)} estimated parameters, "
                 f"condition number {self.condition:.3g}, residual/sigma {np.sqrt(self.sigma2):.3f}", "",
                 f"{'block':<20}{'type':<14}{'rows':>6}   {'RMS before':>22}   {'RMS after':>22}"]
        for b0, b1 in zip(self.before, self.after):
            fmt = lambda d: ", ".join(f"{v:.4g} {k}" for k, v in d.items())
            lines.append(f"{b0.name:<20}{b0.type_name:<14}{b0.rows:>6}   {fmt(b0.rms):>22}   {fmt(b1.rms):>22}")
        lines += ["", "Estimated parameters (SI units):"]
        for name in self.params.free_names:
            p = self.params[name]
            se = f"{p.stderr:.3g}" if p.stderr is not None and np.isfinite(p.stderr) else "n/a"
            lines.append(f"  {name:<32}{p.value:>+14.6g} {p.unit:<4} +- {se}")
        lines += ["", "Identifiability:"] + [f"  {s}" for s in self.identifiability_statements()]
        return "\n".join(lines)


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
