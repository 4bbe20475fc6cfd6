"""scene.json: what the visual checks draw must agree with the residuals the fit used.

Also holds the calibrated cases the other visual-check tests share (test_viz, test_report, test_browser).
"""
import atexit
import json
import shutil
import tempfile
from functools import lru_cache
from importlib.resources import files
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from robocal import load_example
from robocal.estimation.calibrate import calibrate
from robocal.errors import InputError
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import (BallBarResidual, CylinderResidual, LaserLineResidual, PlaneResidual, PointResidual,
                               SphereResidual)
from robocal.viz.scene import VERSION, link_tree, read_scene, scene_bytes, scene_data
from robocal.design.simulate import perturb, random_configurations, simulate_measurements

ARTEFACT_TYPES = ("plane", "sphere", "cylinder", "ball_bar", "laser_line")


@lru_cache(maxsize=1)
def all_types_case():
    """UR5 + tcp probe: tracker points and every artefact type, perturbed truth, calibrated.

    Returns (problem after the fit, result, parameters before the fit).
    """
    rng = np.random.default_rng(1)
    robot = load_example("ur5")
    robot.add_frame("tcp", "tool0", pin.SE3(np.eye(3), np.array([0, 0, 0.05])))
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tcp": True}, base=False)
    n_pt, n_c = 20, 6
    q = list(random_configurations(robot, joints, n_pt, rng, span=0.5))
    res = [PointResidual("tracker", "tcp", np.arange(n_pt), np.zeros((n_pt, 3)), sigma=2e-5)]
    makers = [lambda i: PlaneResidual("table", "tcp", i, normal=(0, 0, 1), offset=0.1, tip_radius=0.003),
              lambda i: SphereResidual("ball", "tcp", i, centre=(0.4, 0.2, 0.2), radius=0.0125),
              lambda i: CylinderResidual("bore", "tcp", i, axis_point=(0.3, -0.3, 0), axis_direction=(0, 0, 1),
                                         radius=0.02),
              lambda i: BallBarResidual("dbb", "tcp", i, np.zeros(n_c), centre=(0.3, 0.0, 0.2), offset=0.15),
              lambda i: LaserLineResidual("laser", "tcp", i, target=(0.5, 0.3, 0.2), direction=(0, 0, 1))]
    for make in makers:
        res.append(make(np.arange(len(q), len(q) + n_c)))
        q += list(random_configurations(robot, joints, n_c, rng, span=0.5))
    problem = Problem(robot, params, joints, np.array(q), res)
    truth = perturb(problem.params, rng, 1e-3, np.radians(0.1))
    simulate_measurements(problem, truth, rng)
    before = problem.params.copy()
    result = calibrate(problem)
    return problem, result, before


@lru_cache(maxsize=1)
def all_types_scene() -> dict:
    problem, result, before = all_types_case()
    return json.loads(scene_bytes(problem, result, before))


_TMP = tempfile.mkdtemp(prefix="robocal-viz-tests-")
atexit.register(shutil.rmtree, _TMP, True)


@lru_cache(maxsize=1)
def demo_result_dir() -> Path:
    """The output folder of the demo config (UR5, 60 tracker poses), with scene.json, as `robocal calibrate` will write it."""
    from robocal.workflows.setup import load_config
    from robocal.workflows.outputs import write_results

    setup = load_config(files("robocal.io") / "demo" / "ur5_calibrate.yaml")
    before = setup.problem.params.copy()
    result = calibrate(setup.problem, setup.options)
    out = Path(_TMP) / "demo"
    write_results(setup.robot, result, out, extra={"scene.json": scene_bytes(setup, result, before)})
    return out


# ---- tests ------------------------------------------------------------------------------------------
def test_every_block_type_is_recorded_with_points_and_artefact():
    scene = all_types_scene()
    types = {b["type"]: b for b in scene["blocks"]}
    assert set(types) == {"point", *ARTEFACT_TYPES}
    for t in ARTEFACT_TYPES:
        assert types[t]["artefact_after"]["kind"] == t
    for b in scene["blocks"]:
        for s in ("before", "after"):
            assert np.array(b[f"measured_{s}"]).shape == (len(b["samples"]), 1, 3)
            assert np.array(b[f"predicted_{s}"]).shape == (len(b["samples"]), 1, 3)


