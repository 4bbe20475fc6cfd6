"""The meshcat visual check: the robot at each sample, measured vs predicted, the artefacts.

`SceneView(scene)` draws a scene (robocal.scene_data) into a meshcat Visualizer: a live one (the CLI
starts the server) or, by default, an offline recorder whose `static_html()` is a self-contained page
(meshcat's three.js bundle, meshes and commands inlined; opens from a file without a server).

Drawn under /meshcat/robocal:
  robot/<link>            after calibration: URDF visual meshes (simple shapes when there are none)
  robot_before/<link>     before calibration: a thin orange skeleton
  frames/<frame>          triads on the measured frames
  measurements/<block>/   points measured (dark), predicted before (orange) / after (blue), residual
                          arrows before / after, each scaled for visibility and coloured by size
  artefacts/<block>/      plane, sphere, cylinder, ball bar (fixed ball and bars), laser (beams, fixed point)
  current/<block>         a marker on the current sample's measurement
Every pose comes from the scene's per-sample link poses (SampleState.pose), so closed-chain machines are
drawn with their loops closed without any special case here.
"""
from __future__ import annotations

import html
import json
import logging
from pathlib import Path

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin

from .meshcat_page import STEP_SCRIPT, RecordingWindow
from .residuals.base import basis_from_normal

log = logging.getLogger(__name__)

ROOT = "robocal"
COLOURS = {"measured": 0x202020, "before": 0xff8c00, "after": 0x1f77b4, "robot": 0x8ca6c0,
           "current": 0xd000d0, "artefact": 0x6fa86f, "laser": 0xe02020, "steel": 0xa0a0a0}
# Residual colour scale (fraction of the largest residual -> RGB): green, yellow, red.
SCALE_STOPS = np.array([[0.0, 0.10, 0.60, 0.31], [0.5, 0.99, 0.88, 0.55], [1.0, 0.84, 0.19, 0.15]])
ARROW_FRACTION = 0.08      # the largest arrow is drawn this fraction of the scene's size


def _se3(p7) -> pin.SE3:
    x, y, z, qx, qy, qz, qw = p7
    return pin.SE3(pin.Quaternion(qw, qx, qy, qz).toRotationMatrix(), np.array([x, y, z]))


def colour_scale(values: np.ndarray, vmax: float) -> np.ndarray:
    """(n, 3) RGB in [0, 1] for |values| on the green-yellow-red scale from 0 to vmax."""
    f = np.clip(np.abs(np.asarray(values, float)) / vmax, 0.0, 1.0) if vmax > 0 else np.zeros(len(values))
    return np.column_stack([np.interp(f, SCALE_STOPS[:, 0], SCALE_STOPS[:, c]) for c in (1, 2, 3)])


def nice_factor(x: float) -> float:
    """The largest 1-2-5 x 10^k not above x (arrow magnification reads as a round number)."""
    if not np.isfinite(x) or x <= 0:
        return 1.0
    e = np.floor(np.log10(x))
    m = x / 10 ** e
    return float((5 if m >= 5 else 2 if m >= 2 else 1) * 10 ** e)


