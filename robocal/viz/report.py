"""The HTML report of a calibration: one self-contained file.

Summary table, residuals per block, parameter table, the identifiability statement in words, the plots
(robocal.viz.svg_plots, inline SVG) and the 3D scene (robocal.viz.meshcat_check, embedded as an iframe's srcdoc).
Inputs are result.json and scene.json of an output folder (or the same data in memory). Neither matplotlib nor
meshcat's Python package is imported: the page needs only meshcat's viewer script (the [viz] extra).
Lengths are shown in mm and angles in mrad; the tables say so.
"""
from __future__ import annotations

import base64
import html
import io
import json
import logging
from pathlib import Path

import numpy as np

from robocal.viz import svg_plots as plots
from robocal.errors import InputError
from robocal.viz.meshcat_check import SceneView
from robocal.viz.report_validation import evaluation_section, refusal_section
from robocal.viz.scene import read_scene, samples_phrase
from robocal.viz.svg_camera import camera_images, reprojection_panels

log = logging.getLogger(__name__)
SHOWN = {"m": (1e3, "mm"), "rad": (1e3, "mrad")}
#: where the evaluation sections sit in report.html (robocal evaluate replaces what lies between)
EVALUATIONS = ("<!--robocal:evaluations-->", "<!--/robocal:evaluations-->")


def png_base64(fn, *args, **kwargs) -> str:
    buf = io.BytesIO()
    fn(*args, buf, **kwargs)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def html_table(header: list[str], rows: list[list], cls: str) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="{cls}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def format_value(v, spec: str = ".4g") -> str:
    return "n/a" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec)


def _length_rows(block: dict, state: str) -> np.ndarray:
    """(terms, k) the block's length rows of each term, in m."""
    r = np.array(block[f"residual_{state}"], float).reshape(len(block["terms"]), -1)
    return r[:, [u == "length" for u in block["row_units"]]]


# ---- plots from the output folder's data --------------------------------------------------------
def report_plots(result: dict, scene: dict | None) -> list[tuple[str, str]]:
    """[(caption, <svg> element)] for the report."""
    out = []
    if scene:
        for b in scene["blocks"]:
            if "camera" in b:
                out += camera_figures(b)
                continue
            r0, r1 = _length_rows(b, "before"), _length_rows(b, "after")
            if r0.shape[1]:
                out.append((f"Residual per sample of block '{b['name']}' ({b['type']}): length rows, mm",
                            plots.residuals_per_sample(1e3 * np.linalg.norm(r0, axis=1), 1e3 * np.linalg.norm(r1, axis=1),
                                                       title=f"{b['name']}: residual per sample")))
        errs = {s: [np.array(b[f"predicted_{s}"]).reshape(-1, 3) - np.array(b[f"measured_{s}"]).reshape(-1, 3)
                    for b in scene["blocks"] if b[f"measured_{s}"] and "camera" not in b] for s in ("before", "after")}
        if errs["after"]:
            out.append(("Per-axis error of every drawn point (predicted - measured), measurement frame, mm",
                        plots.error_histograms(1e3 * np.vstack(errs["before"]), 1e3 * np.vstack(errs["after"]))))
    est = [p for p in result.get("parameters", []) if p.get("vary")]
    if est:
        out.append(("Estimated parameters with +-1 standard error (mm, mrad)",
                    plots.parameter_estimates([p["name"] for p in est], [p["value"] for p in est],
                                              [p.get("stderr") for p in est], units=[p.get("unit", "") for p in est])))
    ident = (scene or {}).get("identification")
    if ident and ident.get("singular_values"):
        out.append((f"Singular values of the column-scaled identification Jacobian at the start point; the "
                    f"base-parameter selection kept {ident['rank']} of {ident['requested']} parameters",
                    plots.singular_values(ident["singular_values"], min(ident["rank"], len(ident["singular_values"])))))
    return out


