"""A camera block's figures in the report (matplotlib, Agg canvas): detected against reprojected corners per image.

`camera_images(scene_block)` gives, per image, the detected pixels, the reprojected ones after the fit and the RMS
(robocal.viz.camera_scene: reprojected = detected + residual_after); `reprojection_panels` draws up to MAX_PANELS of
them, those with the largest RMS first: the image's frame, detected corners (dots), reprojected corners (crosses)
and the residual arrows magnified by one round factor for all panels.
"""
from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from robocal.viz.plots import AFTER, DPI
from robocal.viz.shapes import nice_factor

MAX_PANELS = 12        # images drawn: the worst ones are the ones worth a look
ARROW_FRACTION = 0.06  # the largest arrow is drawn this fraction of the image width


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


def reprojection_panels(images: list[dict], image_size, path, title: str = ""):
    """The panels of `images` (camera_images), worst RMS after first, at most MAX_PANELS; returns (path, the arrow
    magnification, how many drawn)."""
    shown = sorted(images, key=lambda im: -im["rms_after"])[:MAX_PANELS]
    w, h = image_size
    biggest = max([np.max(np.linalg.norm(im["reprojected"] - im["detected"], axis=1)) for im in shown] + [0.0])
    scale = nice_factor(ARROW_FRACTION * w / biggest) if biggest > 0 else 1.0
    cols = min(4, len(shown))
    rows = int(np.ceil(len(shown) / cols))
    fig = Figure(figsize=(3.0 * cols, 3.0 * rows * h / w + 0.6), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(rows, cols)).reshape(-1)
    for ax, im in zip(axes, shown):
        d, p = im["detected"], im["reprojected"]
        ax.plot(d[:, 0], d[:, 1], ".", ms=3, color="#202020", label="detected")
        ax.plot(p[:, 0], p[:, 1], "x", ms=3, color=AFTER, label="reprojected")
        ax.quiver(d[:, 0], d[:, 1], scale * (p[:, 0] - d[:, 0]), scale * (p[:, 1] - d[:, 1]), angles="xy",
                  scale_units="xy", scale=1, color="#d62728", width=0.004)
        ax.set_xlim(-0.5, w - 0.5)
        ax.set_ylim(h - 0.5, -0.5)          # image rows run down
        ax.set_aspect("equal")
        ax.set_title(f"sample {im['sample'] + 1}: RMS {im['rms_after']:.3g} px", fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in axes[len(shown):]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7, loc="lower right")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.savefig(path, format="png", dpi=DPI)
    return path, scale, len(shown)
