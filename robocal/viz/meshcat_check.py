"""The meshcat visual check: the robot at each sample, measured vs predicted, the artefacts.

`SceneView(scene)` draws a scene (robocal.viz.scene) into a meshcat Visualizer: a live one (the CLI
starts the server) or, by default, an offline recorder whose `static_html()` is a self-contained page
(meshcat's three.js bundle, meshes and commands inlined; opens from a file without a server). The shapes are
written as meshcat commands by robocal.viz.three_objects: a page never imports meshcat's Python package.

Drawn under /meshcat/robocal:
  robot/<link>            after calibration: URDF visual meshes, or the skeleton (robocal.viz.skeleton)
  robot_before/<link>     before calibration: a thin orange skeleton
  robot*/moving/          skeleton segments whose length or direction changes per sample (struts)
  frames/<frame>          triads on the measured frames
  measurements/<block>/   points measured (dark), predicted before (orange) / after (blue), residual
                          arrows before / after, each scaled for visibility and coloured by size; pose
                          blocks: triads (robocal.viz.measurements)
  artefacts/<block>/      the measurement artefacts (robocal.viz.artefacts)
  camera/<block>/         a camera's frustum, target and the current image's rays (robocal.viz.camera_view)
  current/<block>         a marker on the current sample's measurement
Every pose comes from the scene's per-sample link poses (SampleState.pose), so closed-chain machines are
drawn with their loops closed without any special case here.
"""
from __future__ import annotations

import html
import json
import logging
from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal.viz import three_objects as three
from robocal.viz.meshcat_page import STEP_SCRIPT, RecordingWindow
from robocal.viz.scene import samples_phrase, upgrade
from robocal.viz.artefacts import draw_artefact
from robocal.viz.camera_view import camera_commands, draw_camera
from robocal.viz.measurements import current_point, draw_measurements, label_parts, rotation_scale
from robocal.viz.shapes import ARROW_FRACTION, COLOURS, nice_factor, pose_matrices
from robocal.viz.skeleton import draw_skeleton, segment_at
from robocal.model.robot import load_urdf

log = logging.getLogger(__name__)

ROOT = "robocal"


# ---- robot geometry -------------------------------------------------------------------------------
def load_visuals(robot_info: dict) -> list[tuple[str, object, object, np.ndarray]]:
    """[(link, meshcat geometry, material, 4x4 placement in the link frame)] from the URDF's visuals.

    Empty when the URDF cannot be read or has no visual elements: the caller then draws simple shapes.
    """

    path = robot_info.get("urdf_path")
    if not path or not Path(path).is_file():
        log.warning("URDF %s not found: drawing the robot with simple shapes", path)
        return []
    try:
        robot = load_urdf(path, package_dirs=robot_info.get("package_dirs", []))
        gm = pin.buildGeomFromUrdf(robot.model, str(path), pin.GeometryType.VISUAL,
                                   package_dirs=robot.package_dirs)
    except (ValueError, RuntimeError) as exc:
        log.warning("cannot load the visual geometry of %s (%s): drawing simple shapes", path, exc)
        return []
    out = []
    for g in gm.geometryObjects:
        frame = robot.model.frames[g.parentFrame]
        geom = _meshcat_geometry(g)
        if geom is None:
            log.info("visual %s: geometry %s not drawn", g.name, type(g.geometry).__name__)
            continue
        T = (frame.placement.inverse() * g.placement).homogeneous
        if isinstance(geom, three.MeshFile):
            T = T @ np.diag([*g.meshScale, 1.0])
        colour = int(np.dot((np.clip(g.meshColor[:3], 0, 1) * 255).astype(int), [65536, 256, 1]))
        mat = three.MeshPhongMaterial(color=colour, opacity=float(g.meshColor[3]))
        out.append((frame.name, geom, mat, T))
    return out


def _meshcat_geometry(g):
    path = g.meshPath or ""
    ext = Path(path).suffix.lower()
    if ext in (".dae", ".stl", ".obj") and Path(path).is_file():
        return three.MeshFile(path)
    shape = g.geometry
    kind = type(shape).__name__
    if kind == "Box":
        return three.Box(2 * np.asarray(shape.halfSide))
    if kind == "Sphere":
        return three.Sphere(shape.radius)
    if kind in ("Cylinder", "Capsule"):
        return three.Cylinder(2 * shape.halfLength, shape.radius, axis="z")     # URDF: along z; three.js: y
    return None


