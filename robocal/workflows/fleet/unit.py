"""One unit's calibration, as a worker runs it: the same library calls as `robocal calibrate`, the
output folder it would write, and the unit's fleet-table row. Never raises for the unit's own
problems (bad CSV, diverged fit): those go into the row's status and message, so the fleet goes on.
"""
from __future__ import annotations

import dataclasses
import os
import socket
import time
from pathlib import Path

import numpy as np

from robocal.errors import InputError, RobocalError
from robocal.workflows.calibrate import CalibrationRun, run_calibration, sigma_ratio
from robocal.workflows.config_types import CalibrationConfig
from robocal.workflows.fleet.manifest import UnitJob
from robocal.workflows.setup import Setup, build_setup, with_urdf

#: statuses whose row is final: a re-run with the same inputs and config skips the unit
FINAL_STATUSES = ("converged", "ill-conditioned", "not converged", "diverged", "input error", "error")
#: the status of a task the cluster lost (its workers died); a re-run calibrates it again
LOST = "lost"


def unit_config(job: UnitJob) -> CalibrationConfig:
    """The template config with this unit's data files, URDF and output folder."""
    config = job.config

    def own(csv: Path | None) -> str | None:     # a block's csv as the template writes it: the manifest's key
        return None if csv is None else Path(os.path.relpath(csv, config.base_dir)).as_posix()
    blocks = tuple(dataclasses.replace(m, csv=Path(job.data[own(m.csv)])) if own(m.csv) in job.data else m
                   for m in config.measurements)
    config = dataclasses.replace(config, data=dataclasses.replace(config.data, csv=Path(job.data[""])),
                                 measurements=blocks, output=dataclasses.replace(config.output, dir=Path(job.output_dir)))
    return with_urdf(config, job.urdf) if job.urdf else config


def unit_setup(job: UnitJob) -> Setup:
    return build_setup(unit_config(job))


def calibrate_unit(job: UnitJob) -> dict:
    """Calibrate one unit as `robocal calibrate` would (run_calibration), return its table row (plain values)."""
    start = time.perf_counter()
    row = {**job.identity(), "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        run = run_calibration(unit_setup(job), job.output_dir, force=True, accept_sigma_ratio=job.max_sigma_ratio)
        row.update(unit_status(run), **result_columns(run.result, sigma_ratio(run.result)))
    except InputError as exc:
        row.update(status="input error", message=str(exc))
    except RobocalError as exc:
        row.update(status="error", message=str(exc))
    except Exception as exc:   # a bug or an unforeseen input: recorded in the row, the fleet goes on
        row.update(status="error", message=f"{type(exc).__name__}: {exc}")
    row["elapsed_s"] = time.perf_counter() - start
    return row


def unit_status(run: CalibrationRun) -> dict:
    """The row's status and message: the fit's status, 'diverged' for a rejected fit."""
    result = run.result
    if run.rejected:
        return {"status": "diverged", "message": run.rejected}
    if not result.solve.success:
        return {"status": result.status, "message": f"{result.solve.message} after {result.solve.nit} iterations"}
    if result.ill_conditioned:
        return {"status": result.status, "message": result.identifiability_statements()[-1]}
    return {"status": result.status, "message": ""}


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