def camera_figures(b: dict) -> list[tuple[str, str]]:
    """A camera block's figures, both inline SVG: RMS per image before / after, and detected against reprojected
    corners in the worst images (robocal.viz.svg_camera)."""
    images = camera_images(b)
    panels, scale, shown = reprojection_panels(images, b["camera"]["image_size"], ident=b["name"],
                                               title=f"{b['name']}: detected vs reprojected corners (px)")
    caption = (f"Block '{b['name']}': detected corners (dots) and the calibrated model's reprojections (crosses) "
               f"in the {shown} image(s) with the largest RMS of {len(images)}; arrows x{scale:g}")
    return [(f"Reprojection RMS per image of block '{b['name']}' (camera), px per corner",
             plots.residuals_per_sample([im["rms_before"] for im in images], [im["rms_after"] for im in images],
                                        unit="px", title=f"{b['name']}: RMS per image")),
            (caption, panels)]


# ---- HTML ---------------------------------------------------------------------------------------
def iso9283_section(iso: dict) -> list[str]:
    """ISO 9283 pose (and distance) characteristics of the nominal and the calibrated model, in mm / mrad."""
    rows, dist = [], []
    for model in ("nominal", "calibrated"):
        for p in iso.get(model, {}).get("poses", []):
            rows.append([model, p["pose"], p["visits"], format_value(1e3 * p["AP"]),
                         ", ".join(format_value(1e3 * p[f"AP_{k}"], "+.3g") for k in "xyz"),
                         ", ".join(format_value(1e3 * p[f"AP_{k}"], "+.3g") for k in "abc"),
                         format_value(1e3 * p["RP"]), ", ".join(format_value(1e3 * p[f"RP_{k}"], ".3g") for k in "abc")])
        for d in iso.get(model, {}).get("distances", []):
            dist.append([model, " - ".join(d["poses"]), d["cycles"], format_value(1e3 * d["AD"]), format_value(1e3 * d["RD"])])
    parts = ["<h2>ISO 9283 pose characteristics (mm, mrad)</h2>",
             f"<p>Frame {html.escape(str(iso.get('frame')))}; the calibrated figures are what the same robot "
             "reaches when its controller uses the calibrated model (first order at the commanded joints).</p>",
             html_table(["model", "pose", "visits", "AP", "AP x, y, z", "AP a, b, c", "RP", "RP a, b, c"], rows, "iso9283")]
    if dist:
        parts.append(html_table(["model", "poses", "cycles", "AD", "RD"], dist, "iso9283-distance"))
    return parts


