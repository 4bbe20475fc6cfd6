"""ISO 9283 pose and distance figures from a calibration config for the nominal and the calibrated model.

The config is a calibration YAML (robot, data, parameters, measurements, solver) plus a section:

    iso9283:
      pose_id: pose               # column holding the commanded pose's label; rows with an empty
                                  # cell are calibration-only rows and take no part in the figures
      measurement: tracker        # the pose block whose measurements are the attained poses
                                  # (default: the config's only pose block)
      commanded: [xc, yc, zc, qxc, qyc, qzc, qwc]   # optional: commanded pose columns (measurement
                                  # frame, the data's length unit, quaternion scalar last); default:
                                  # the nominal model at the commanded joints
      distance_pairs: [[P1, P2]]  # optional; default: consecutive poses in order of appearance

The commanded joints of a pose are the mean of its visits' readings. The calibrated model comes from
fitting the config's measurements (all rows), or from a previous result with --parameters
result.json. Attained poses under a model are predicted as in robocal.estimation.iso9283.model_attained.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from robocal.errors import InputError
from robocal.estimation.calibrate import calibrate
from robocal.estimation.iso9283 import Iso9283Figures, group_visits, iso9283_figures, model_attained, pose6
from robocal.workflows.config_types import Iso9283Config
from robocal.workflows.outputs import apply_result, load_result
from robocal.workflows.setup import load_config
from robocal.model.kinematics import ModelState


@dataclass
class Iso9283Run:
    nominal: Iso9283Figures
    calibrated: Iso9283Figures
    result: object | None          # the CalibrationResult when robocal fitted the model here
    frame: str

    def to_dict(self) -> dict:
        return {"frame": self.frame, "units": "SI (m, rad)", "nominal": self.nominal.to_dict(),
                "calibrated": self.calibrated.to_dict(),
                "calibration_status": None if self.result is None else self.result.status}


def check_iso9283(setup) -> Iso9283Config:
    """The config's `iso9283:` section, checked against the data before any fitting so a mistake costs no
    time: its pose block exists."""
    sec = setup.config.iso9283
    if sec is None:
        raise InputError("the config needs an 'iso9283' section (pose_id, measurement, commanded)",
                         source=setup.source, field="iso9283")
    pose_block(setup, sec)
    return sec


def pose_block(setup, sec: Iso9283Config):
    poses = [r for r in setup.problem.residuals if r.type_name == "pose"]
    if sec.measurement is None:
        if len(poses) != 1:
            raise InputError(f"name the pose block to use ({', '.join(r.name for r in poses) or 'none found'})",
                             source=setup.source, field="iso9283.measurement")
        return poses[0]
    hit = [r for r in poses if r.name == sec.measurement]
    if not hit:
        raise InputError(f"no pose block named '{sec.measurement}' (pose blocks: "
                         f"{', '.join(r.name for r in poses)})", source=setup.source, field="iso9283.measurement")
    return hit[0]


def _cells(setup, res, column: str):
    """(table rows, cell text) of `column` for each term of `res`."""
    out = []
    for k in range(res.n_terms):
        file, row = setup.sample_rows[int(res.samples[k])]
        tab = setup.tables[file]
        if not tab.has(column):
            raise InputError(f"missing column (columns present: {', '.join(tab.header)})", source=file,
                             field=column)
        out.append((tab, row, tab.cells[row][tab.header.index(column)].strip()))
    return out


def _commanded_columns(sec: Iso9283Config, setup, res, terms):
    cols = sec.commanded
    if cols is None:
        return None
    length_unit = setup.units["length"]
    out = []
    for k in terms:
        file, row = setup.sample_rows[int(res.samples[k])]
        tab = setup.tables[file]
        xyz = [tab.column(str(c), "length", length_unit, [row])[0] for c in cols[:3]]
        quat = np.array([tab.column(str(c), "", None, [row])[0] for c in cols[3:]])
        norm = np.linalg.norm(quat)
        if not 0.5 < norm < 1.5:
            raise InputError(f"commanded quaternion has norm {norm:.3g}; expected a unit quaternion",
                             source=file, row=tab.line(row), field=str(cols[3]))
        qx, qy, qz, qw = quat / norm
        out.append(pin.SE3(pin.Quaternion(qw, qx, qy, qz).toRotationMatrix(), np.array(xyz)))
    return out


def iso9283_from_config(config, parameters=None) -> Iso9283Run:
    """Figures of the config's ISO rows for the nominal and the calibrated model (see module doc)."""
    return iso9283_from_setup(load_config(config), parameters)


def iso9283_from_setup(setup, parameters=None) -> Iso9283Run:
    """As iso9283_from_config for a setup already built: the model is fitted here, or its parameters come
    from a previous result.json (`parameters`)."""
    check_iso9283(setup)
    nominal = setup.problem.params.copy()
    result = None
    if parameters is not None:
        doc, source = load_result(parameters)
        apply_result(setup.problem.params, doc, source)
    else:
        result = calibrate(setup.problem, setup.options, source=setup.source)
    return iso9283_run(setup, nominal, setup.problem.params, result)


def iso9283_run(setup, nominal_params, calibrated_params, result=None) -> Iso9283Run:
    """ISO 9283 figures of a setup's `iso9283:` rows under the nominal and the calibrated parameters
    (`robocal calibrate` passes the parameters it has just fitted; nothing is read again)."""
    sec = check_iso9283(setup)
    problem = setup.problem
    res = pose_block(setup, sec)
    id_col = sec.pose_id
    cells = _cells(setup, res, id_col)
    terms = [k for k, (_, _, text) in enumerate(cells) if text]
    if not terms:
        raise InputError(f"no row has a pose id in column '{id_col}'", source=str(cells[0][0].path) if cells else None,
                         field=id_col)
    ids = [cells[k][2] for k in terms]
    values = problem.values[res.samples[terms]]
    measured = [pin.SE3(pin.Quaternion(m[6], m[3], m[4], m[5]).toRotationMatrix(), m[:3].copy())
                for m in res.measurements[terms]]
    groups = group_visits(ids)
    q_c = {pid: values[rows].mean(axis=0) for pid, rows in groups.items()}
    nominal_ms = ModelState(setup.robot, nominal_params, problem.joint_names)
    calibrated_ms = ModelState(setup.robot, calibrated_params, problem.joint_names)
    fk = {name: {pid: ms.sample(q).pose(res.frame) for pid, q in q_c.items()}
          for name, ms in (("nominal", nominal_ms), ("calibrated", calibrated_ms))}
    commanded = _commanded_columns(sec, setup, res, terms) or [fk["nominal"][pid] for pid in ids]
    pairs = None if sec.distance_pairs is None else [list(p) for p in sec.distance_pairs]
    figures = {}
    for name in ("nominal", "calibrated"):
        attained = model_attained([fk["nominal"][pid] for pid in ids], [fk[name][pid] for pid in ids], measured)
        figures[name] = iso9283_figures(ids, [pose6(P) for P in commanded], [pose6(A) for A in attained],
                                        pairs, label=name)
    return Iso9283Run(figures["nominal"], figures["calibrated"], result, res.frame)
