"""Post-fit checks that refuse a fit the data do not support, each with the config change that fixes it.

A fit is refused (status not converged / implausible / ill-conditioned; no URDF without --allow-failed) when
  - the solver stopped at its iteration cap or found no descent;
  - the kept block is ill-conditioned beyond solver.condition_limit;
  - a robot parameter lies beyond BEYOND physical scales from its nominal value and the data do not determine it
    (fewer than FINDING_SIGMAS data-only standard errors from nominal; one they do determine is a finding,
    robocal.estimation.findings);
  - a robot parameter the data leave loose is free beyond BEYOND physical scales: its standard error, with the
    contribution of every prior (its own or its confounded partners'), exceeds BEYOND scales.
Each fix is exact: it is computed from the effective prior of every parameter (the config's patterns and the
default prior as they ended up), never repeats what the config already has, names every parameter, and is also
given as a config fragment (`changes`: alternatives, each merged into the config by `merge_change`) that
tests/test_plausibility_fixes.py applies to check that the refusal goes away.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from robocal.estimation.determinacy import LOOSE
from robocal.estimation.findings import firmly_determined
from robocal.estimation.physical_scale import BEYOND, FINDING_SIGMAS, unit_label

STILL_FALLING = 1e-6     # relative cost decrease per iteration at the cap above which more iterations help
SHOWN = 6                # parameters named on the terminal per refusal; summary.txt and result.json: all


SOLVER_CAP, NO_DESCENT, ILL_CONDITIONED, BEYOND_SCALE, LOOSE_FREE = (
    "iteration cap", "no descent", "ill-conditioned", "beyond physical scale", "free beyond physical scale")


@dataclass
class Refusal:
    kind: str                            # one of the five above
    problem: str                         # what went wrong (without the parameter list)
    fix: str                             # the change that fixes it, in words
    items: list[str] = field(default_factory=list)      # every parameter concerned, with its figures
    changes: list[dict] = field(default_factory=list)   # alternatives, each a config fragment that fixes it
    names: list[str] = field(default_factory=list)      # the parameters concerned

    def lines(self, k: int, limit: int | None = None) -> list[str]:
        """'Refused (k): ...' and '  Fix: ...'; limit: items and change entries shown (None: all)."""
        items = self.items if limit is None or len(self.items) <= limit else self.items[:limit] + [
            f"and {len(self.items) - limit} more (every one in summary.txt and result.json)"]
        problem = self.problem + (": " + "; ".join(items) if items else "")
        fixes = [flow(c, limit) for c in self.changes]
        fix = self.fix + (" " + " or ".join(f"`{f}`" for f in fixes) if fixes else "")
        return [f"Refused ({k}): {problem}.", f"  Fix: {fix}."]

    def to_dict(self) -> dict:
        return {"kind": self.kind, "problem": self.problem, "parameters": self.names, "figures": self.items,
                "fix": self.fix, "config_changes": self.changes}


def flow(change, limit: int | None = None) -> str:
    """A config fragment as one line of YAML flow text; a mapping longer than `limit` shows its count."""
    if isinstance(change, dict):
        items = list(change.items())
        shown = items if limit is None or len(items) <= limit else items[:limit]
        text = ", ".join(f"{key_text(k)}: {flow(v, limit)}" for k, v in shown)
        if len(shown) < len(items):
            text += f", and {len(items) - len(shown)} more (the whole change in summary.txt and result.json)"
        return "{" + text + "}"
    if isinstance(change, list):
        shown = change if limit is None or len(change) <= limit else change[:limit]
        text = ", ".join(flow(v, limit) for v in shown)
        if len(shown) < len(change):
            text += f", and {len(change) - len(shown)} more (the whole change in summary.txt and result.json)"
        return "[" + text + "]"
    if isinstance(change, float):
        return f"{change:.3g}"
    return key_text(change) if isinstance(change, str) else str(change)


def key_text(k: str) -> str:
    return k if k.replace("_", "").replace(".", "").isalnum() else f"'{k}'"


def merge_change(config: dict, change: dict) -> dict:
    """`config` (a parsed YAML mapping) with `change` merged in: mappings key by key (a new key after the
    existing ones, so a parameter's own prior overrides an earlier pattern), lists extended."""
    out = copy.deepcopy(config)
    for k, v in change.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge_change(out[k], v)
        elif isinstance(v, list) and isinstance(out.get(k), list):
            out[k] = out[k] + [x for x in v if x not in out[k]]
        else:
            out[k] = copy.deepcopy(v)
    return out


def rounded(x: float) -> float:
    return float(f"{x:.3g}")


def hold(params, names, scales) -> dict:
    """The config change that holds `names`: a prior at the physical scale where the effective prior is looser
    (or missing), else fix the parameter at its initial value."""
    priors, fix = {}, []
    for n in names:
        sigma = params[n].prior_sigma
        if n in scales.scale and (sigma is None or sigma > scales.scale[n] * (1 + 1e-9)):
            priors[n] = rounded(scales.scale[n])
        else:
            fix.append(n)
    change = {}
    if priors:
        change["priors"] = priors
    if fix:
        change["fix"] = fix
    return {"parameters": change}


def hold_words(change: dict) -> str:
    words = []
    if "priors" in change["parameters"]:
        words.append("a prior at the physical scale (tighter than the one it has, if any)")
    if "fix" in change["parameters"]:
        words.append("fix those whose prior is already at the scale")
    return "add to the config " + " and ".join(words) + ":"


def figure(p, nominal: float, scale: float, se_data: float) -> str:
    k, u = unit_label(p)
    d = p.value - nominal
    se = "no information" if not np.isfinite(se_data) else f"data alone +- {k * se_data:.3g}"
    return f"{p.name} = {k * p.value:+.4g} {u} ({se}, {abs(d) / scale:.3g} physical scales)"


def solver_refusals(result, scales, regularisation: str, max_iterations: int) -> list[Refusal]:
    solve = result.solve
    if solve.success:
        return []
    if solve.nit < max_iterations:
        return [Refusal(NO_DESCENT, f"the solver found no step that lowers the cost ({solve.message})",
                        "check the data (units, joint columns, outliers: solver: {loss: huber}) and the starting "
                        "model (robot.base, parameters.initial)")]
    costs = [h.cost for h in solve.history[-3:]]
    falling = len(costs) >= 2 and (costs[0] - costs[-1]) / max(abs(costs[0]), 1e-300) > STILL_FALLING * len(costs)
    changes, words = [], []
    if falling:
        changes.append({"solver": {"max_iterations": 4 * max_iterations}})
        words.append("the cost was still falling: raise the cap")
    if regularisation != "auto":
        changes.append({"solver": {"regularisation": "auto"}})
        words.append("let the default prior hold the weak directions")
    det = result.determinacy
    loose = [n for n in (det.names_in(LOOSE) if det is not None else []) if n in scales.scale]
    if not changes and loose:        # stalled along the loose directions: hold those parameters
        changes.append(hold(result.params, loose, scales))
        words.append(hold_words(changes[-1])[:-1])
    if not changes:
        return [Refusal(SOLVER_CAP, f"the solver stopped at its cap of {max_iterations} iterations before converging",
                        "the cost had stalled with no loose robot parameter to hold: check the data and the "
                        "starting model, or run `robocal select CONFIG` for a model the data support")]
    held = loose if "parameters" in changes[-1] else []
    return [Refusal(SOLVER_CAP, f"the solver stopped at its cap of {max_iterations} iterations before converging",
                    " or ".join(words) + ", with", changes=changes, names=held)]


def check_fit(result, nominal: dict[str, float], scales, regularisation: str, max_iterations: int) -> list[Refusal]:
    """Refusals of a finished fit (empty: plausible)."""
    out = solver_refusals(result, scales, regularisation, max_iterations)
    params, det = result.params, result.determinacy
    data_se = det.stderr if det is not None else {}
    if result.ill_conditioned:
        weak = [n for n in result.weakest_direction if n in params]
        held = [n for n in weak if n in scales.scale] or weak[-1:]      # robot parameters, else the latest one
        change = hold(params, held, scales)
        out.append(Refusal(ILL_CONDITIONED, f"the fit is ill-conditioned (condition number {result.condition:.3g} "
                           f"> {result.condition_limit:.3g}); its weakest direction moves " + ", ".join(weak),
                           hold_words(change), changes=[change], names=held))
    far = [n for n, s in scales.scale.items() if n in params and params[n].vary
           and abs(params[n].value - nominal.get(n, 0.0)) > BEYOND * s
           and not firmly_determined(params[n].value - nominal.get(n, 0.0), data_se.get(n))]
    if far:
        change = hold(params, far, scales)
        out.append(Refusal(BEYOND_SCALE, f"{len(far)} parameter(s) beyond {BEYOND:g} physical scales from nominal "
                           f"that the data do not determine (fewer than {FINDING_SIGMAS:g} data-only standard errors "
                           "from nominal)",
                           hold_words(change),
                           [figure(params[n], nominal.get(n, 0.0), scales.scale[n], data_se.get(n, np.inf))
                            for n in far], [change], far))
    if det is not None:
        # free: the data leave it loose and nothing else holds it either (its standard error with every prior's
        # contribution, its own or its partners', is still beyond BEYOND scales)
        loose = [n for n in det.names_in(LOOSE) if n in scales.scale and n not in far
                 and not (params[n].stderr is not None and params[n].stderr <= BEYOND * scales.scale[n])]
        if loose:
            change = hold(params, loose, scales)
            changes = [change] + ([{"solver": {"regularisation": "auto"}}] if regularisation != "auto" else [])
            out.append(Refusal(LOOSE_FREE, f"{len(loose)} parameter(s) the data leave free beyond {BEYOND:g} "
                               "physical scales (standard error, with every prior's contribution), nothing holding "
                               "them",
                               hold_words(change)[:-1] + (", or let the default prior hold them:"
                                                          if regularisation != "auto" else ":"),
                               [figure(params[n], nominal.get(n, 0.0), scales.scale[n], data_se[n]) for n in loose],
                               changes, loose))
    return out


def nominal_values(params) -> dict[str, float]:
    return {p.name: float(p.value) for p in params}


def finite_or_none(x: float):
    return float(x) if x is not None and np.isfinite(x) else None
