"""The scene of a parallel-CMM self-calibration (`robocal.systems.pcmm.calibration.calibrate_pcmm`).

The calibration's problem computes the tips in closed form (its parameters are the reduced ones, not
placements of a model to draw), so the scene is built from the equivalent URDF problem: the URDF of the
nominal machine (robocal.systems.pcmm.machine.build_urdf, loops closed by
robocal's assembly), the sphere-artefact residual over the same hits, and placement parameters whose
values make the URDF model the nominal (before) and the identified (after) machine exactly: each slide
joint's placement is moved by log6 of its nominal-to-identified change (position and tilt), each loop
anchor by its b_i or l_i change. The identification summary is the calibration's (rank 27 of 32).

    write_pcmm_scene(calibration, hits, artefact, "out/")    # then: robocal view out/ --html scene.html
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal.systems.pcmm.machine import Artefact, ProbeHits, urdf_configuration, write_urdf
from robocal.systems.pcmm.kinematics import N_REDUCED, PCMMGeometry
from robocal.model.parameters import ParameterSet, placement_parameters
from robocal.estimation.problem import Problem
from robocal.residuals.sphere_artefact import SphereArtefactResidual
from robocal.model.robot import load_urdf
from robocal.viz.scene import scene_data

RESIDUAL = "artefact"


def _slide(geo: PCMMGeometry, i: int) -> pin.SE3:
    """limb i's slide joint origin as the URDF writes it: at A_i, rotated Rx(alpha) Ry(beta)."""
    al, be = geo.tilts[i]
    return pin.SE3(pin.utils.rotate("x", al) @ pin.utils.rotate("y", be), np.asarray(geo.columns[i], float))


def pcmm_parameters(nominal: PCMMGeometry, geo: PCMMGeometry) -> ParameterSet:
    """Placement parameters that turn the URDF of `nominal` into `geo` exactly (all zero for geo = nominal)."""
    ps = ParameterSet()
    for i in range(4):
        limb = f"limb{i + 1}"
        deltas = {f"{limb}_slide": pin.log6(_slide(nominal, i).inverse() * _slide(geo, i)).vector,
                  f"{limb}_top.link2": np.r_[geo.platform_joints[i] - nominal.platform_joints[i], np.zeros(3)],
                  f"{limb}_top.link1": np.r_[0.0, 0.0, geo.lengths[i] - nominal.lengths[i], np.zeros(3)]}
        for target, delta in deltas.items():
            kind = "joint_placement" if target.endswith("_slide") else "frame_placement"
            for p in placement_parameters(kind, target):
                p.value = float(delta[p.index])
                ps.add(p)
    return ps


def urdf_problem(nominal: PCMMGeometry, geo: PCMMGeometry, hits: ProbeHits, artefact: Artefact, urdf_path,
                 poses: np.ndarray | None = None) -> Problem:
    """The generic problem of the hits with the model at `geo`; writes the nominal URDF to `urdf_path`.

    poses: (N, 4) platform poses of the hits (warm starts for the loop assembly), e.g. the fast path's FK.
    """
    robot = load_urdf(write_urdf(nominal, urdf_path))
    res = SphereArtefactResidual(RESIDUAL, "probe_tip", hits.groups(), artefact.radii, artefact.distances,
                                 tip_radius=nominal.tip_radius)
    problem = Problem(robot, pcmm_parameters(nominal, geo), robot.loops.actuated, hits.readings, [res])
    if poses is not None:
        for i, (y, r) in enumerate(zip(poses, hits.readings)):
            problem.warm_starts[i] = urdf_configuration(robot, geo, y, r)
    return problem


def pcmm_scene_data(calibration, hits: ProbeHits, artefact: Artefact, urdf_path) -> dict:
    """The scene (robocal.viz.scene layout) of a PCMMCalibration: before = nominal, after = identified."""
    poses = calibration.poses
    problem = urdf_problem(calibration.nominal, calibration.geometry, hits, artefact, urdf_path, poses)
    s = np.asarray(calibration.singular_values, float)
    rank = int(calibration.rank)
    ident = {"singular_values": s.tolist(), "rank": rank, "requested": N_REDUCED, "rtol": None,
             "condition": float(s[0] / s[rank - 1]) if rank else float("inf")}
    return scene_data(problem, None, pcmm_parameters(calibration.nominal, calibration.nominal), ident)


def write_pcmm_scene(calibration, hits: ProbeHits, artefact: Artefact, folder) -> Path:
    """Write <folder>/scene.json (and the nominal URDF it refers to, pcmm_4puu.urdf); returns scene.json."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    scene = pcmm_scene_data(calibration, hits, artefact, folder / "pcmm_4puu.urdf")
    path = folder / "scene.json"
    path.write_text(json.dumps(scene, separators=(",", ":")), encoding="utf-8")
    return path