def report_html(result: dict, scene: dict | None = None, meshes: bool = True, title: str = "robocal calibration report",
                iso9283: dict | None = None) -> str:
    """The report page. `result` is result.json's content, `scene` scene.json's (None: no plots of points),
    `iso9283` iso9283.json's (None: no ISO section)."""
    ident = result.get("identifiability", {})
    summary = [["status", result.get("status")], ["solver message", result.get("message")],
               ["iterations", result.get("iterations")], ["residual rows", result.get("rows")],
               ["degrees of freedom", result.get("degrees_of_freedom")],
               ["identifiable from the data alone", f"{ident.get('identifiable_from_data')} of "
                                                     f"{ident.get('requested')} requested"],
               *[[f"class: {cls}", n] for cls, n in (ident.get("counts") or {}).items()],
               ["condition number", format_value(result.get("condition_number"), ".3g")],
               ["residual / stated sigma", format_value(result.get("sigma_ratio"), ".3f")]]
    if scene:
        summary.insert(0, ["robot", f"{scene['robot']['name']} ({samples_phrase(scene)})"])
    blocks = []
    for b0, b1 in zip(result.get("residuals_before", []), result.get("residuals_after", [])):
        fmt = lambda d: ", ".join(f"{v:.4g} {k}" for k, v in (d or {}).items())
        norm_of = ", ".join(f"{k}: {v}" for k, v in (b1.get("norm_of") or {}).items())
        blocks.append([b0["name"], b0["type"], b0["rows"], norm_of, fmt(b0.get("rms_norm")), fmt(b1.get("rms_norm")),
                       fmt(b0.get("max_norm")), fmt(b1.get("max_norm")), fmt(b1.get("rms_per_component"))])
    params = []
    classes = ident.get("classes") or {}
    for p in result.get("parameters", []):
        k, unit = SHOWN.get(p.get("unit", ""), (1.0, p.get("unit", "")))
        se, sd = p.get("stderr"), p.get("stderr_data_only")
        state = classes.get(p["name"]) or ("estimated" if p.get("vary") else "fixed by the config")
        params.append([p["name"], unit, format_value(k * p["value"], "+.5g"),
                       format_value(k * se, ".3g") if p.get("vary") and se is not None else "",
                       format_value(k * sd, ".3g") if p.get("vary") and sd is not None else
                       ("n/a" if p.get("vary") else ""), state])
    parts = [f"<h1>{html.escape(title)}</h1>", *refusal_section(result),     # what went wrong first
             "<h2>Summary</h2>", html_table(["quantity", "value"], summary, "summary"),
             "<h2>Residuals (mm, mrad)</h2>",
             "<p>RMS and maximum of the error norm (3D per point or orientation); before = the nominal robot with "
             "only the registration frames fitted (" + html.escape(", ".join(
                 (result.get("registration_before") or {}).get("parameters") or ["none"])) + ").</p>",
             html_table(["block", "type", "rows", "norm of", "RMS |e| before", "RMS |e| after", "max |e| before",
                     "max |e| after", "RMS per component after"], blocks, "residuals"),
             "<h2>Identifiability</h2>", "<ul class=\"identifiability\">"
             + "".join(f"<li>{html.escape(s)}</li>" for s in ident.get("statements", [])) + "</ul>",
             "<h2>Parameters (lengths in mm, angles in mrad)</h2>",
             "<p>Standard error: the fit's, with the prior's contribution; data alone: without it (the "
             "parameters set by the prior held; n/a: the data cannot tell it). Class: see Identifiability.</p>",
             html_table(["parameter", "unit", "value", "standard error", "data alone", "class"], params,
                        "parameters")]
    if iso9283:
        parts += iso9283_section(iso9283)
    parts.append(evaluations_html(result.get("evaluations") or []))     # robocal evaluate's files in the folder
    figures = report_plots(result, scene)
    if figures:
        parts.append("<h2>Plots</h2>")
        parts += [svg_figure(c, b) for c, b in figures]
    if scene:
        parts += scene_section(scene, meshes)
    else:
        parts.append("<p>No scene.json in this result: no 3D scene and no per-sample plots.</p>")
    return html_page(title, parts)


def scene_section(scene: dict, meshes: bool) -> list[str]:
    """The 3D scene as an iframe (meshcat's viewer; without the [viz] extra, a line that says so)."""
    try:
        page = SceneView(scene, meshes=meshes).static_html()
    except ImportError as exc:
        return [f"<h2>3D scene</h2><p>Not drawn: {html.escape(str(exc.name))} is not installed "
                "(pip install 'robocal[viz]').</p>"]
    return ["<h2>3D scene</h2><p>The robot after calibration (orange skeleton: before) at each sample; "
            "measured points, predictions and residual arrows scaled for visibility. Use the buttons to step "
            "through the samples and the meshcat menu to show or hide parts.</p>",
            f'<iframe class="scene" title="3D scene" srcdoc="{html.escape(page, quote=True)}"></iframe>']


def html_page(title: str, parts: list[str]) -> str:
    """A self-contained HTML page of the report's style holding `parts` (HTML fragments)."""
    style = ("body{font-family:sans-serif;max-width:1100px;margin:1em auto;padding:0 1em}"
             "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:2px 8px;"
             "font-size:13px;text-align:left}th{background:#eef}img{max-width:100%}"
             "iframe.scene{width:100%;height:640px;border:1px solid #ccc}figcaption{font-size:12px;color:#444}"
             "figure svg{max-width:100%;height:auto}")
    return (f"<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{style}</style></head><body>{''.join(parts)}</body></html>")


