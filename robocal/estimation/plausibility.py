"""Post-fit checks that refuse a fit no robot could have produced, each with the change that fixes it.

A fit is refused (status not converged / implausible / ill-conditioned; no URDF without --allow-failed) when
  - the solver stopped at its iteration cap or found no descent;
  - the kept block is ill-conditioned beyond solver.condition_limit;
  - a robot parameter lies beyond BEYOND physical scales from its nominal value;
  - a direction the data leave free beyond BEYOND physical scales has no prior to decide it (left to chance).
Each refusal says what went wrong and what to run or change (docs/validation.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.estimation.physical_scale import BEYOND, unit_label


@dataclass
class Refusal:
    problem: str          # what went wrong
    fix: str              # the command or config change that fixes it

    def to_dict(self) -> dict:
        return {"problem": self.problem, "fix": self.fix}


def prior_hint(params, names, scales) -> str:
    """`priors:` entries at the physical scale for the named parameters, as YAML flow text."""
    items = [f"'{n}': {scales.scale[n]:.3g}" for n in names if n in scales.scale][:4]
    more = ", ..." if len(names) > 4 else ""
    return "parameters: {priors: {" + ", ".join(items) + more + "}}"


def check_fit(result, nominal: dict[str, float], scales, regularisation: str, max_iterations: int) -> list[Refusal]:
    """Refusals of a finished fit (empty: plausible)."""
    out = []
    params = result.params
    solve = result.solve
    if not solve.success:
        if solve.nit >= max_iterations:
            out.append(Refusal(f"the solver stopped at its cap of {max_iterations} iterations before converging",
                               "run `robocal select CONFIG` to fit the model the data support, or keep "
                               "solver: {regularisation: auto} (the default) so weak directions get a prior; "
                               f"raising solver: {{max_iterations: {4 * max_iterations}}} only helps if the "
                               "cost is still falling"))
        else:
            out.append(Refusal(f"the solver found no step that lowers the cost ({solve.message})",
                               "check the data (units, joint columns, outliers: solver: {loss: huber}) and the "
                               "starting model (robot.base, parameters.initial)"))
    if result.ill_conditioned:
        out.append(Refusal(f"the fit is ill-conditioned (condition number {result.condition:.3g} > "
                           f"{result.condition_limit:.3g})",
                           "run `robocal select CONFIG`, or fix the parameters named under Identifiability"))
    far = []
    for n, s in scales.scale.items():
        if n in params and params[n].vary and abs(params[n].value - nominal.get(n, 0.0)) > BEYOND * s:
            far.append(n)
    if far:
        shown = ", ".join(f"{n} = {params[n].value * unit_label(params[n])[0]:+.4g} {unit_label(params[n])[1]}"
                          for n in far[:4])
        out.append(Refusal(f"{len(far)} parameter(s) beyond {BEYOND:g} physical scales from nominal: {shown}"
                           + (" ..." if len(far) > 4 else ""),
                           "add priors at the physical scale (" + prior_hint(params, far, scales) + ") or run "
                           "`robocal select CONFIG`; if the value is real, check the URDF and the joint zero"))
    det = result.determinacy
    if det is not None:
        # weak (1-10 scales) is reported; free to wander past what a robot can be (> BEYOND scales) is refused
        loose = [d for d in det.directions if d.in_scales > BEYOND and not d.decided_by_prior
                 and any(t[0] in scales.scale and params[t[0]].prior_sigma is None for t in d.terms)]
        if loose:
            names = [t[0] for d in loose for t in d.terms if t[0] in scales.scale]
            out.append(Refusal(f"{len(loose)} direction(s) the data leave free beyond {BEYOND:g} physical scales, "
                               f"with no prior to decide them: {loose[0].describe()}",
                               ("add priors (" if regularisation == "auto" else
                                "set solver: {regularisation: auto}, or add priors (")
                               + prior_hint(params, list(dict.fromkeys(names)), scales) + "), or run "
                               "`robocal select CONFIG`"))
    return out


def nominal_values(params) -> dict[str, float]:
    return {p.name: float(p.value) for p in params}


def finite_or_none(x: float):
    return float(x) if x is not None and np.isfinite(x) else None
