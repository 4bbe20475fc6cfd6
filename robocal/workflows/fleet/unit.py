"""One unit's calibration, as a worker runs it: the same library calls as `robocal calibrate`, the
output folder it would write, and the unit's fleet-table row. Never raises for the unit's own
problems (bad CSV, diverged fit): those go into the row's status and message, so the fleet goes on.
"""
from __future__ import annotations

import copy
import os
import socket
import time
from pathlib import Path

import numpy as np

from robocal.errors import InputError, RobocalError
from robocal.estimation.calibrate import calibrate
from robocal.workflows.fleet.manifest import UnitJob
from robocal.workflows.config import Setup, setup_from_config
from robocal.workflows.outputs import write_results
from robocal.viz.scene import scene_bytes

#: statuses whose row is final: a re-run with the same inputs and config skips the unit
FINAL_STATUSES = ("converged", "ill-conditioned", "not converged", "diverged", "input error", "error")
#: the status of a task the cluster lost (its workers died); a re-run calibrates it again
LOST = "lost"


def unit_config(job: UnitJob) -> dict:
    """The template config with this unit's data files, URDF and output folder."""
    raw = copy.deepcopy(job.raw)
    data = raw.setdefault("data", {}) or {}
    raw["data"] = data
    data["csv"] = job.data[""]
    for block in raw.get("measurements") or []:
        if isinstance(block, dict) and block.get("csv") in job.data:
            block["csv"] = job.data[block["csv"]]
    if job.urdf:
        robot = {k: v for k, v in (raw.get("robot") or {}).items() if k not in ("urdf", "example")}
        raw["robot"] = {**robot, "urdf": job.urdf}
    raw.setdefault("output", {})
    raw["output"] = {**(raw["output"] or {}), "dir": job.output_dir}
    return raw


def unit_setup(job: UnitJob) -> Setup:
    raw = unit_config(job)
    return setup_from_config(raw, Path(job.template).parent, job.template)


def calibrate_unit(job: UnitJob) -> dict:
    """Calibrate one unit, write its output folder, return its table row (plain Python values)."""
    start = time.perf_counter()
    row = {**job.identity(), "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        setup = unit_setup(job)
        row.update(_fit(setup, job))
    except InputError as exc:
        row.update(status="input error", message=str(exc))
    except RobocalError as exc:
        row.update(status="error", message=str(exc))
    except Exception as exc:   # a bug or an unforeseen input: recorded in the row, the fleet goes on
        row.update(status="error", message=f"{type(exc).__name__}: {exc}")
    row["elapsed_s"] = time.perf_counter() - start
    return row


def _fit(setup: Setup, job: UnitJob) -> dict:
    p = setup.problem
    before = p.params.copy()    # the scene shows the model before and after the fit
    result = calibrate(p, setup.options, source=", ".join(str(t.path) for t in setup.tables.values()))
    dof = max(result.dof, 1)
    ratio = float(np.sqrt(np.sum(result.solve.fun ** 2) / dof))   # residual / stated sigma
    status, message = result.status, ""
    if not result.solve.success:
        message = f"{result.solve.message} after {result.solve.nit} iterations"
    elif ratio > job.max_sigma_ratio:
        status = "diverged"
        rms = "; ".join(f"{b.name} " + ", ".join(f"{v:.4g} {k}" for k, v in b.rms.items()) for b in result.after)
        message = (f"residual/sigma {ratio:.4g} exceeds accept.max_sigma_ratio {job.max_sigma_ratio:g} "
                   f"(RMS after the fit: {rms}); the fitted model does not explain the data")
        setup.robot.urdf_text = None   # no calibrated URDF from a rejected fit (result.json still written)
    elif result.ill_conditioned:
        message = result.identifiability_statements()[-1]
    extra = {"scene.json": scene_bytes(setup, result, before)}
    if (setup.raw.get("output") or {}).get("report", True):
        try:
            from robocal.viz.report import report_bytes   # matplotlib and meshcat: the optional [viz] extra
            extra["report.html"] = report_bytes(result, extra["scene.json"], meshes=False)
        except ImportError:
            pass   # the folder holds everything else; `robocal report` can add the page later
    write_results(setup.robot, result, job.output_dir, force=True, extra=extra)
    return {"status": status, "message": message, **result_columns(result, ratio)}


def result_columns(result, sigma_ratio: float) -> dict:
    """Fit figures and every requested parameter's estimate (est:NAME) and standard error (se:NAME).

    Residual figures are labelled rms_before:BLOCK:UNIT / rms_after:BLOCK:UNIT (norm RMS in mm, mrad).
    Parameters the data cannot determine keep their initial value and have no standard error.
    """
    out = {"iterations": int(result.solve.nit), "rows": int(result.n_rows), "sigma_ratio": sigma_ratio,
           "condition": float(result.condition)}
    for state, blocks in (("before", result.before), ("after", result.after)):
        for b in blocks:
            for label, v in b.rms.items():
                out[f"rms_{state}:{b.name}:{label}"] = float(v)
    for name in result.requested:
        p = result.params[name]
        out[f"est:{name}"] = float(p.value)
        out[f"se:{name}"] = float(p.stderr) if p.vary and p.stderr is not None and np.isfinite(p.stderr) else None
    return out
