"""Across a fleet: each parameter's distribution, outlier units and drift of units calibrated again.

Only converged rows take part. For every parameter the fleet's centre is the median and its spread
the scaled MAD (1.4826 MAD: the standard deviation for normal data), floored at the median standard
error so that a fleet more alike than its own estimates can tell apart flags nobody. A unit whose
estimate lies more than `threshold` spreads from the median is an outlier, reported with every
parameter that makes it so. A unit with converged rows at two or more dates drifts in a parameter
when last - first exceeds `threshold` combined standard errors sqrt(se_first^2 + se_last^2).
Values are SI (m, rad). See docs/fleet.md.
"""
from __future__ import annotations

import datetime
from dataclasses import dataclass, field

import numpy as np

MAD_TO_SIGMA = 1.4826     # 1 / Phi^-1(3/4): MAD -> standard deviation for normal data
DEFAULT_THRESHOLD = 5.0   # robust sigmas; see docs/fleet.md for the false-alarm rate
OK = "converged"


@dataclass
class Spread:
    name: str
    n: int
    median: float
    scale: float        # max(1.4826 MAD, median standard error)
    low: float
    high: float


@dataclass
class Outlier:
    key: str
    unit: str
    date: str
    parameters: list[tuple[str, float, float, float]]   # (name, estimate, fleet median, robust z), |z| first


@dataclass
class Drift:
    unit: str
    parameter: str
    first_date: str
    last_date: str
    first: float
    last: float
    z: float             # (last - first) / combined standard error
    per_year: float      # (last - first) per year (nan for the same day)
    history: list[tuple[str, float, float]] = field(default_factory=list)   # (date, estimate, stderr)


@dataclass
class FleetReport:
    rows: int
    statuses: dict[str, int]
    failures: list[dict]
    spreads: list[Spread]
    outliers: list[Outlier]
    drifts: list[Drift]
    threshold: float
    robust_z: dict[str, np.ndarray]       # parameter -> z of every converged row (in `converged` order)
    converged: list[str]                  # keys of the converged rows


def parameter_names(rows: list[dict]) -> list[str]:
    return list(dict.fromkeys(k[len("est:"):] for r in rows for k in r if k.startswith("est:")))


def estimated(rows: list[dict], name: str) -> tuple[np.ndarray, np.ndarray]:
    """(estimates, standard errors) of `name` over `rows`; nan where a row has none."""
    est = np.array([np.nan if r.get(f"est:{name}") is None else r[f"est:{name}"] for r in rows], float)
    se = np.array([np.nan if r.get(f"se:{name}") is None else r[f"se:{name}"] for r in rows], float)
    return est, se


def fleet_report(rows: list[dict], threshold: float = DEFAULT_THRESHOLD) -> FleetReport:
    ok = [r for r in rows if r.get("status") == OK]
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    spreads, zs = [], {}
    flagged: dict[str, list] = {}
    for name in parameter_names(ok):
        est, se = estimated(ok, name)
        has = np.isfinite(est) & np.isfinite(se)     # estimated (not fixed as unidentifiable) in that row
        if has.sum() < 3:
            continue
        med = float(np.median(est[has]))
        scale = max(MAD_TO_SIGMA * float(np.median(np.abs(est[has] - med))), float(np.median(se[has])))
        z = np.where(has, (est - med) / scale, np.nan)
        zs[name] = z
        spreads.append(Spread(name, int(has.sum()), med, scale, float(est[has].min()), float(est[has].max())))
        for i in np.flatnonzero(np.abs(np.nan_to_num(z)) > threshold):
            flagged.setdefault(ok[i]["key"], []).append((name, float(est[i]), med, float(z[i])))
    outliers = []
    for r in ok:
        if r["key"] in flagged:
            params = sorted(flagged[r["key"]], key=lambda t: -abs(t[3]))
            outliers.append(Outlier(r["key"], r["unit"], r.get("date") or "", params))
    outliers.sort(key=lambda o: -abs(o.parameters[0][3]))
    failures = [r for r in rows if r.get("status") != OK]
    return FleetReport(len(rows), statuses, failures, spreads, outliers, drifts(ok, threshold), threshold, zs,
                       [r["key"] for r in ok])


def drifts(ok: list[dict], threshold: float) -> list[Drift]:
    """Parameters that changed by more than `threshold` combined standard errors between a unit's first
    and last dated calibrations, largest first."""
    by_unit: dict[str, list[dict]] = {}
    for r in ok:
        if r.get("date"):
            by_unit.setdefault(r["unit"], []).append(r)
    out = []
    for unit, rs in by_unit.items():
        if len(rs) < 2:
            continue
        rs.sort(key=lambda r: r["date"])
        days = (datetime.date.fromisoformat(rs[-1]["date"]) - datetime.date.fromisoformat(rs[0]["date"])).days
        for name in parameter_names(rs):
            est, se = estimated(rs, name)
            if not (np.isfinite(se[0]) and np.isfinite(se[-1])):
                continue
            change = est[-1] - est[0]
            z = change / np.hypot(se[0], se[-1])
            if abs(z) > threshold:
                out.append(Drift(unit, name, rs[0]["date"], rs[-1]["date"], float(est[0]), float(est[-1]), float(z),
                                 change / (days / 365.25) if days > 0 else float("nan"),
                                 [(r["date"], float(e), float(s)) for r, e, s in zip(rs, est, se)]))
    out.sort(key=lambda d: -abs(d.z))
    return out


def summary_lines(rep: FleetReport) -> list[str]:
    """The report in words (what `robocal fleet report` prints)."""
    lines = [f"{rep.rows} calibrations: " + ", ".join(f"{n} {s}" for s, n in sorted(rep.statuses.items())),
             f"{len(rep.spreads)} parameters compared across {len(rep.converged)} converged calibrations "
             f"(threshold {rep.threshold:g} robust standard deviations)"]
    for r in rep.failures:
        lines.append(f"  FAILED {r['key']}: {r['status']}: {r.get('message') or ''}")
    for o in rep.outliers:
        lines.append(f"  OUTLIER {o.key}: " + ", ".join(f"{n} {v:+.4g} (fleet median {m:+.4g}, z {z:+.1f})"
                                                        for n, v, m, z in o.parameters))
    for d in rep.drifts:
        lines.append(f"  DRIFT {d.unit} {d.parameter}: {d.first:+.4g} ({d.first_date}) -> {d.last:+.4g} "
                     f"({d.last_date}), {d.z:+.1f} standard errors")
    if not (rep.failures or rep.outliers or rep.drifts):
        lines.append("  no failures, no outliers, no drift")
    return lines