def arrows(start: np.ndarray, vec: np.ndarray, colours: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Line-segment vertices (3, 6n) and colours of arrows start -> start + vec (shaft and two barbs)."""
    pos, col = [], []
    for a, v, c in zip(start, vec, colours):
        length = np.linalg.norm(v)
        if length == 0:
            continue
        u = v / length
        side = np.cross(u, [0.0, 0.0, 1.0] if abs(u[2]) < 0.9 else [1.0, 0.0, 0.0])
        side /= np.linalg.norm(side)
        tip = a + v
        for b in (a, tip - 0.25 * length * u + 0.1 * length * side, tip - 0.25 * length * u - 0.1 * length * side):
            pos += [b, tip]
            col += [c, c]
    return np.array(pos, np.float32).reshape(-1, 3).T, np.array(col, np.float32).reshape(-1, 3).T


def _points_object(points: np.ndarray, colour: int, size: float):
    return mg.Points(mg.PointsGeometry(points.T.astype(np.float32)), mg.PointsMaterial(size=size, color=colour))


def _segments_object(pos: np.ndarray, col: np.ndarray | None = None, colour: int = 0xffffff):
    return mg.LineSegments(mg.PointsGeometry(pos, col),
                           mg.LineBasicMaterial(color=colour, vertexColors=col is not None))


def _segment_transform(a: np.ndarray, b: np.ndarray, radius_scale: float = 1.0) -> np.ndarray:
    """4x4 taking meshcat's unit cylinder (axis y, centred) onto the segment a -> b."""
    d = b - a
    # basis_from_normal gives a rotation with z along d; Rx(90 deg) brings y onto z.
    R = basis_from_normal(d) @ pin.rpy.rpyToMatrix(np.pi / 2, 0, 0)
    T = np.eye(4)
    T[:3, :3] = R @ np.diag([radius_scale, np.linalg.norm(d), radius_scale])
    T[:3, 3] = (a + b) / 2
    return T


# ---- robot geometry -------------------------------------------------------------------------------
def load_visuals(robot_info: dict) -> list[tuple[str, object, object, np.ndarray]]:
    """[(link, meshcat geometry, material, 4x4 placement in the link frame)] from the URDF's visuals.

    Empty when the URDF cannot be read or has no visual elements: the caller then draws simple shapes.
    """
    from .robot import load_urdf

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
        if isinstance(geom, mg.MeshGeometry):
            T = T @ np.diag([*g.meshScale, 1.0])
        colour = int(np.dot((np.clip(g.meshColor[:3], 0, 1) * 255).astype(int), [65536, 256, 1]))
        mat = mg.MeshPhongMaterial(color=colour, opacity=float(g.meshColor[3]))
        out.append((frame.name, geom, mat, T))
    return out


def _meshcat_geometry(g):
    path = g.meshPath or ""
    ext = Path(path).suffix.lower()
    if ext in (".dae", ".stl", ".obj") and Path(path).is_file():
        return {".dae": mg.DaeMeshGeometry, ".stl": mg.StlMeshGeometry, ".obj": mg.ObjMeshGeometry}[ext].from_file(path)
    shape = g.geometry
    kind = type(shape).__name__
    if kind == "Box":
        return mg.Box(2 * np.asarray(shape.halfSide))
    if kind == "Sphere":
        return mg.Sphere(shape.radius)
    if kind in ("Cylinder", "Capsule"):
        return _ZCylinder(2 * shape.halfLength, shape.radius)
    return None


class _ZCylinder(mg.Cylinder):
    """URDF cylinders lie along z; meshcat's along y."""

    def intrinsic_transform(self):
        T = np.eye(4)
        T[:3, :3] = pin.rpy.rpyToMatrix(np.pi / 2, 0, 0)
        return T


# ---- the scene ------------------------------------------------------------------------------------
class SceneView:
    """Draw a robocal scene into meshcat and step through its samples.

    scene: the dict of robocal.scene_data (read_scene); vis: a meshcat Visualizer (None: offline recorder);
    meshes: use the URDF's visual meshes when it has them (False: simple shapes, a much smaller page).
    """

    def __init__(self, scene: dict, vis: meshcat.Visualizer | None = None, meshes: bool = True):
        self.scene = scene
        self.window = RecordingWindow() if vis is None else None
        self.vis = meshcat.Visualizer(window=self.window) if vis is None else vis
        self.root = self.vis[ROOT]
        self.frames = {f: i for i, f in enumerate(scene["frames"])}
        self.links = [lk["name"] for lk in scene["robot"]["links"]]
        self.n_samples = len(scene["values"])
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
        self.meshes = meshes
        self.drawn = False

    def pose(self, state: str, sample: int, frame: str) -> np.ndarray:
        return _se3(self.scene["poses"][state][sample][self.frames[frame]]).homogeneous

    # ---- drawing -------------------------------------------------------------------------------
    def draw(self, sample: int = 0) -> "SceneView":
        self.root.delete()
        visuals = load_visuals(self.scene["robot"]) if self.meshes else []
        if visuals:
            for k, (link, geom, mat, T) in enumerate(visuals):
                node = self.root["robot"][link][f"visual{k}"]
                node.set_object(geom, mat)
                node.set_transform(T)
        else:
            self._skeleton("robot", COLOURS["robot"], 0.025, 1.0)
        self._skeleton("robot_before", COLOURS["before"], 0.008, 0.6)
        for f in dict.fromkeys(b["frame"] for b in self.scene["blocks"] if b["frame"]):
            self.root["frames"][f].set_object(mg.triad(0.05))
        for b in self.scene["blocks"]:
            self._measurements(b)
            self._artefact(b)
        self._camera()
        self.drawn = True
        self.show_sample(sample)
        return self

    def _skeleton(self, name: str, colour: int, radius: float, opacity: float) -> None:
        """Spheres at link origins, cylinders to the child links (geometry taken at sample 0)."""
        mat = mg.MeshLambertMaterial(color=colour, opacity=opacity)
        state = "after" if name == "robot" else "before"
        for lk in self.scene["robot"]["links"]:
            node = self.root[name][lk["name"]]
            node["joint"].set_object(mg.Sphere(1.6 * radius), mat)
            if lk["parent"] is None:
                continue
            rel = np.linalg.inv(self.pose(state, 0, lk["parent"])) @ self.pose(state, 0, lk["name"])
            if np.linalg.norm(rel[:3, 3]) > 1e-6:
                seg = self.root[name][lk["parent"]][f"to_{lk['name']}"]
                seg.set_object(mg.Cylinder(1.0, radius), mat)
                seg.set_transform(_segment_transform(np.zeros(3), rel[:3, 3]))
        # closed chains: each closure's anchors are drawn as a joint with arms from both links' origins
        # (a Stewart platform's plate appears as the arms from its origin to the strut ends)
        for c in self.scene["robot"].get("closures", []):
            for frame, link in zip(c["frames"], c["links"]):
                if link not in self.links:
                    continue
                rel = np.linalg.inv(self.pose(state, 0, link)) @ self.pose(state, 0, frame)
                node = self.root[name][link][f"closure_{c['name']}_{frame}"]
                if np.linalg.norm(rel[:3, 3]) > 1e-6:
                    node.set_object(mg.Cylinder(1.0, 0.6 * radius), mat)
                    node.set_transform(_segment_transform(np.zeros(3), rel[:3, 3]))
            self.root[name][c["links"][1]][f"closure_{c['name']}_joint"].set_object(mg.Sphere(1.4 * radius), mat)
            anchor = np.linalg.inv(self.pose(state, 0, c["links"][1])) @ self.pose(state, 0, c["frames"][1])
            self.root[name][c["links"][1]][f"closure_{c['name']}_joint"].set_transform(anchor)

    def _measurements(self, b: dict) -> None:
        node = self.root["measurements"][b["name"]]
        meas = np.array(b["measured_after"]).reshape(-1, 3)
        if not len(meas):
            return
        size = 0.006 * max(self.size, 0.5)
        node["measured"].set_object(_points_object(meas, COLOURS["measured"], size))
        for s in ("before", "after"):
            m = np.array(b[f"measured_{s}"]).reshape(-1, 3)
            p = np.array(b[f"predicted_{s}"]).reshape(-1, 3)
            node[f"predicted_{s}"].set_object(_points_object(p, COLOURS[s], size))
            err = np.linalg.norm(p - m, axis=1)
            pos, col = arrows(m, self.arrow_scale[s] * (p - m), colour_scale(err, self.arrow_max[s]))
            if pos.size:
                node[f"residual_{s}"].set_object(_segments_object(pos, col))
        node["predicted_before"].set_property("visible", False)
        self.root["current"][b["name"]].set_object(mg.Sphere(0.012 * max(self.size, 0.5)),
                                                   mg.MeshLambertMaterial(color=COLOURS["current"], opacity=0.5))

    def _artefact(self, b: dict) -> None:
        for s in ("after", "before"):
            a = b.get(f"artefact_{s}")
            if not a:
                continue
            node = self.root["artefacts"][b["name"]][s]
            meas = np.array(b[f"measured_{s}"]).reshape(-1, 3)
            pred = np.array(b[f"predicted_{s}"]).reshape(-1, 3)
            mat = mg.MeshLambertMaterial(color=COLOURS["artefact"], opacity=0.45 if s == "after" else 0.2)
            kind = a["kind"]
            if kind == "plane":
                R = basis_from_normal(a["normal"])
                local = (meas - meas.mean(axis=0)) @ R
                span = np.ptp(local[:, :2], axis=0) + 0.1
                T = np.eye(4)
                T[:3, :3], T[:3, 3] = R, meas.mean(axis=0)
                node.set_object(mg.Box([span[0], span[1], 0.001]), mat)
                node.set_transform(T)
            elif kind == "sphere":
                node.set_object(mg.Sphere(a["radius"]), mg.MeshLambertMaterial(color=COLOURS["steel"]))
                node.set_transform(pin.SE3(np.eye(3), np.array(a["centre"])).homogeneous)
            elif kind == "cylinder":
                p0, u = np.array(a["point"]), np.array(a["direction"])
                t = (meas - p0) @ u
                node.set_object(mg.Cylinder(1.0, 1.0), mat)
                node.set_transform(_segment_transform(p0 + (t.min() - 0.05) * u, p0 + (t.max() + 0.05) * u,
                                                      a["radius"]))
            elif kind == "ball_bar":
                c = np.array(a["centre"])
                node["ball"].set_object(mg.Sphere(0.011), mg.MeshLambertMaterial(color=COLOURS["steel"]))
                node["ball"].set_transform(pin.SE3(np.eye(3), c).homogeneous)
                pos = np.column_stack([np.tile(c, (len(pred), 1)), pred]).reshape(-1, 3).T.astype(np.float32)
                node["bars"].set_object(_segments_object(pos, colour=0x606060))
            elif kind == "laser_line":
                P, o = np.array(a["target"]), np.array(b[f"beam_origin_{s}"]).reshape(-1, 3)
                node["fixed_point"].set_object(mg.Sphere(0.008), mg.MeshLambertMaterial(color=COLOURS["laser"]))
                node["fixed_point"].set_transform(pin.SE3(np.eye(3), P).homogeneous)
                ends = o + 1.15 * (pred - o)
                pos = np.column_stack([o, ends]).reshape(-1, 3).T.astype(np.float32)
                node["beams"].set_object(_segments_object(pos, colour=COLOURS["laser"]))
            if s == "before":
                node.set_property("visible", False)

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
        for b in self.scene["blocks"]:
            if b["frame"]:
                T[f"{base}/frames/{b['frame']}"] = self.pose("after", sample, b["frame"])
            hits = [k for k, i in enumerate(b["samples"]) if i == sample]
            path = f"{base}/current/{b['name']}"
            V[path] = bool(hits) and bool(b["measured_after"])
            if V[path]:
                T[path] = pin.SE3(np.eye(3), np.mean(b["measured_after"][hits[0]], axis=0)).homogeneous
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
        parts = []
        for b in self.scene["blocks"]:
            for k, i in enumerate(b["samples"]):
                if i == sample:
                    length = np.array(b["row_units"]) == "length"     # mm only: pose blocks also hold angles
                    r0, r1 = (np.linalg.norm(np.array(b[f"residual_{s}"][k])[length]) for s in ("before", "after"))
                    parts.append(f"{b['name']}: |r| {1e3 * r0:.3g} -> {1e3 * r1:.3g} mm")
        return f"sample {sample + 1} / {self.n_samples}" + ("; " + "; ".join(parts) if parts else "")

    # ---- static page ---------------------------------------------------------------------------
    def legend_html(self) -> str:
        rows = [f'<b>robocal visual check</b>: {html.escape(self.scene["robot"]["name"])}, '
                f'{self.n_samples} samples. <span id="robocal-sample"></span>',
                '<button onclick="robocalShow(robocalSample-1)">&#9664; previous</button> '
                '<button onclick="robocalShow(robocalSample+1)">next &#9654;</button>',
                '<span class="dot" style="background:#202020"></span> measured '
                '<span class="dot" style="background:#1f77b4"></span> predicted after '
                '<span class="dot" style="background:#ff8c00"></span> predicted before (hidden: toggle in the '
                'meshcat menu) &middot; orange skeleton: robot before calibration']
        for s in ("before", "after"):
            rows.append(f'residual {s}: <span class="bar"></span> 0 &ndash; {1e3 * self.arrow_max[s]:.3g} mm, '
                        f'arrows &times;{self.arrow_scale[s]:g}')
        return '<div id="robocal-legend">' + "<br>".join(rows) + "</div>"

    def static_html(self, sample: int = 0) -> str:
        """A self-contained page of the scene (offline recorder only), with sample stepping."""
        if self.window is None:
            return self.vis.static_html()
        if not self.drawn:
            self.draw(sample)
        steps = []
        for i in range(self.n_samples):
            T, V = self.sample_commands(i)
            steps.append({"T": {p: np.round(M.T.reshape(-1), 7).tolist() for p, M in T.items()}, "V": V,
                          "label": self.sample_label(i)})
        script = STEP_SCRIPT.format(steps=json.dumps(steps, separators=(",", ":")), start=int(sample))
        return self.window.get_scene(overlay=self.legend_html(), script=script)


def write_static_html(scene: dict, path: str | Path, meshes: bool = True, sample: int = 0) -> Path:
    """Write the self-contained scene page; returns its path."""
    path = Path(path)
    path.write_text(SceneView(scene, meshes=meshes).static_html(sample), encoding="utf-8")
    return path
