"""The scene's shapes as meshcat viewer commands, without importing meshcat's Python package.

meshcat's package imports IPython and zmq for its live viewer (0.25-0.4 s of every report and `robocal view
--html`), while a static page needs only the commands its viewer script replays: three.js objects (format 4.5)
packed with msgpack. This module writes the same commands as meshcat.geometry and meshcat.commands for the
shapes the visual check draws, under the same names (Box, Sphere, Cylinder, PointsGeometry, Points,
LineSegments, the materials, triad). `Node` is the path tree (`node["a/b"].set_object(...)`) that sends them to
a window: robocal.viz.meshcat_page.RecordingWindow for a page, `LiveWindow` for a running meshcat server.
Object ids derive from the node's path, so the same scene gives the same bytes.
"""
from __future__ import annotations

import uuid
from pathlib import Path

import numpy as np
import umsgpack

FLOAT32, UINT8 = 0x17, 0x12         # msgpack extension codes of meshcat's typed arrays


def typed_array(x: np.ndarray) -> dict:
    """A (k, n) array as a three.js buffer attribute (float32, column after column, as meshcat packs it)."""
    x = np.asarray(x, np.float32)
    return {"itemSize": 1 if x.ndim == 1 else x.shape[0], "type": "Float32Array",
            "array": umsgpack.Ext(FLOAT32, x.tobytes("F")), "normalized": False}


# ---- geometries -----------------------------------------------------------------------------------
class Geometry:
    kind = ""

    def fields(self) -> dict:
        return {}

    def intrinsic_transform(self) -> np.ndarray:
        return np.eye(4)

    def lower(self, uid: str) -> dict:
        return {"uuid": uid, "type": self.kind, **self.fields()}


class Box(Geometry):
    kind = "BoxGeometry"

    def __init__(self, lengths):
        self.lengths = [float(v) for v in lengths]

    def fields(self):
        return {"width": self.lengths[0], "height": self.lengths[1], "depth": self.lengths[2]}


class Sphere(Geometry):
    kind = "SphereGeometry"

    def __init__(self, radius: float):
        self.radius = float(radius)

    def fields(self):
        return {"radius": self.radius, "widthSegments": 20, "heightSegments": 20}


class Cylinder(Geometry):
    """Axis along y (three.js); `axis="z"` turns it onto z (a URDF cylinder)."""
    kind = "CylinderGeometry"

    def __init__(self, height: float, radius: float = 1.0, axis: str = "y"):
        self.height, self.radius, self.axis = float(height), float(radius), axis

    def fields(self):
        return {"radiusTop": self.radius, "radiusBottom": self.radius, "height": self.height, "radialSegments": 50}

    def intrinsic_transform(self):
        T = np.eye(4)
        if self.axis == "z":          # rotation by +90 deg about x: y -> z
            T[1:3, 1:3] = [[0.0, -1.0], [1.0, 0.0]]
        return T


class PointsGeometry(Geometry):
    """(3, n) positions and optional (3, n) RGB colours in [0, 1]."""
    kind = "BufferGeometry"

    def __init__(self, position, color=None):
        self.position, self.color = position, color

    def fields(self):
        attrs = {"position": typed_array(self.position)}
        if self.color is not None:
            attrs["color"] = typed_array(self.color)
        return {"data": {"attributes": attrs}}


class MeshFile(Geometry):
    """A mesh file the viewer parses itself (.dae, .obj as text; .stl as bytes)."""
    kind = "_meshfile"

    def __init__(self, path: str | Path):
        path = Path(path)
        self.format = path.suffix.lower().lstrip(".")
        self.data = (umsgpack.Ext(UINT8, path.read_bytes()) if self.format == "stl"
                     else path.read_text(encoding="utf-8", errors="replace"))

    def lower(self, uid: str) -> dict:
        return {"type": self.kind, "uuid": uid, "format": self.format, "data": self.data}   # meshcat's key order


# ---- materials ------------------------------------------------------------------------------------
class Material:
    kind = ""

    def __init__(self, color: int = 0xffffff, opacity: float = 1.0, vertexColors: bool = False):
        self.color, self.opacity, self.vertex_colors = int(color), float(opacity), vertexColors

    def lower(self, uid: str) -> dict:
        return {"uuid": uid, "type": self.kind, "color": self.color, "reflectivity": 0.5, "side": 2,
                "transparent": self.opacity != 1, "opacity": self.opacity, "linewidth": 1.0, "wireframe": False,
                "wireframeLinewidth": 1.0, "vertexColors": 2 if self.vertex_colors else 0}


