"""robocal.viz.svg_torques: the identify / evaluate torque figure as SVG (no matplotlib)."""
import re

import numpy as np
import pytest

from robocal.errors import InputError
from robocal.viz.svg_torques import joint_torques, pixel_envelope


def test_envelope_keeps_every_pixel_columns_first_last_lowest_highest():
    x = np.linspace(0.0, 10.0, 20001)
    y = np.sin(7 * x) + np.random.default_rng(0).normal(size=x.size)
    xs, ys = pixel_envelope(x, y, 0.0, 10.0, 600)
    assert len(xs) <= 4 * 600 and np.all(np.diff(xs) > 0)          # time order, at most 4 a column
    col, kept = (np.clip((v / 10.0 * 600).astype(int), 0, 599) for v in (x, xs))
    for c in range(600):
        m, k = col == c, kept == c
        assert (ys[k].min(), ys[k].max()) == (y[m].min(), y[m].max())
        assert (xs[k][0], xs[k][-1]) == (x[m][0], x[m][-1])
    short = np.arange(50.0)
    assert pixel_envelope(short, short, 0.0, 49.0, 600)[0] is short       # few samples: every one drawn


def test_one_panel_per_joint_with_each_models_rms_error():
    t = np.linspace(0.0, 2.0, 400)
    tau = np.c_[np.sin(t), 3 * np.cos(t)]
    out = joint_torques(t, tau, {"ols": tau + 0.1, "consistent": tau - 0.2}, ["torso", "arm_1"], ["N", "N m"])
    assert out.startswith("<svg") and out.endswith("</svg>")
    assert len(re.findall("<polyline", out)) == 2 * 3                       # measured + 2 models per joint
    assert "rms error ols 0.1, consistent 0.2 N m" in out and "torso [N]" in out
    one = joint_torques(t, tau[:, 0], tau[:, 0])
    assert len(re.findall("<polyline", one)) == 2
    with pytest.raises(InputError):
        joint_torques(t[:10], tau, tau)
