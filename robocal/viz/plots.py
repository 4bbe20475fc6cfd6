"""Calibration plots as PNG (matplotlib, Agg canvas: no display, no global pyplot state).

Every function takes plain arrays (SI units unless it says otherwise), writes one PNG to `path` (a file
path or a binary stream) and returns `path`. Reports show lengths in mm and angles in mrad and say so.
"""
from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from robocal.errors import InputError
from robocal.viz.svg_torques import torque_series

BEFORE, AFTER = "#ff8c00", "#1f77b4"
DPI = 100


def _figure(width: float = 7.0, height: float = 3.6, **subplots):
    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(**subplots)


def _save(fig, path):
    fig.savefig(path, format="png", dpi=DPI)
    return path


def _check_same_length(**arrays):
    lengths = {k: len(v) for k, v in arrays.items()}
    if len(set(lengths.values())) > 1:
        raise InputError(f"arrays must have the same length: {lengths}", field=", ".join(lengths))


def residuals_per_sample(before, after, path, unit: str = "mm", title: str = "Residual per sample"):
    """Residual size of each sample before and after calibration (already in `unit`), log scale."""
    before, after = np.asarray(before, float).ravel(), np.asarray(after, float).ravel()
    _check_same_length(before=before, after=after)
    fig, ax = _figure()
    x = np.arange(1, len(before) + 1)
    ax.semilogy(x, np.maximum(before, 1e-12), "o-", ms=3, lw=0.8, color=BEFORE, label="before")
    ax.semilogy(x, np.maximum(after, 1e-12), "o-", ms=3, lw=0.8, color=AFTER, label="after")
    ax.set_xlabel("sample")
    ax.set_ylabel(f"|residual| [{unit}]")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return _save(fig, path)