def test_drawn_residual_arrow_is_the_residual_the_fit_used():
    """|predicted - measured| of every drawn pair equals the residual norm, for every type, before and after."""
    scene = all_types_scene()
    for b in scene["blocks"]:
        for s in ("before", "after"):
            arrow = np.linalg.norm(np.array(b[f"predicted_{s}"]) - np.array(b[f"measured_{s}"]), axis=-1).ravel()
            r = np.linalg.norm(np.array(b[f"residual_{s}"]), axis=1)
            np.testing.assert_allclose(arrow, r, rtol=1e-9, atol=1e-12, err_msg=f"{b['name']} {s}")
        # the fit worked, so the picture must show it: residuals shrink by at least 20x in every block
        assert np.max(np.abs(b["residual_after"])) < np.max(np.abs(b["residual_before"])) / 20, b["name"]


def test_poses_are_the_sample_states_of_the_parameters_before_and_after():
    problem, _, before = all_types_case()
    scene = all_types_scene()
    fi = scene["frames"].index("wrist_3_link")
    for state, params in (("before", before), ("after", problem.params)):
        ms = ModelState(problem.robot, params, problem.joint_names)
        for i in (0, 17, len(problem.values) - 1):
            M = ms.sample(problem.values[i]).pose("wrist_3_link")
            p7 = scene["poses"][state][i][fi]
            np.testing.assert_allclose(p7[:3], M.translation, atol=1e-12)
            R = pin.Quaternion(p7[6], *p7[3:6]).toRotationMatrix()
            np.testing.assert_allclose(R, M.rotation, atol=1e-12)
    # before and after differ by the calibration (mm), not by nothing
    moved = np.array(scene["poses"]["after"])[:, fi, :3] - np.array(scene["poses"]["before"])[:, fi, :3]
    assert 1e-4 < np.abs(moved).max() < 2e-2


def test_identification_data_match_the_result():
    _, result, _ = all_types_case()
    ident = all_types_scene()["identification"]
    assert ident["rank"] == result.selection.rank < ident["requested"] == len(result.requested)
    assert len(ident["singular_values"]) == len(result.requested)


def test_link_tree_of_ur5_is_a_chain_from_the_root():
    links = link_tree(load_example("ur5"))
    parent = {lk["name"]: lk["parent"] for lk in links}
    chain, link = [], "wrist_3_link"
    while link is not None:
        chain.append(link)
        link = parent[link]
    assert chain[-1] == links[0]["name"] and "shoulder_link" in chain and len(chain) >= 7


def test_scene_data_accepts_a_config_setup_and_round_trips(tmp_path):
    folder = demo_result_dir()
    scene = read_scene(folder)
    assert scene["robot"]["name"] == "ur5" and len(scene["values"]) == 60
    assert [b["type"] for b in scene["blocks"]] == ["pose"]
    assert len(scene["blocks"][0]["orientation_after"]) == 60


def test_read_scene_reports_bad_files(tmp_path):
    with pytest.raises(InputError, match="no scene.json") as e:
        read_scene(tmp_path)
    assert e.value.source.endswith("scene.json")
    bad = tmp_path / "scene.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON") as e:
        read_scene(bad)
    assert e.value.row == 1
    bad.write_text(json.dumps({"format": "other"}))
    with pytest.raises(InputError) as e:
        read_scene(bad)
    assert e.value.field == "format"
    good = dict(all_types_scene())
    good["poses"] = {"before": [], "after": good["poses"]["after"]}
    bad.write_text(json.dumps(good))
    with pytest.raises(InputError) as e:
        read_scene(bad)
    assert e.value.field == "poses.before"


