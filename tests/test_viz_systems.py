"""Every system of the specs can be viewed: a small synthetic (or shipped) result of each builds a scene and
its static page, with its points drawn and, for parallel machines, the loops closed and the struts ending
on their closure anchors at every sample."""
import json
import re
from pathlib import Path

import numpy as np

from robocal import load_urdf
from robocal.estimation.calibrate import calibrate
from robocal.workflows.setup import load_config
from robocal.systems.laser_psd.calibration import calibrate_laser, zero_offset_problem
from robocal.systems.pcmm import error_model as pe
from robocal.systems.pcmm.machine import (reference_artefact, reference_geometry, reference_placements, reference_raw,
                                     simulate_probing)
from robocal.model.parameters import ParameterSet, offset_parameter, placement_parameters
from robocal.systems.pcmm.calibration import calibrate_pcmm, pcmm_problem
from robocal.estimation.problem import Problem
from robocal.residuals import PoseResidual
from robocal.viz.scene import read_scene, scene_bytes
from robocal.systems.pcmm.scene import write_pcmm_scene
from robocal.design.simulate import perturb, simulate_measurements
from robocal.viz.meshcat_check import SceneView
from robocal.viz.shapes import se3_from_pose7

import laser_psd_cases as lc

ROOT = "/meshcat/robocal"
REPO = Path(__file__).resolve().parents[1]


def _world(scene, state, i, link, p):
    M = se3_from_pose7(scene["poses"][state][i][scene["frames"].index(link)])
    return M.act(np.asarray(p, float))


def check_closed_chain(scene):
    """Anchors coincide (1e-9) in every sample and state, and a skeleton segment of each side ends on it."""
    assert scene["robot"]["closed_chain"] and scene["robot"]["closures"]
    for state in ("before", "after"):
        segs = scene["robot"]["skeleton"][state]["segments"]
        for c in scene["robot"]["closures"]:
            for i in range(len(scene["values"])):
                a1, a2 = (_world(scene, state, i, f, np.zeros(3)) for f in c["frames"])
                assert np.linalg.norm(a1 - a2) < 1e-9, (c["name"], state, i)
                for link in c["links"]:
                    ends = [_world(scene, state, i, lk, p) for a, pa, b, pb, _ in segs
                            for lk, p in ((a, pa), (b, pb)) if lk == link]
                    assert min(np.linalg.norm(e - a1) for e in ends) < 1e-9, (c["name"], link, state, i)


def check_view(scene, n_points):
    """The static page has one step per sample and every block's points and arrows are drawn."""
    view = SceneView(scene, meshes=False)
    page = view.static_html()
    steps = json.loads(re.search(r"var robocalSteps = (\[.*?\]);\n", page).group(1))
    assert len(steps) == len(scene["values"])
    drawn = 0
    for b in scene["blocks"]:
        node = view.window.nodes[f"{ROOT}/measurements/{b['name']}/measured"]
        assert node["object"] is not None and view.window.nodes[f"{ROOT}/measurements/{b['name']}/residual_before"]
        drawn += np.array(b["measured_after"]).reshape(-1, 3).shape[0]
    assert drawn == n_points
    return view


def test_stewart_platform_struts_end_on_their_anchors():
    from test_viz_closed_loop import stewart_scene
    scene = stewart_scene()
    check_closed_chain(scene)
    view = check_view(scene, len(scene["values"]))
    # the struts change length per sample: world-level nodes placed by every step
    moving = [p for p, _, _ in view.moving]
    assert len(moving) >= 12 and all(f"{ROOT}/{p}" in view.sample_commands(3)[0] for p in moving)
    # no skeleton segment runs from the base's origin (z = 0, far below its joints) or along the floating joint
    segs = scene["robot"]["skeleton"]["after"]["segments"]
    assert not any("platform" in (a, b) and "base" in (a, b) for a, _, b, _, _ in segs)
    assert not any(a == "base" and np.allclose(pa, 0) for a, pa, _, _, _ in segs)


