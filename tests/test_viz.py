"""The meshcat scene: what is drawn where, arrow scaling, colours, sample stepping, the static page."""
import json
import re

import numpy as np
import pytest

from robocal.viz import RecordingWindow, SceneView, arrows, colour_scale, nice_factor, write_static_html
from test_viz_scene_data import all_types_scene, demo_result_dir

ROOT = "/meshcat/robocal"


def _view(meshes=False, scene=None):
    view = SceneView(scene or all_types_scene(), meshes=meshes)
    view.draw(0)
    return view


def test_every_block_draws_points_arrows_and_its_artefact():
    view = _view()
    nodes = view.window.nodes
    for b in view.scene["blocks"]:
        for part in ("measured", "predicted_before", "predicted_after", "residual_before", "residual_after"):
            assert nodes[f"{ROOT}/measurements/{b['name']}/{part}"]["object"] is not None, (b["name"], part)
    art = {"table": ["after"], "ball": ["after"], "bore": ["after"], "dbb": ["after/ball", "after/bars"],
           "laser": ["after/fixed_point", "after/beams"]}
    for name, parts in art.items():
        for part in parts:
            assert nodes[f"{ROOT}/artefacts/{name}/{part}"]["object"] is not None, (name, part)
    # the initial artefacts are there but hidden
    assert "visible" in nodes[f"{ROOT}/artefacts/table/before"]["properties"]


def test_skeleton_without_meshes_and_meshes_from_the_urdf():
    simple = _view(meshes=False).window.nodes
    links = [lk["name"] for lk in all_types_scene()["robot"]["links"]]
    assert all(simple[f"{ROOT}/robot/{lk}/joint"]["object"] is not None for lk in links)
    assert not any("/visual" in p for p in simple)
    meshed = _view(meshes=True).window.nodes
    visuals = [p for p in meshed if p.startswith(f"{ROOT}/robot/") and "/visual" in p]
    assert len(visuals) == 7                       # UR5: one .dae per link
    assert all(meshed[p]["object"] is not None and meshed[p]["transform"] is not None for p in visuals)
    assert b"_meshfile_object" in meshed[visuals[0]]["object"] or b"dae" in meshed[visuals[0]]["object"]


def test_missing_urdf_falls_back_to_simple_shapes():
    scene = json.loads(json.dumps(all_types_scene()))
    scene["robot"]["urdf_path"] = "/nonexistent/robot.urdf"
    nodes = _view(meshes=True, scene=scene).window.nodes
    assert not any("/visual" in p for p in nodes)
    assert f"{ROOT}/robot/shoulder_link/joint" in nodes


def test_sample_commands_put_links_at_their_recorded_poses_and_mark_the_current_measurement():
    view = _view()
    scene = view.scene
    plane = next(b for b in scene["blocks"] if b["name"] == "table")
    k = plane["samples"][2]
    T, V = view.sample_commands(k)
    np.testing.assert_allclose(T[f"{ROOT}/robot/wrist_3_link"], view.pose("after", k, "wrist_3_link"))
    np.testing.assert_allclose(T[f"{ROOT}/robot_before/wrist_3_link"], view.pose("before", k, "wrist_3_link"))
    assert not np.allclose(T[f"{ROOT}/robot/wrist_3_link"], view.sample_commands(0)[0][f"{ROOT}/robot/wrist_3_link"])
    assert V[f"{ROOT}/current/table"] and not V[f"{ROOT}/current/tracker"]
    np.testing.assert_allclose(T[f"{ROOT}/current/table"][:3, 3], plane["measured_after"][2][0])
    with pytest.raises(IndexError):
        view.show_sample(len(scene["values"]))


def test_show_sample_sends_the_transforms_to_the_viewer():
    view = _view()
    view.show_sample(5)
    node = view.window.nodes[f"{ROOT}/robot/forearm_link"]
    T = view.pose("after", 5, "forearm_link")
    import umsgpack
    sent = np.array(umsgpack.unpackb(node["transform"])["matrix"]).reshape(4, 4).T
    np.testing.assert_allclose(sent, T, atol=1e-6)


def test_arrow_scale_and_colours():
    assert nice_factor(37.0) == 20.0 and nice_factor(0.6) == 0.5 and nice_factor(1234) == 1000
    c = colour_scale(np.array([0.0, 0.5, 1.0, 3.0]), 1.0)
    assert c[0, 1] > c[0, 0] and c[2, 0] > c[2, 1]      # green at zero, red at the top
    np.testing.assert_allclose(c[3], c[2])               # clipped above vmax
    view = _view()
    for s in ("before", "after"):
        # the largest arrow is drawn between 3 % and 8 % of the scene's size whatever the residual size
        drawn = view.arrow_scale[s] * view.arrow_max[s] / view.size
        assert 0.03 <= drawn <= 0.08 + 1e-12, (s, drawn)
    assert view.arrow_max["before"] > 20 * view.arrow_max["after"]