def figure_html(caption: str, png: str) -> str:
    """An embedded PNG (base64, from png_base64) with its caption."""
    return (f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{png}"><figcaption>'
            f"{html.escape(caption)}</figcaption></figure>")


def svg_figure(caption: str, svg: str) -> str:
    """An inline SVG plot (robocal.viz.svg_plots) with its caption."""
    return f"<figure>{svg}<figcaption>{html.escape(caption)}</figcaption></figure>"


def report_bytes(result, scene=None, meshes: bool = True, iso9283: dict | None = None) -> bytes:
    """report.html content for `write_results(..., extra=...)`.

    result: a CalibrationResult or its dict; scene: scene.json bytes or dict (robocal.viz.scene) or None.
    """
    if hasattr(result, "to_json"):
        result = json.loads(result.to_json())
    if isinstance(scene, (bytes, bytearray)):
        scene = json.loads(scene)
    return report_html(result, scene, meshes=meshes, iso9283=iso9283).encode("utf-8")


def read_result(folder: str | Path) -> dict:
    path = Path(folder) / "result.json"
    if not path.is_file():
        raise InputError("no result.json: not a robocal output folder", source=str(path))
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", source=str(path), row=exc.lineno) from exc


def evaluations_html(evaluations: list[dict]) -> str:
    """The evaluation sections between markers, so that `report_with_new_evaluations` can replace them."""
    return EVALUATIONS[0] + "".join(part for e in evaluations for part in evaluation_section(e)) + EVALUATIONS[1]


def folder_evaluations(folder: Path, new: list[dict] | None = None) -> list[dict]:
    """The folder's evaluation_*.json, each replaced by the `new` one of the same session and refit choice."""
    found = {p.name: json.loads(p.read_text(encoding="utf-8")) for p in sorted(folder.glob("evaluation_*.json"))}
    def key(e):        # one evaluation per session and refit choice
        return e.get("data"), bool(e.get("refitted"))
    return [e for e in found.values() if all(key(e) != key(n) for n in new or [])] + list(new or [])


def report_with_evaluations(folder: str | Path, new: list[dict] | None = None, meshes: bool = True) -> bytes:
    """report.html content of an output folder, with its evaluation_*.json files and `new` evaluations."""
    folder = Path(folder)
    result = read_result(folder)
    scene = read_scene(folder) if (folder / "scene.json").is_file() else None
    if scene is None:
        log.warning("%s has no scene.json: the report has no 3D scene and no per-sample plots", folder)
    iso_path = folder / "iso9283.json"
    iso = json.loads(iso_path.read_text(encoding="utf-8")) if iso_path.is_file() else None
    result["evaluations"] = folder_evaluations(folder, new)
    return report_bytes(result, scene, meshes=meshes, iso9283=iso)


def report_with_new_evaluations(folder: str | Path, new: list[dict]) -> bytes:
    """The folder's report.html with its evaluation sections brought up to date (`robocal evaluate`): the rest
    of the page (tables, plots, 3D scene) is what the fit wrote, so only the evaluation sections are made
    anew; a report without the markers (written before them) is made anew whole, as `robocal calibrate` does
    (simple shapes in the scene)."""
    folder = Path(folder)
    page = (folder / "report.html").read_text(encoding="utf-8")
    start, end = page.find(EVALUATIONS[0]), page.find(EVALUATIONS[1])
    if start < 0 or end < start or page.count(EVALUATIONS[0]) != 1:
        return report_with_evaluations(folder, new, meshes=False)
    sections = evaluations_html(folder_evaluations(folder, new))
    return (page[:start] + sections + page[end + len(EVALUATIONS[1]):]).encode("utf-8")


def write_report(folder: str | Path, out: str | Path | None = None, meshes: bool = True) -> Path:
    """Write the report of an output folder (default: <folder>/report.html); returns its path.

    Without scene.json the report still has the tables, the parameter plot and the statements.
    """
    folder = Path(folder)
    path = Path(out) if out else folder / "report.html"
    path.write_bytes(report_with_evaluations(folder, meshes=meshes))
    return path
