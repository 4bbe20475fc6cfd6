"""Approach direction of each joint at each sample: the input of the `joint_backlash` parameter kind.

A joint with play settles on one side of it or the other depending on the direction it last moved in.
d in {-1, 0, +1} per sample and read joint; 0 means unknown (the model then takes the centre of the play).

Two sources (config `data.approach`, docs/config.md):
  order    derived from the rows: ASSUMES the static postures were recorded in the order they were
           visited (optionally sorted by a time column). d_k = sign(q_k - q_prev) when the joint moved
           by more than a threshold, else the previous row's direction; the first row gets `initial`
           (default 0).
  columns  one column of -1 / 0 / +1 per joint, written by the acquisition.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robocal.io.tables import Table
from robocal.errors import InputError

#: smaller moves than these (rad, m) are encoder noise or a hold, not an approach
DEFAULT_THRESHOLD = {"angle": 2e-3, "length": 1e-3}


@dataclass
class ApproachSpec:
    source: str = "order"                              # order | columns
    sort_by: str | None = None                         # column giving the visiting order (a time)
    threshold: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_THRESHOLD))
    initial: dict[str, float] = field(default_factory=dict)   # joint -> direction before the first row
    columns: dict[str, str] = field(default_factory=dict)     # joint -> column (source: columns)


def directions_from_order(values: np.ndarray, thresholds: np.ndarray, order: np.ndarray | None = None,
                          initial: np.ndarray | None = None) -> np.ndarray:
    """(N, n) directions of readings `values` (N, n), visited in `order` (default: row order)."""
    values = np.asarray(values, dtype=float)
    order = np.arange(len(values)) if order is None else np.asarray(order, dtype=int)
    last = np.zeros(values.shape[1]) if initial is None else np.asarray(initial, dtype=float)
    out = np.zeros(values.shape)
    prev = None
    for i in order:
        if prev is not None:
            step = values[i] - values[prev]
            last = np.where(np.abs(step) > thresholds, np.sign(step), last)
        out[i] = last
        prev = i
    return out


def table_directions(tab: Table, joint_values: np.ndarray, joints: list[str], prismatic: list[bool],
                     spec: ApproachSpec) -> np.ndarray:
    """(n_rows, n_joints) directions of every row of `tab`; joint_values: its readings (SI), all rows."""
    if spec.source == "columns":
        out = np.zeros((tab.n_rows, len(joints)))
        for k, j in enumerate(joints):
            if j in spec.columns:
                out[:, k] = _direction_column(tab, spec.columns[j])
        return out
    order = None
    if spec.sort_by is not None:
        order = np.argsort(tab.column(spec.sort_by), kind="stable")
    thresholds = np.array([spec.threshold["length" if p else "angle"] for p in prismatic])
    initial = np.array([float(spec.initial.get(j, 0.0)) for j in joints])
    return directions_from_order(joint_values, thresholds, order, initial)


def _direction_column(tab: Table, name: str) -> np.ndarray:
    d = tab.column(name)
    bad = np.flatnonzero(~np.isin(d, (-1.0, 0.0, 1.0)))
    if len(bad):
        raise InputError(f"approach direction {d[bad[0]]:g} is not -1, 0 or +1", source=str(tab.path),
                         row=tab.line(int(bad[0])), field=name)
    return d
