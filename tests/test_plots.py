"""Every plot function writes a real PNG: the right size, many colours, more than a blank axes frame."""
import io

import numpy as np
import pytest
from matplotlib.image import imread

from robocal.viz import plots
from robocal.errors import InputError

MIN_BYTES = 12_000          # an empty 700x360 axes frame is ~5 kB


def _check_png(path_or_buf, min_bytes=MIN_BYTES):
    data = path_or_buf.getvalue() if isinstance(path_or_buf, io.BytesIO) else open(path_or_buf, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > min_bytes, len(data)
    img = imread(io.BytesIO(data), format="png")
    assert img.shape[0] >= 250 and img.shape[1] >= 500
    colours = np.unique((img[..., :3] * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 50, f"only {len(colours)} colours"
    # the before (orange) or after (blue) series really was drawn
    rgb = (img[..., :3] * 255).astype(int)
    orange = np.all(np.abs(rgb - [255, 140, 0]) < 40, axis=-1).sum()
    blue = np.all(np.abs(rgb - [31, 119, 180]) < 40, axis=-1).sum()
    return img, orange, blue


def test_residuals_per_sample(tmp_path):
    rng = np.random.default_rng(0)
    out = plots.residuals_per_sample(rng.uniform(1, 5, 60), rng.uniform(0.01, 0.05, 60), tmp_path / "r.png")
    _, orange, blue = _check_png(out)
    assert orange > 200 and blue > 200
    with pytest.raises(InputError):
        plots.residuals_per_sample(np.ones(3), np.ones(4), tmp_path / "x.png")


def test_error_histograms(tmp_path):
    rng = np.random.default_rng(1)
    out = plots.error_histograms(rng.normal(0, 2, (80, 3)), rng.normal(0, 0.02, (80, 3)), tmp_path / "h.png")
    _, orange, blue = _check_png(out)
    assert orange > 1000 and blue > 1000
    with pytest.raises(InputError):
        plots.error_histograms(np.ones((5, 2)), np.ones((5, 3)), tmp_path / "x.png")


def test_errors_by_group_sorts_samples_and_draws_both_models(tmp_path):
    rng = np.random.default_rng(2)
    groups = rng.integers(0, 3, 60)
    ref, model = rng.uniform(2, 6, 60), rng.uniform(0.5, 2, 60)
    out = plots.errors_by_group({"reference": ref, "chosen": model}, groups, tmp_path / "g.png",
                                group_names=["repeated", "new", "out of range"])
    _, orange, blue = _check_png(out)
    assert orange > 300 and blue > 300
    with pytest.raises(InputError):                                  # lengths differ
        plots.errors_by_group({"a": ref, "b": model[:-1]}, groups, tmp_path / "x.png")
    with pytest.raises(InputError):                                  # a group without a name
        plots.errors_by_group({"a": ref}, groups, tmp_path / "x.png", group_names=["repeated", "new"])


def test_parameter_estimates_with_error_bars(tmp_path):
    names = ["shoulder_pan_joint.offset", "elbow_joint.tx", "elbow_joint.ry", "tool0.tz"]
    out = plots.parameter_estimates(names, [1e-3, -2e-4, 3e-3, 5e-4], [1e-5, None, 2e-5, 1e-6],
                                    tmp_path / "p.png", units=["rad", "m", "rad", "m"])
    _check_png(out)
    with pytest.raises(InputError):
        plots.parameter_estimates(names, [1.0], [0.1], tmp_path / "x.png")


def test_singular_values_with_rank_cut(tmp_path):
    s = np.concatenate([np.logspace(1, -2, 30), np.full(6, 1e-14)])
    buf = plots.singular_values(s, 30, io.BytesIO())
    _check_png(buf)
    with pytest.raises(InputError):
        plots.singular_values(s, 40, io.BytesIO())


def test_joint_torques_measured_vs_predicted(tmp_path):
    t = np.linspace(0, 5, 500)
    tau = np.column_stack([np.sin(t * (j + 1)) * (10 - j) for j in range(6)])
    out = plots.joint_torques(t, tau + 0.2 * np.random.default_rng(2).normal(size=tau.shape), tau,
                              tmp_path / "tau.png", joint_names=[f"j{j}" for j in range(6)])
    img, _, blue = _check_png(out, min_bytes=40_000)
    assert img.shape[0] > 600 and blue > 500          # six panels, predicted curves drawn
    # a single joint as 1-D arrays
    _check_png(plots.joint_torques(t, tau[:, 0], tau[:, 0], tmp_path / "one.png"))
    with pytest.raises(InputError):
        plots.joint_torques(t[:10], tau, tau, tmp_path / "x.png")


def test_blank_figure_fails_the_check(tmp_path):
    """The check above can fail: a figure with no data does not pass it."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(7, 3.6), dpi=100)
    FigureCanvasAgg(fig)
    fig.savefig(tmp_path / "blank.png")
    with pytest.raises(AssertionError):
        _check_png(tmp_path / "blank.png")


def test_joint_torques_several_models_and_units(tmp_path):
    t = np.linspace(0, 1, 50)
    tau = np.column_stack([np.sin(t), np.cos(t)])
    out = plots.joint_torques(t, tau, {"ols": tau + 0.1, "consistent": tau - 0.1}, tmp_path / "two.png",
                              ["torso", "arm_1"], ["N", "N m"])
    _check_png(out)
    with pytest.raises(InputError, match="consistent"):
        plots.joint_torques(t, tau, {"ols": tau, "consistent": tau[:10]}, tmp_path / "bad.png")
