"""Measured and predicted joint torques over time as SVG, written directly (no matplotlib): the figure of
`robocal identify` (held-out window) and of `robocal evaluate` on an identify folder.

The same arrays as robocal.viz.plots.joint_torques (which keeps matplotlib for PNG files). matplotlib's import
and layout cost 0.6-1.4 s of CPU, more than the whole identification of the shipped logs. A series longer than
twice the panel's width in pixels is drawn as each pixel column's first, lowest, highest and last sample, in
time order: the same picture at the page's scale, a few thousand points instead of every row of a 5 kHz log.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.viz.svg_plots import AFTER, BEFORE, GREEN, Panel, padded, svg

#: measured, then up to four models: (colour, SVG dash pattern, legend kind)
MEASURED = ("#404040", "", "line")
STYLES = [(AFTER, "6 3", "dash:6 3"), (BEFORE, "2 2", "dash:2 2"), (GREEN, "6 2 2 2", "dash:6 2 2 2"),
          ("#9467bd", "", "line")]
WIDTH, LEFT, RIGHT, ROW = 760, 96, 16, 150


def pixel_envelope(x: np.ndarray, y: np.ndarray, x0: float, x1: float, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) reduced to each of `columns` pixel columns' first, lowest, highest and last sample (time order);
    unchanged when there are fewer than 2 x columns samples."""
    if len(x) < 2 * columns or not x1 > x0:
        return x, y
    col = np.clip(((x - x0) / (x1 - x0) * columns).astype(int), 0, columns - 1)
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])        # x is sorted: each column one run
    lowest = np.lexsort((y, col))[starts]          # per run, the index of its smallest (then largest) y
    highest = np.lexsort((-y, col))[starts]
    idx = np.unique(np.concatenate([starts, np.r_[starts[1:], len(x)] - 1, lowest, highest]))
    return x[idx], y[idx]


def polyline(p: Panel, x: np.ndarray, y: np.ndarray, colour: str, dash: str) -> None:
    """Panel.line for long series: points to 0.1 px, formatted from Python floats (numpy scalars format ~5x
    slower, and a 5 kHz log's figure has some 50000 points)."""
    pts = " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(p.px(x).tolist(), p.py(y).tolist()))
    p.parts.append(f'<polyline points="{pts}" fill="none" stroke="{colour}" stroke-width="0.8"'
                   + (f' stroke-dasharray="{dash}"' if dash else "") + "/>")


def torque_series(time, measured, predicted) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(time (n,), measured (n, nj), {label: predicted (n, nj)}) of a torque figure's arguments (one joint's
    (n,) arrays become (n, 1)); InputError when their shapes disagree. Shared with robocal.viz.plots."""
    time = np.asarray(time, float).ravel()
    measured = np.asarray(measured, float)
    models = predicted if isinstance(predicted, dict) else {"predicted": predicted}
    models = {k: np.asarray(v, float) for k, v in models.items()}
    if measured.ndim == 1:
        measured, models = measured[:, None], {k: v.reshape(-1, 1) for k, v in models.items()}
    for name, pred in models.items():
        if measured.shape != pred.shape or len(time) != len(measured):
            raise InputError(f"time {time.shape}, measured {measured.shape} and {name} {pred.shape} disagree",
                             field="measured/predicted")
    return time, measured, models


def joint_torques(time, measured, predicted, joint_names=None, unit="N m",
                  title: str = "Joint torques: measured vs predicted") -> str:
    """One `<svg>`: a panel per joint, measured and predicted torque over time with each model's rms error.
    time (n,), measured (n, nj) or (n,), predicted one such array or {label: array} for several models; unit:
    one for every joint or a list (N for a prismatic joint)."""
    time, measured, models = torque_series(time, measured, predicted)
    if len(models) > len(STYLES):
        raise InputError(f"{len(models)} models: at most {len(STYLES)} in one figure", field="predicted")
    nj = measured.shape[1]
    names = list(joint_names) if joint_names is not None else [f"joint {j + 1}" for j in range(nj)]
    units = [unit] * nj if isinstance(unit, str) else list(unit)
    xlim = (float(time[0]), float(time[-1])) if len(time) and time[-1] > time[0] else (0.0, 1.0)
    w = WIDTH - LEFT - RIGHT
    parts = []
    for j in range(nj):
        series = [("measured", measured[:, j], MEASURED)] + [(k, v[:, j], s) for (k, v), s in zip(models.items(), STYLES)]
        values = np.concatenate([s[1] for s in series])
        finite = values[np.isfinite(values)]
        ylim = padded(float(finite.min()), float(finite.max())) if len(finite) else (-1.0, 1.0)
        p = Panel(LEFT, 40 + j * ROW, w, ROW - 48, xlim, ylim)
        for _, y, (colour, dash, _) in series:
            polyline(p, *pixel_envelope(time, y, *xlim, int(w)), colour, dash)
        rms = ", ".join(f"{k} {np.sqrt(np.mean((measured[:, j] - v[:, j]) ** 2)):.3g}" for k, v in models.items())
        p.axes("time [s]" if j == nj - 1 else "", f"{names[j]} [{units[j]}]", f"rms error {rms} {units[j]}", size=10)
        if j == 0:
            p.legend([(k, colour, kind) for k, _, (colour, _, kind) in series], size=10)
        parts += p.parts
    return svg(WIDTH, 40 + nj * ROW + 10, parts, title)