class MeshPhongMaterial(Material):
    kind = "MeshPhongMaterial"


class MeshLambertMaterial(Material):
    kind = "MeshLambertMaterial"


class LineBasicMaterial(Material):
    kind = "LineBasicMaterial"


class PointsMaterial(Material):
    kind = "PointsMaterial"

    def __init__(self, size: float = 0.001, color: int = 0xffffff):
        super().__init__(color)
        self.size = float(size)

    def lower(self, uid: str) -> dict:
        return {"uuid": uid, "type": self.kind, "color": self.color, "size": self.size, "vertexColors": 2}


# ---- objects --------------------------------------------------------------------------------------
class Object:
    kind = "Mesh"

    def __init__(self, geometry: Geometry, material: Material | None = None):
        self.geometry, self.material = geometry, material if material is not None else MeshPhongMaterial()

    def lower(self, path: str) -> dict:
        ids = [str(uuid.uuid5(uuid.NAMESPACE_URL, f"{path}#{k}")) for k in range(3)]
        return {"metadata": {"version": 4.5, "type": "Object"},
                "geometries": [self.geometry.lower(ids[1])], "materials": [self.material.lower(ids[2])],
                "object": {"uuid": ids[0], "type": self.kind, "geometry": ids[1], "material": ids[2],
                           "matrix": self.geometry.intrinsic_transform().flatten().tolist()}}


class Mesh(Object):
    kind = "Mesh"


class Points(Object):
    kind = "Points"


class LineSegments(Object):
    kind = "LineSegments"


def triad(scale: float = 1.0) -> LineSegments:
    """The x, y, z axes as red, green, blue segments of length `scale`."""
    ends = np.zeros((3, 6), np.float32)
    ends[[0, 1, 2], [1, 3, 5]] = scale
    colours = np.array([[1, 0, 0], [1, 0.6, 0], [0, 1, 0], [0.6, 1, 0], [0, 0, 1], [0, 0.6, 1]], np.float32).T
    return LineSegments(PointsGeometry(ends, colours), LineBasicMaterial(vertexColors=True))


# ---- the path tree --------------------------------------------------------------------------------
class Node:
    """One path of the scene tree; `node["a/b"]` is a child path, a leading "/" starts from the root.
    Commands go to `window.send(dict)` (the meshcat command, lowered)."""

    __slots__ = ("window", "path")

    def __init__(self, window, path: tuple[str, ...] = ("meshcat",)):
        self.window, self.path = window, path

    def __getitem__(self, name: str) -> "Node":
        path = () if name.startswith("/") else self.path
        return Node(self.window, path + tuple(p for p in name.split("/") if p))

    def path_str(self) -> str:
        return "/" + "/".join(self.path)

    def set_object(self, geometry: Geometry | Object, material: Material | None = None) -> None:
        if not isinstance(geometry, Object):
            geometry = (Points if isinstance(material, PointsMaterial) else Mesh)(geometry, material)
        path = self.path_str()
        self.window.send({"type": "set_object", "object": geometry.lower(path), "path": path})

    def set_transform(self, matrix: np.ndarray) -> None:
        self.window.send({"type": "set_transform", "path": self.path_str(),
                          "matrix": np.asarray(matrix, float).T.flatten().tolist()})

    def set_property(self, key: str, value) -> None:
        self.window.send({"type": "set_property", "path": self.path_str(), "property": key.lower(), "value": value})

    def delete(self) -> None:
        self.window.send({"type": "delete", "path": self.path_str()})


class LiveWindow:
    """Sends the commands to a running meshcat server through a meshcat.Visualizer (`robocal view`)."""

    def __init__(self, visualizer):
        self.visualizer = visualizer

    def send(self, data: dict) -> None:
        self.visualizer.window.send(Lowered(data))


class Lowered:
    """A command already lowered, in the shape meshcat's window expects (an object with lower())."""

    __slots__ = ("data",)

    def __init__(self, data: dict):
        self.data = data

    def lower(self) -> dict:
        return self.data
