"""A camera block's figure in the report as SVG, written directly (no matplotlib): detected against reprojected
corners per image.

`camera_images(scene_block)` gives, per image, the detected pixels, the reprojected ones after the fit and the RMS
(robocal.viz.camera_scene: reprojected = detected + residual_after); `reprojection_panels` draws up to MAX_PANELS of
them, those with the largest RMS first: the image's frame (u right, v down, px), detected corners (dots),
reprojected corners (crosses) and the residual arrows magnified by one round factor for all panels. matplotlib's
import and the layout of 12 panels cost ~1 s of CPU, half of the camera example's whole `robocal calibrate`.
"""
from __future__ import annotations

import html
import re

import numpy as np

from robocal.viz.shapes import nice_factor
from robocal.viz.svg_plots import AFTER, RED, Panel, linear_ticks, num, svg, text_width

MAX_PANELS = 12        # images drawn: the worst ones are the ones worth a look
ARROW_FRACTION = 0.06  # the largest arrow is drawn this fraction of the image width
DETECTED = "#202020"
COLUMNS, PANEL_W, LEFT, RIGHT, TOP, BOTTOM = 4, 140, 58, 8, 20, 30     # px; the first row also sits under HEAD
HEAD = 46                 # the figure's title and legend line


def camera_images(b: dict) -> list[dict]:
    """Per image (drawn sample) of a camera block: sample, detected (n, 2), reprojected after (n, 2), RMS before /
    after (px per corner)."""
    px = np.array(b["camera"]["pixels"], float).reshape(-1, 2)
    r = {s: np.array(b[f"residual_{s}"], float).reshape(-1, 2) for s in ("before", "after")}
    samples = np.array([t[0] for t in b["terms"]], dtype=int)
    out = []
    for i in np.unique(samples):
        k = samples == i
        out.append({"sample": int(i), "detected": px[k], "reprojected": px[k] + r["after"][k],
                    "rms_before": float(np.sqrt(np.mean(np.sum(r["before"][k] ** 2, axis=1)))),
                    "rms_after": float(np.sqrt(np.mean(np.sum(r["after"][k] ** 2, axis=1))))})
    return out


def arrows(p: Panel, start: np.ndarray, end: np.ndarray, colour: str, head: float = 3.0) -> None:
    """Segments start -> end (data coordinates) with a small V head each, in one path."""
    a = np.column_stack([p.px(start[:, 0]), p.py(start[:, 1])])
    b = np.column_stack([p.px(end[:, 0]), p.py(end[:, 1])])
    d = b - a
    n = np.linalg.norm(d, axis=1, keepdims=True)
    u = np.divide(d, n, out=np.zeros_like(d), where=n > 0)
    s = np.minimum(head, 0.5 * n)                        # a head never longer than half its arrow
    left = b - s * (u + 0.5 * u[:, ::-1] * [1, -1])
    right = b - s * (u - 0.5 * u[:, ::-1] * [1, -1])
    path = "".join(f"M{num(x0)} {num(y0)}L{num(x1)} {num(y1)}M{num(lx)} {num(ly)}L{num(x1)} {num(y1)}L{num(rx)} {num(ry)}"
                   for (x0, y0), (x1, y1), (lx, ly), (rx, ry) in zip(a.tolist(), b.tolist(), left.tolist(), right.tolist()))
    if path:
        p.parts.append(f'<path d="{path}" stroke="{colour}" stroke-width="0.9" fill="none"/>')


def reprojection_panels(images: list[dict], image_size, title: str = "", ident: str = "camera") -> tuple[str, float, int]:
    """The panels of `images` (camera_images), worst RMS after first, at most MAX_PANELS; returns (one `<svg>`,
    the arrow magnification, how many drawn). ident names the panels' clip paths (unique within a page)."""
    shown = sorted(images, key=lambda im: -im["rms_after"])[:MAX_PANELS]
    w, h = image_size
    biggest = max([np.max(np.linalg.norm(im["reprojected"] - im["detected"], axis=1)) for im in shown] + [0.0])
    scale = nice_factor(ARROW_FRACTION * w / biggest) if biggest > 0 else 1.0
    cols = max(1, min(COLUMNS, len(shown)))
    rows = max(1, int(np.ceil(len(shown) / cols)))
    panel_h = PANEL_W * h / w
    cell_w, cell_h = LEFT + PANEL_W + RIGHT, TOP + panel_h + BOTTOM
    key = re.sub(r"[^A-Za-z0-9_-]", "_", ident)
    uticks, vticks = linear_ticks(0, w - 1, 4), linear_ticks(0, h - 1, 4)
    ulabels, vlabels = [f"{t:g}" for t in uticks], [f"{t:g}" for t in vticks]
    defs, parts = [], [legend_line(cols * cell_w, scale)]
    for n, im in enumerate(shown):
        r, c = divmod(n, cols)
        # v runs down the image: the panel's y axis holds -v, labelled with v
        p = Panel(c * cell_w + LEFT, HEAD + r * cell_h + TOP, PANEL_W, panel_h, (-0.5, w - 0.5), (-(h - 0.5), 0.5))
        d, q = im["detected"], im["reprojected"]
        arrows(p, d * [1, -1], (d + scale * (q - d)) * [1, -1], RED)
        p.dots(d[:, 0], -d[:, 1], DETECTED, 3.0)
        p.crosses(q[:, 0], -q[:, 1], AFTER, 3.0)
        clip = f"clip-{key}-{n}"
        defs.append(f'<clipPath id="{clip}"><rect x="{num(p.x)}" y="{num(p.y)}" width="{num(p.w)}" '
                    f'height="{num(p.h)}"/></clipPath>')
        p.parts = [f'<g clip-path="url(#{clip})">' + "".join(p.parts) + "</g>"]
        p.axes("u [px]" if r == rows - 1 else "", "v [px]" if c == 0 else "",
               f"sample {im['sample'] + 1}: RMS {im['rms_after']:.3g} px", size=9, xticks=uticks, xlabels=ulabels,
               yticks=-vticks, ylabels=vlabels)
        parts += p.parts
    head = [f"<defs>{''.join(defs)}</defs>"] if defs else []
    return svg(cols * cell_w, HEAD + rows * cell_h + 6, head + parts, title), scale, len(shown)


def legend_line(width: float, scale: float) -> str:
    """The three series' keys in one line under the title, centred (the panels stay clear of a legend box)."""
    items = [("detected", f'<path d="M{{x}} 34h0" stroke="{DETECTED}" stroke-width="5" stroke-linecap="round"/>'),
             ("reprojected", f'<path d="M{{a}} 31l6 6m0 -6l-6 6" stroke="{AFTER}" stroke-width="1.2"/>'),
             (f"residual x{scale:g} (arrow)", f'<path d="M{{b}} 34h16" stroke="{RED}" stroke-width="1.2"/>')]
    widths = [24 + text_width(t, 11) + 18 for t, _ in items]
    x = (width - sum(widths)) / 2
    out = []
    for (text, mark), wd in zip(items, widths):
        out.append(mark.format(x=num(x + 8), a=num(x + 5), b=num(x)))
        out.append(f'<text x="{num(x + 22)}" y="34" dy="0.35em" font-size="11">{html.escape(text)}</text>')
        x += wd
    return "".join(out)
