"""The report's SVG plots: well-formed, every value drawn where its axis says, ticks round and inside."""
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from robocal.errors import InputError
from robocal.viz import svg_plots

NS = "{http://www.w3.org/2000/svg}"


def dots(svg: str, colour: str) -> np.ndarray:
    """(n, 2) pixel centres of one series' dots (zero-length round-capped segments)."""
    path = next(p for p in ET.fromstring(svg).iter(f"{NS}path")
                if p.get("stroke") == colour and p.get("stroke-linecap") == "round" and p.get("d").count("M") > 1)
    return np.array([[float(a), float(b)] for a, b in re.findall(r"M([-\d.]+) ([-\d.]+)h0", path.get("d"))])


def test_ticks_are_round_and_inside_the_range():
    assert svg_plots.linear_ticks(0.0, 7.3).tolist() == [0.0, 2.0, 4.0, 6.0]
    t = svg_plots.linear_ticks(-0.137, 0.112)
    assert np.all((t >= -0.137) & (t <= 0.112)) and 0.0 in t and len(t) >= 3
    assert svg_plots.log_ticks(0.02, 5.0).tolist() == [0.1, 1.0]
    assert svg_plots.log_ticks(0.3, 4.0).tolist() == [0.5, 1.0, 2.0]       # under two decades: 1, 2, 5 each


def test_residuals_are_drawn_on_a_log_axis():
    before = np.array([1.0, 10.0, 100.0, 3.0])
    after = np.array([0.1, 0.01, 0.1, 1.0])
    svg = svg_plots.residuals_per_sample(before, after, title="t")
    ET.fromstring(svg)                                         # well-formed
    b, a = dots(svg, svg_plots.BEFORE), dots(svg, svg_plots.AFTER)
    assert len(b) == len(a) == 4
    assert np.allclose(np.diff(b[:, 0]), b[1, 0] - b[0, 0], atol=0.02) and np.allclose(a[:, 0], b[:, 0])   # x: sample
    # a decade is the same height everywhere (to the 0.01 px the coordinates are written with)
    assert b[0, 1] - b[1, 1] == pytest.approx(b[1, 1] - b[2, 1], abs=0.02)
    assert a[0, 1] - a[3, 1] == pytest.approx(b[0, 1] - b[1, 1], abs=0.02)
    assert a[0, 1] == pytest.approx(a[2, 1], abs=1e-9) and a[1, 1] > a[0, 1]     # smaller values lower
    with pytest.raises(InputError):
        svg_plots.residuals_per_sample(before, after[:3])


def test_histograms_count_every_error():
    rng = np.random.default_rng(0)
    before, after = rng.normal(0, 2, (90, 3)), rng.normal(0, 0.05, (90, 3))
    svg = svg_plots.error_histograms(before, after)
    root = ET.fromstring(svg)
    bars = [p.get("d") for p in root.iter(f"{NS}path") if p.get("fill") in (svg_plots.BEFORE, svg_plots.AFTER)]
    assert len(bars) == 6                                     # one path of bins per panel
    assert all(d.count("z") == 30 for d in bars)              # min(30, max(5, 90 // 3)) bins each
    titles = [t.text for t in root.iter(f"{NS}text") if t.text and "rms" in t.text]
    assert f"x before: rms {np.sqrt(np.mean(before[:, 0] ** 2)):.3g} mm" in titles and len(titles) == 6
    with pytest.raises(InputError):
        svg_plots.error_histograms(before[:, :2], after)


def test_parameters_have_one_row_and_one_error_bar_each():
    names = ["a.tx", "a.rx", "b.offset", "c.k"]
    svg = svg_plots.parameter_estimates(names, [1e-3, -2e-3, 5e-4, 0.3], [1e-4, None, 2e-4, 0.1],
                                        units=["m", "rad", "rad", "rad/(N m)"])
    root = ET.fromstring(svg)
    labels = [t.text for t in root.iter(f"{NS}text")]
    assert {"a.tx [mm]", "a.rx [mrad]", "b.offset [mrad]", "c.k [rad/(N m)]"} <= set(labels)
    bars = next(p.get("d") for p in root.iter(f"{NS}path") if p.get("stroke") == "black")
    assert bars.count("H") == 3                                # no bar for the parameter without a standard error


def test_singular_values_split_at_the_rank():
    s = [10.0, 3.0, 1.0, 1e-9, 1e-14]
    svg = svg_plots.singular_values(s, 3)
    assert len(dots(svg, svg_plots.AFTER)) == 3
    crosses = next(p.get("d") for p in ET.fromstring(svg).iter(f"{NS}path") if p.get("stroke") == svg_plots.RED)
    assert crosses.count("M") == 2
    assert "rank cut: 3 of 5" in svg
    with pytest.raises(InputError):
        svg_plots.singular_values(s, 6)