def test_scene_data_is_deterministic():
    problem, result, before = all_types_case()
    assert scene_data(problem, result, before) == scene_data(problem, result, before)


def test_version_1_scene_files_still_open(tmp_path):
    """A scene written before the skeleton and `terms` existed reads, draws and steps."""
    from robocal.viz.meshcat_check import SceneView
    old = json.loads(json.dumps(all_types_scene()))
    old["version"] = 1
    del old["robot"]["skeleton"]
    for b in old["blocks"]:
        del b["terms"]
    (tmp_path / "scene.json").write_text(json.dumps(old))
    scene = read_scene(tmp_path)
    assert scene["version"] == VERSION and all(b["terms"] == [[i] for i in b["samples"]] for b in scene["blocks"])
    segs = scene["robot"]["skeleton"]["after"]["segments"]
    assert len(segs) == len(scene["robot"]["links"]) - 1           # link origins joined to their parents
    view = SceneView(scene, meshes=False)
    assert view.sample_label(3).startswith("sample 4 /") and len(view.static_html()) > 500_000


def test_a_large_fit_draws_evenly_spaced_samples_numbered_in_the_scene(monkeypatch):
    """Beyond MAX_SAMPLES the scene draws that many evenly spaced samples: each drawn pose and each kept
    term's residual is the full scene's for the same problem sample, terms point at drawn samples only,
    and the scene says which samples of how many these are."""
    import robocal.viz.scene as scene_module
    problem, result, before = all_types_case()
    full = scene_data(problem, result, before)
    n = len(problem.values)
    monkeypatch.setattr(scene_module, "MAX_SAMPLES", 9)
    part = scene_data(problem, result, before)
    drawn = part["drawn"]["samples"]
    assert part["drawn"]["of"] == n and len(drawn) == len(part["values"]) == 9
    assert drawn[0] == 0 and drawn[-1] == n - 1 and drawn == sorted(set(drawn))
    assert "drawn" not in full
    for s in ("before", "after"):
        np.testing.assert_allclose(part["poses"][s], np.array(full["poses"][s])[drawn], atol=1e-12)
    np.testing.assert_array_equal(part["values"], np.array(full["values"])[drawn])
    kept_terms = 0
    for bf, bp in zip(full["blocks"], part["blocks"]):
        for terms, row in zip(bp["terms"], bp["residual_after"]):
            assert all(0 <= t < 9 for t in terms)
            original = [drawn[t] for t in terms]
            k = bf["terms"].index(original)
            np.testing.assert_allclose(row, bf["residual_after"][k], atol=1e-12)
            kept_terms += 1
        # every term of the full scene whose samples were all drawn is kept
        assert len(bp["terms"]) == sum(all(t in drawn for t in terms) for terms in bf["terms"])
    assert kept_terms > 0
    assert scene_module.scene_note(problem).startswith(f"scene.json (the 3D check and the report's point plots) "
                                                       f"draws 9 of the {n} samples")


def test_session_poses_drawn_in_each_session_frame(monkeypatch):
    """Two sessions with the tracker re-registered: the batched scene poses equal each sample's state (its pose in
    its own session's measurement frame) before and after, as the per-sample path draws them."""
    from pathlib import Path
    from robocal.estimation.calibrate import calibrate
    from robocal.viz import scene as scene_module
    from robocal.workflows.setup import load_config
    setup = load_config(Path(__file__).parents[1] / "examples" / "tiago_mocap" / "select_hand_sessions.yaml")
    problem = setup.problem
    before = problem.params.copy()
    calibrate(problem, setup.options)
    assert max(abs(problem.params[n].value) for n in problem.params.names if "@" in n) > 1e-3
    batched = scene_module.scene_data(problem, None, before, ident={})
    monkeypatch.setattr(scene_module, "supports_batch", lambda ms: False)
    per_sample = scene_module.scene_data(problem, None, before, ident={})
    for state in ("before", "after"):
        np.testing.assert_allclose(batched["poses"][state], per_sample["poses"][state], atol=1e-12)