def test_arrow_geometry():
    start = np.array([[0.0, 0, 0], [1.0, 1, 1]])
    vec = np.array([[0.1, 0, 0], [0, 0, 0.2]])
    pos, col = arrows(start, vec, np.ones((2, 3)))
    assert pos.shape == (3, 12) and col.shape == (3, 12)
    np.testing.assert_allclose(pos[:, 0], start[0])
    np.testing.assert_allclose(pos[:, 1], start[0] + vec[0], atol=1e-7)
    # barbs end at the tip and are shorter than the shaft
    for j in (2, 4):
        np.testing.assert_allclose(pos[:, j + 1], start[0] + vec[0], atol=1e-7)
        assert np.linalg.norm(pos[:, j] - pos[:, j + 1]) < 0.1
    assert arrows(start, np.zeros((2, 3)), np.ones((2, 3)))[0].shape[1] == 0


def test_static_page_is_self_contained_and_steps_through_samples(tmp_path):
    view = SceneView(all_types_scene(), meshes=False)
    page = view.static_html(sample=3)
    assert "<script src" not in page and "http://" not in page.split("<script>")[0]
    assert "MeshCat.Viewer" in page and "robocalShow" in page
    steps = json.loads(re.search(r"var robocalSteps = (\[.*?\]);\n", page).group(1))
    assert len(steps) == len(all_types_scene()["values"])
    assert steps[3]["label"].startswith("sample 4 /")
    n_cmds = len(view.window.commands())
    assert n_cmds > 50 and page.count('"') > 2 * n_cmds
    out = write_static_html(all_types_scene(), tmp_path / "scene.html", meshes=False)
    assert out.stat().st_size > 500_000      # the three.js bundle alone is 850 kB


def test_recording_window_keeps_the_last_command_per_path_and_deletes_subtrees():
    import meshcat
    import meshcat.geometry as mg
    w = RecordingWindow()
    vis = meshcat.Visualizer(window=w)
    vis["a/b"].set_object(mg.Sphere(0.1))
    vis["a/b"].set_transform(np.eye(4))
    vis["a/b"].set_transform(2 * np.eye(4))
    vis["a/c"].set_object(mg.Box([1, 1, 1]))
    assert len(w.commands()) == 3
    vis["a"].delete()
    assert w.commands() == []


def test_demo_result_scene_draws_pose_blocks():
    from robocal.viz.scene import read_scene
    view = _view(scene=read_scene(demo_result_dir()))
    assert view.window.nodes[f"{ROOT}/measurements/tracker/residual_after"]["object"] is not None
    assert f"{ROOT}/frames/tool0" in view.window.nodes


def test_sample_label_shows_the_position_residual_in_mm():
    from robocal.viz.scene import read_scene
    scene = read_scene(demo_result_dir())
    view = SceneView(scene, meshes=False)
    r = np.array(scene["blocks"][0]["residual_after"][4])
    label = view.sample_label(4)
    assert label.startswith("sample 5 / 60") and f"-> {1e3 * np.linalg.norm(r[:3]):.3g} mm" in label


def test_pose_blocks_draw_triads_with_the_rotation_error_magnified():
    from robocal.viz.scene import read_scene
    import umsgpack
    view = _view(scene=read_scene(demo_result_dir()))
    b = view.scene["blocks"][0]
    nodes = view.window.nodes
    base = f"{ROOT}/measurements/tracker"
    assert "visible" in nodes[f"{base}/triad_before"]["properties"]          # before: hidden at first
    pos = {}
    for part in ("measured", "after"):
        obj = umsgpack.unpackb(nodes[f"{base}/triad_{part}"]["object"])
        arr = obj["object"]["geometries"][0]["data"]["attributes"]["position"]["array"]    # a msgpack Ext
        pos[part] = np.frombuffer(arr.data, np.float32).reshape(-1, 2, 3)
    assert len(pos["measured"]) == 3 * len(b["samples"])                   # three axes per measured pose
    np.testing.assert_allclose(pos["after"][:, 0], pos["measured"][:, 0], atol=1e-6)   # same origins
    # the angle between measured and predicted x axes is the magnified rotation residual (small angles)
    k = int(np.argmax(np.linalg.norm(np.array(b["residual_after"])[:, 3:], axis=1)))
    u, v = (pos[p][3 * k, 1] - pos[p][3 * k, 0] for p in ("measured", "after"))
    angle = np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1))
    r = np.array(b["residual_after"][k][3:])
    x = pos["measured"][3 * k, 1] - pos["measured"][3 * k, 0]
    expected = view.rotation_scale["after"] * np.linalg.norm(np.cross(r, x / np.linalg.norm(x)))
    assert view.rotation_scale["after"] > 1 and abs(angle - expected) < 0.05 * expected + 1e-4


def test_pose_matrices_are_those_of_each_pose():
    """The placements drawn (all samples and frames at once) are Pinocchio's, pose by pose."""
    from robocal.viz.shapes import pose_matrices, se3_from_pose7
    p7 = np.array(all_types_scene()["poses"]["after"])
    T = pose_matrices(p7)
    for i in range(0, len(p7), 7):
        for f in range(p7.shape[1]):
            np.testing.assert_allclose(T[i, f], se3_from_pose7(p7[i, f]).homogeneous, rtol=0, atol=1e-14)