def test_pcmm_calibration_scene(tmp_path):
    nominal, art = reference_geometry(), reference_artefact()
    true = pe.reduce(pe.random_raw_errors(reference_raw(), np.random.default_rng(3)), nominal)
    cen, yaw = reference_placements()
    hits = simulate_probing(true, art, cen[:4], yaw[:4], np.random.default_rng(4), n_hits=5)
    cal = calibrate_pcmm(nominal, hits, art)
    scene = read_scene(write_pcmm_scene(cal, hits, art, tmp_path))
    check_closed_chain(scene)
    view = check_view(scene, len(hits.readings))
    b = scene["blocks"][0]
    assert b["type"] == "sphere_artefact" and len(b["terms"]) == 4 and len(b["terms"][0]) == 20
    # the URDF model at the scene's parameters is the fast path's machine exactly, before and after
    np.testing.assert_allclose(np.ravel(b["residual_before"]), pcmm_problem(nominal, hits, art).evaluate().raw,
                               atol=1e-10)
    assert np.abs(b["residual_after"]).max() < 1e-10 < np.abs(b["residual_before"]).max()
    # each hit's arrow is its radial error against the certified sphere about the fitted centre
    m, p = np.array(b["measured_before"][0]), np.array(b["predicted_before"][0])
    c = np.array(b["artefact_before"]["centres"][0][0])
    np.testing.assert_allclose(np.linalg.norm(m[:5] - c, axis=1), art.radii[0] + nominal.tip_radius, atol=1e-12)
    assert np.abs(np.cross(p[:5] - m[:5], p[:5] - c)).max() < 1e-12         # the arrow points along the radius
    assert len(b["artefact_after"]["centres"]) == 4
    assert view.window.nodes[f"{ROOT}/artefacts/artefact/after/placement3/sphere3"]["object"] is not None
    # stepping marks the current hit and names its placement
    T, V = view.sample_commands(7)
    np.testing.assert_allclose(T[f"{ROOT}/current/artefact"][:3, 3], b["measured_after"][0][7])
    assert view.sample_label(7).startswith("sample 8 / 80; artefact: |r|")


def test_floating_nut_hexapod_scene():
    robot = load_urdf(REPO / "urdf" / "floating_nut_hexapod.urdf")
    act = robot.loops.actuated
    ps = ParameterSet()
    for j in act:
        ps.add(offset_parameter(j, "m"))
    for p in placement_parameters("frame_placement", "platform"):
        p.vary = False
        ps.add(p)
    rng = np.random.default_rng(5)
    n = 10
    values = rng.uniform(-0.02, 0.02, (n, 6))
    problem = Problem(robot, ps, act, values, [PoseResidual("tracker", "platform", np.arange(n),
                                                            np.tile([0, 0, 0, 0, 0, 0, 1.0], (n, 1)),
                                                            sigma=(1e-5, 1e-5))])
    simulate_measurements(problem, perturb(problem.params, rng, 1e-3, 1e-3), rng)
    before = problem.params.copy()
    scene = json.loads(scene_bytes(problem, calibrate(problem), before))
    check_closed_chain(scene)
    view = check_view(scene, n)
    assert view.window.nodes[f"{ROOT}/measurements/tracker/triad_after"]["object"] is not None


def test_laser_psd_scene():
    problem = zero_offset_problem(lc.robot(), lc.joints(), lc.exact_readings("three_fans"), lc.MOUNT)
    before = problem.params.copy()
    laser = calibrate_laser(problem, lc.MOUNT)
    scene = json.loads(scene_bytes(problem, laser.result, before))
    n = len(problem.values)
    view = check_view(scene, n)
    b = scene["blocks"][0]
    assert b["type"] == "laser_line" and len(b["beam_origin_after"]) == n
    assert view.window.nodes[f"{ROOT}/artefacts/psd/after/beams"]["object"] is not None
    assert np.abs(b["residual_after"]).max() < 1e-3 * np.abs(b["residual_before"]).max()


def test_tiago_mocap_scene():
    setup = load_config(REPO / "examples" / "tiago_mocap" / "hand_offsets.yaml")
    before = setup.problem.params.copy()
    scene = json.loads(scene_bytes(setup, calibrate(setup.problem, setup.options), before))
    assert not scene["robot"]["closed_chain"]
    check_view(scene, 4 * len(scene["values"]))            # the hand's four points per posture
