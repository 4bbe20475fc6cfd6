"""A meshcat window without a server: records the scene's commands and renders one self-contained HTML
page (meshcat's viewer script inlined) that replays them, plus a stepping script for the samples.
"""
from __future__ import annotations

import base64
import uuid
from importlib.util import find_spec
from pathlib import Path

import umsgpack


def viewer_script() -> Path:
    """meshcat's viewer bundle (three.js and its command handler), found without importing meshcat's package
    (which imports IPython and zmq); ImportError when the [viz] extra is not installed."""
    spec = find_spec("meshcat")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("No module named 'meshcat'", name="meshcat")
    path = Path(next(iter(spec.submodule_search_locations))) / "viewer" / "dist" / "main.min.js"
    if not path.is_file():
        raise ImportError(f"meshcat's viewer script is missing: {path}", name="meshcat")
    return path


# ---- offline meshcat window --------------------------------------------------------------------
class RecordingWindow:
    """A meshcat window without a server: keeps the latest command per path, renders static HTML."""

    def __init__(self):
        self.nodes: dict[str, dict] = {}

    def send(self, command) -> None:
        """A command lowered to its dict (robocal.viz.three_objects.Node), or meshcat's command object."""
        if isinstance(command, dict):
            data = command
        else:
            if hasattr(command, "object"):
                _stable_ids(command.object, command.path.lower())
            data = command.lower()
        path, kind = data["path"], data["type"]
        if kind == "delete":
            for p in [p for p in self.nodes if p == path or p.startswith(path + "/")]:
                del self.nodes[p]
            return
        node = self.nodes.setdefault(path, {"object": None, "transform": None, "properties": {}})
        packed = umsgpack.packb(data)
        if kind == "set_object":
            node["object"], node["properties"] = packed, {}
        elif kind == "set_transform":
            node["transform"] = packed
        elif kind == "set_property":
            node["properties"][data["property"]] = packed

    def commands(self) -> list[bytes]:
        """Objects before their properties and transforms, parents before children."""
        out = []
        for path in sorted(self.nodes, key=lambda p: p.count("/")):
            n = self.nodes[path]
            out += [c for c in (n["object"], *n["properties"].values(), n["transform"]) if c is not None]
        return out

    def get_scene(self, overlay: str = "", script: str = "") -> str:
        js = viewer_script().read_text(encoding="utf-8")
        cmds = ",\n".join(f'"{base64.b64encode(c).decode()}"' for c in self.commands())
        return _PAGE.format(mainjs=js, commands=cmds, overlay=overlay, script=script)


def _stable_ids(obj, path: str) -> None:
    """meshcat gives every object a time-based uuid; ids derived from the path make pages reproducible."""
    for k, el in enumerate((obj, getattr(obj, "geometry", None), getattr(obj, "material", None))):
        if el is not None and hasattr(el, "uuid"):
            el.uuid = str(uuid.uuid5(uuid.NAMESPACE_URL, f"{path}#{k}"))


_PAGE = """<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>robocal visual check</title>
<style>body{{margin:0;font-family:sans-serif}}#meshcat-pane{{width:100vw;height:100vh;overflow:hidden}}
#robocal-legend{{position:fixed;left:8px;bottom:8px;background:rgba(255,255,255,.88);padding:6px 10px;
border-radius:4px;font-size:12px;line-height:1.5;max-width:420px}}
.bar{{display:inline-block;width:90px;height:9px;vertical-align:middle;
background:linear-gradient(to right,#1a994f,#fce08c,#d63026)}}
.dot{{display:inline-block;width:9px;height:9px;vertical-align:middle}}</style></head>
<body><div id="meshcat-pane"></div>{overlay}
<script>{mainjs}</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
function robocalDecode(b64) {{
  var s = atob(b64), a = new Uint8Array(s.length);
  for (var i = 0; i < s.length; i++) a[i] = s.charCodeAt(i);
  return a;
}}
[{commands}].forEach(function (c) {{ viewer.handle_command_bytearray(robocalDecode(c)); }});
{script}
</script></body></html>
"""

# Stepping through samples in the static page: per-sample transforms and visibility, applied with
# meshcat's own command handler. The first sample shown can be chosen with #sample=K in the URL.
STEP_SCRIPT = """
var robocalSteps = {steps};
var robocalSample = 0;
function robocalShow(k) {{
  var n = robocalSteps.length; robocalSample = ((k % n) + n) % n;
  var st = robocalSteps[robocalSample];
  for (var p in st.T) viewer.handle_command({{type: "set_transform", path: p, matrix: new Float32Array(st.T[p])}});
  for (var p in st.V) viewer.handle_command({{type: "set_property", path: p, property: "visible", value: st.V[p]}});
  document.getElementById("robocal-sample").textContent = st.label;
}}
var m = /sample=(\\d+)/.exec(window.location.hash);
robocalShow(m ? parseInt(m[1]) : {start});
"""


# ---- helpers --------------------------------------------------------------------------------------