def error_histograms(before, after, path, axes=("x", "y", "z"), unit: str = "mm",
                     title: str = "Error per axis", labels=("before", "after")):
    """Histograms of (n, k) per-axis errors (in `unit`), before and after, one panel per axis.

    Before and after differ by orders of magnitude after a good fit, so each gets its own bins.
    labels: the names of the two rows (two models on held-out data: e.g. the reference and the chosen one).
    """
    before, after = np.atleast_2d(np.asarray(before, float)), np.atleast_2d(np.asarray(after, float))
    if before.shape[1] != len(axes) or after.shape[1] != len(axes):
        raise InputError(f"errors need {len(axes)} columns ({', '.join(axes)}); got {before.shape[1]} and "
                         f"{after.shape[1]}", field="before/after")
    fig, ax = _figure(2.6 * len(axes), 4.4, nrows=2, ncols=len(axes), squeeze=False)
    for j, name in enumerate(axes):
        for row, (data, colour, label) in enumerate(((before, BEFORE, labels[0]), (after, AFTER, labels[1]))):
            a = ax[row, j]
            a.hist(data[:, j], bins=min(30, max(5, len(data) // 3)), color=colour, alpha=0.85)
            a.set_title(f"{name} {label}: rms {np.sqrt(np.mean(data[:, j] ** 2)):.3g} {unit}", fontsize=9)
            a.set_xlabel(f"{name} error [{unit}]", fontsize=8)
            a.tick_params(labelsize=7)
    fig.suptitle(title)
    return _save(fig, path)


def errors_by_group(errors: dict, groups, path, group_names=None, unit: str = "mm",
                    title: str = "Held-out error per sample, by group"):
    """Error size per sample of two models (`errors`: {label: (n,) sizes in `unit`}, first one drawn as
    the reference in orange), samples sorted by group (`groups`: (n,) int) and shaded per group; the legend
    gives each model's RMS in each group. For a validation session split into repeated / new / out of
    range postures."""
    labels = list(errors)
    if not 1 <= len(labels) <= 2:
        raise InputError(f"errors_by_group draws one or two models, got {len(labels)}", field="errors")
    data = [np.asarray(errors[k], float).ravel() for k in labels]
    groups = np.asarray(groups, int).ravel()
    _check_same_length(groups=groups, **{k: d for k, d in zip(labels, data)})
    present = sorted(set(groups.tolist()))
    names = list(group_names) if group_names is not None else [f"group {g}" for g in present]
    if len(names) <= max(present, default=0):
        raise InputError(f"{len(names)} group names for groups up to {max(present)}", field="group_names")
    order = np.argsort(groups, kind="stable")
    fig, ax = _figure(8.0, 4.2)
    x = np.arange(1, len(order) + 1)
    start = 0
    for g in present:
        n = int(np.sum(groups == g))
        if g % 2:
            ax.axvspan(start + 0.5, start + n + 0.5, color="#000000", alpha=0.06, lw=0)
        ax.text(start + n / 2 + 0.5, 1.0, names[g], transform=ax.get_xaxis_transform(), ha="center", va="bottom",
                fontsize=8)
        start += n
    for d, colour, label in zip(data, (BEFORE, AFTER), labels):
        rms = ", ".join(f"{names[g]} {np.sqrt(np.mean(d[groups == g] ** 2)):.2f}" for g in present)
        ax.plot(x, d[order], "o-", ms=3, lw=0.7, color=colour, label=f"{label} (rms: {rms} {unit})")
    ax.set_xlabel("sample, sorted by group")
    ax.set_ylabel(f"|error| [{unit}]")
    ax.set_title(title, pad=14)
    ax.grid(True, alpha=0.3)
    fig.legend(fontsize=7, loc="outside lower center")       # below the axes: the data stay uncovered
    return _save(fig, path)


def parameter_estimates(names, values, stderr, path, units=None, title: str = "Parameter estimates"):
    """Estimates with +-1 standard-error bars, shown in mm (m) and mrad (rad), one row per parameter."""
    values = np.asarray(values, float)
    stderr = np.asarray([np.nan if s is None else s for s in stderr], float)
    _check_same_length(names=names, values=values, stderr=stderr)
    units = list(units) if units is not None else ["m"] * len(values)
    scale = np.array([1e3 if u in ("m", "rad") else 1.0 for u in units])
    shown = {"m": "mm", "rad": "mrad"}
    fig, ax = _figure(7.0, max(2.5, 0.2 * len(values) + 1.2))
    y = np.arange(len(values))[::-1]
    colours = [AFTER if u == "m" else "#2ca02c" if u == "rad" else "#7f7f7f" for u in units]
    ax.barh(y, values * scale, color=colours, alpha=0.5)
    ok = np.isfinite(stderr)
    ax.errorbar((values * scale)[ok], y[ok], xerr=(stderr * scale)[ok], fmt="none", ecolor="black", capsize=2, lw=0.8)
    ax.set_yticks(y, [f"{n} [{shown.get(u, u)}]" for n, u in zip(names, units)], fontsize=7)
    ax.axvline(0, color="black", lw=0.5)
    ax.set_xlabel("estimate (mm for lengths, mrad for angles), bars: +-1 standard error")
    ax.set_title(title)
    ax.grid(True, axis="x", alpha=0.3)
    return _save(fig, path)


def singular_values(s, rank: int, path, title: str = "Identification Jacobian (column-scaled)"):
    """Singular values (largest first, log scale) with the rank the base-parameter selection kept."""
    s = np.sort(np.asarray(s, float).ravel())[::-1]
    if not 0 <= rank <= len(s):
        raise InputError(f"rank {rank} is outside 0..{len(s)}", field="rank")
    fig, ax = _figure()
    x = np.arange(1, len(s) + 1)
    floor = max(s.max() * 1e-18, 1e-300) if len(s) else 1.0
    ax.semilogy(x[:rank], np.maximum(s[:rank], floor), "o", ms=4, color=AFTER, label="kept (identifiable)")
    ax.semilogy(x[rank:], np.maximum(s[rank:], floor), "x", ms=5, color="#d62728", label="beyond the rank")
    ax.axvline(rank + 0.5, color="black", ls="--", lw=1, label=f"rank cut: {rank} of {len(s)}")
    ax.set_xlabel("index")
    ax.set_ylabel("singular value")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def joint_torques(time, measured, predicted, path, joint_names=None, unit="N m",
                  title: str = "Joint torques: measured vs predicted"):
    """Measured and predicted torque of each joint over time: (n,) time, (n, nj) torques, one panel per joint.
    predicted: one (n, nj) array, or {label: (n, nj) array} for several models; unit: one for every joint or
    a list (N for a prismatic joint)."""
    time, measured, models = torque_series(time, measured, predicted)
    nj = measured.shape[1]
    names = list(joint_names) if joint_names is not None else [f"joint {j + 1}" for j in range(nj)]
    units = [unit] * nj if isinstance(unit, str) else list(unit)
    fig, ax = _figure(7.0, max(3.0, 1.5 * nj + 0.8), nrows=nj, ncols=1, sharex=True, squeeze=False)
    styles = [(AFTER, "--"), (BEFORE, ":"), ("#2ca02c", "-."), ("#9467bd", "-")]
    for j in range(nj):
        a = ax[j, 0]
        a.plot(time, measured[:, j], color="#404040", lw=0.8, label="measured")
        rms = []
        for (label, pred), (color, ls) in zip(models.items(), styles):
            a.plot(time, pred[:, j], color=color, lw=0.8, ls=ls, label=label)
            rms.append(f"{label} {np.sqrt(np.mean((measured[:, j] - pred[:, j]) ** 2)):.3g}")
        a.set_ylabel(f"{names[j]}\n[{units[j]}]", fontsize=8)
        a.set_title(f"rms error {', '.join(rms)} {units[j]}", fontsize=8, loc="right")
        a.grid(True, alpha=0.3)
    ax[0, 0].legend(fontsize=7, loc="best", ncol=len(models) + 1)
    ax[-1, 0].set_xlabel("time [s]")
    fig.suptitle(title)
    return _save(fig, path)