# ---- the scene ------------------------------------------------------------------------------------
class SceneView:
    """Draw a robocal scene into meshcat and step through its samples.

    scene: the dict of robocal.viz.scene (read_scene); vis: a live meshcat.Visualizer (None: offline recorder);
    meshes: use the URDF's visual meshes when it has them (False: simple shapes, a much smaller page).
    """

    def __init__(self, scene: dict, vis=None, meshes: bool = True):
        self.scene = upgrade(scene)
        self.window = RecordingWindow() if vis is None else None
        self.vis = three.Node(self.window if vis is None else three.LiveWindow(vis))
        self.root = self.vis[ROOT]
        self.frames = {f: i for i, f in enumerate(scene["frames"])}
        self.links = [lk["name"] for lk in scene["robot"]["links"]]
        self.n_samples = len(scene["values"])
        # every (sample, frame) placement as a 4x4, once: drawing and stepping read them thousands of times
        self.matrices = {s: pose_matrices(np.asarray(self.scene["poses"][s], float)) for s in ("before", "after")}
        pts = [np.array(b["measured_after"]).reshape(-1, 3) for b in scene["blocks"]]
        origins = np.array(scene["poses"]["after"])[:, :, :3].reshape(-1, 3)
        cloud = np.vstack(pts + [origins])
        self.size = float(max(np.ptp(cloud, axis=0).max(), 0.2))
        self.centre = (cloud.min(axis=0) + cloud.max(axis=0)) / 2
        self.arrow_scale, self.arrow_max = {}, {}
        for s in ("before", "after"):
            mx = max([np.linalg.norm(np.array(b[f"predicted_{s}"]) - np.array(b[f"measured_{s}"]), axis=-1).max()
                      for b in scene["blocks"] if b[f"measured_{s}"]] + [0.0])
            self.arrow_max[s] = float(mx)
            self.arrow_scale[s] = nice_factor(ARROW_FRACTION * self.size / mx) if mx > 0 else 1.0
        self.rotation_max, self.rotation_scale = {}, {}
        for s in ("before", "after"):
            self.rotation_max[s], self.rotation_scale[s] = rotation_scale(scene["blocks"], s)
        self.moving: list[tuple] = []
        self.meshes = meshes
        self.drawn = False

    def pose(self, state: str, sample: int, frame: str) -> np.ndarray:
        return self.matrices[state][sample, self.frames[frame]]

    def poses(self, state: str, frame: str) -> np.ndarray:
        """(samples, 4, 4) placements of one frame."""
        return self.matrices[state][:, self.frames[frame]]

    # ---- drawing -------------------------------------------------------------------------------
    def draw(self, sample: int = 0) -> "SceneView":
        self.root.delete()
        visuals = load_visuals(self.scene["robot"]) if self.meshes else []
        if visuals:
            for k, (link, geom, mat, T) in enumerate(visuals):
                node = self.root["robot"][link][f"visual{k}"]
                node.set_object(geom, mat)
                node.set_transform(T)
        self.moving = [] if visuals else draw_skeleton(self, "robot", "after", COLOURS["robot"], 0.025, 1.0)
        self.moving += draw_skeleton(self, "robot_before", "before", COLOURS["before"], 0.008, 0.6)
        for f in dict.fromkeys(b["frame"] for b in self.scene["blocks"] if b["frame"]):
            self.root["frames"][f].set_object(three.triad(0.05))
        for b in self.scene["blocks"]:
            draw_measurements(self, b)
            draw_artefact(self, b)
            if "camera" in b:
                draw_camera(self, b)
        self._camera()
        self.drawn = True
        self.show_sample(sample)
        return self

    def _camera(self) -> None:
        # meshcat's camera orbits the origin and this meshcat has no command to move its target, so the
        # scene is shifted to put its centre there (a parallel machine may sit far from the world origin).
        self.root.set_transform(pin.SE3(np.eye(3), -self.centre).homogeneous)
        # meshcat's camera lives in a y-up frame: (x, y, z)_robot -> (x, z, -y).
        d = 0.8 * self.size
        eye = d * np.array([1.0, 0.7, 0.6])
        self.vis["/Cameras/default/rotated/<object>"].set_property("position", [eye[0], eye[2], -eye[1]])
        # meshcat's floor grid renders misleadingly in a perspective far from it; the axes give the scale
        self.vis["/Grid"].set_property("visible", False)

    # ---- stepping ------------------------------------------------------------------------------
    def sample_commands(self, sample: int) -> tuple[dict[str, np.ndarray], dict[str, bool]]:
        """Transforms {node path: 4x4} and visibilities {node path: bool} that show one sample."""
        base = f"/meshcat/{ROOT}"
        T, V = {}, {}
        for name, state in (("robot", "after"), ("robot_before", "before")):
            for link in self.links:
                T[f"{base}/{name}/{link}"] = self.pose(state, sample, link)
        for path, state, ends in self.moving:
            T[f"{base}/{path}"] = segment_at(self, state, sample, ends)
        for b in self.scene["blocks"]:
            if b["frame"]:
                T[f"{base}/frames/{b['frame']}"] = self.pose("after", sample, b["frame"])
            point = current_point(b, sample)
            path = f"{base}/current/{b['name']}"
            V[path] = point is not None
            if point is not None:
                T[path] = pin.SE3(np.eye(3), point).homogeneous
            if "camera" in b:
                Tc, Vc = camera_commands(self, b, sample, base)
                T.update(Tc)
                V.update(Vc)
        return T, V

    def show_sample(self, sample: int) -> None:
        """Put the robot (before and after) in the pose of one sample and mark its measurements."""
        if not 0 <= sample < self.n_samples:
            raise IndexError(f"sample {sample} is outside 0..{self.n_samples - 1}")
        if not self.drawn:
            self.draw(sample)
            return
        T, V = self.sample_commands(sample)
        for path, M in T.items():
            self.vis[path].set_transform(M)
        for path, v in V.items():
            self.vis[path].set_property("visible", v)

    def sample_label(self, sample: int) -> str:
        parts = [p for b in self.scene["blocks"] for p in label_parts(b, sample)]
        drawn = self.scene.get("drawn")
        where = (f"sample {drawn['samples'][sample] + 1} of {drawn['of']} (drawn {sample + 1} / {self.n_samples})"
                 if drawn else f"sample {sample + 1} / {self.n_samples}")
        return where + ("; " + "; ".join(parts) if parts else "")

    # ---- static page ---------------------------------------------------------------------------
    def legend_html(self) -> str:
        rows = [f'<b>robocal visual check</b>: {html.escape(self.scene["robot"]["name"])}, '
                f'{samples_phrase(self.scene)}. <span id="robocal-sample"></span>',
                '<button onclick="robocalShow(robocalSample-1)">&#9664; previous</button> '
                '<button onclick="robocalShow(robocalSample+1)">next &#9654;</button>',
                '<span class="dot" style="background:#202020"></span> measured '
                '<span class="dot" style="background:#1f77b4"></span> predicted after '
                '<span class="dot" style="background:#ff8c00"></span> predicted before (hidden: toggle in the '
                'meshcat menu) &middot; orange skeleton: robot before calibration']
        for s in ("before", "after"):
            rows.append(f'residual {s}: <span class="bar"></span> 0 &ndash; {1e3 * self.arrow_max[s]:.3g} mm, '
                        f'arrows &times;{self.arrow_scale[s]:g}')
        if any("camera" in b for b in self.scene["blocks"]):
            rows.append("camera: frustum (grey lines) and target (board); the current image's rays through each "
                        "detected corner, measured points on them at the corner's depth, arrows to the reprojected "
                        "corners (the pixel error carried to the target)")
        if any(b["type"] == "pose" for b in self.scene["blocks"]):
            rows.append("pose triads: measured (red, green, blue axes), predicted after (blue) / before (orange, "
                        "hidden); rotation errors &times;" + ", &times;".join(
                            f"{self.rotation_scale[s]:g} ({s}, up to {1e3 * self.rotation_max[s]:.3g} mrad)"
                            for s in ("after", "before")))
        return '<div id="robocal-legend">' + "<br>".join(rows) + "</div>"

    def static_html(self, sample: int = 0) -> str:
        """A self-contained page of the scene (offline recorder only), with sample stepping."""
        if self.window is None:
            return self.vis.window.visualizer.static_html()
        if not self.drawn:
            self.draw(sample)
        steps = []
        for i in range(self.n_samples):
            T, V = self.sample_commands(i)
            columns = np.round(np.stack(list(T.values())).transpose(0, 2, 1).reshape(len(T), 16), 7).tolist()
            steps.append({"T": dict(zip(T, columns)), "V": V, "label": self.sample_label(i)})
        script = STEP_SCRIPT.format(steps=json.dumps(steps, separators=(",", ":")), start=int(sample))
        return self.window.get_scene(overlay=self.legend_html(), script=script)


def write_static_html(scene: dict, path: str | Path, meshes: bool = True, sample: int = 0) -> Path:
    """Write the self-contained scene page; returns its path."""
    path = Path(path)
    path.write_text(SceneView(scene, meshes=meshes).static_html(sample), encoding="utf-8")
    return path
