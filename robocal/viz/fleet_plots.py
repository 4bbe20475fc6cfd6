"""Fleet report plots as PNG (matplotlib, Agg canvas), in the style of robocal.viz.plots."""
from __future__ import annotations

import datetime

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from robocal.viz.plots import AFTER, BEFORE, DPI


def parameter_spread(names, z, flagged, threshold, path, title="Every parameter across the fleet"):
    """Robust z of each unit's estimate (columns of z: parameters); flagged[i, j] marks outlier points."""
    z, flagged = np.asarray(z, float), np.asarray(flagged, bool)
    fig = Figure(figsize=(max(7.0, 0.25 * len(names)), 4.2), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    x = np.broadcast_to(np.arange(len(names)), z.shape)
    jitter = np.random.default_rng(0).uniform(-0.2, 0.2, z.shape)   # fixed seed: the same page every time
    ax.scatter((x + jitter)[~flagged], z[~flagged], s=8, color=AFTER, label="unit")
    ax.scatter((x + jitter)[flagged], z[flagged], s=24, color=BEFORE, marker="D", label="outlier")
    for t in (-threshold, threshold):
        ax.axhline(t, color="0.5", ls="--", lw=1)
    ax.set_xticks(range(len(names)), names, rotation=90, fontsize=7)
    ax.set_yscale("symlog", linthresh=threshold)   # linear inside the threshold, far outliers still on the page
    ax.set_ylabel("(estimate - fleet median) / robust sd")
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, format="png", dpi=DPI)
    return path


def drift_histories(drifts, path, title="Largest drifts: estimate +-1 standard error over time (SI units)"):
    """One panel per Drift (robocal.workflows.fleet.report): its unit's estimates against the date."""
    n = len(drifts)
    cols = min(n, 2)
    rows = (n + cols - 1) // cols
    fig = Figure(figsize=(7.0, 2.6 * rows), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for ax, d in zip(axes, drifts):
        dates = [datetime.date.fromisoformat(t) for t, _, _ in d.history]
        ax.errorbar(dates, [e for _, e, _ in d.history], yerr=[s for _, _, s in d.history], marker="o", color=AFTER)
        ax.set_title(f"{d.unit}: {d.parameter} ({d.z:+.1f} se)", fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=10)
    fig.savefig(path, format="png", dpi=DPI)
    return path
