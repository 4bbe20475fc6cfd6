"""The report's camera figure as SVG: per image, the detected corners, the reprojected ones and the residual arrows
where the image's pixel axes say, worst images first, at most MAX_PANELS."""
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from robocal.viz import svg_camera
from robocal.viz.svg_plots import AFTER, RED

NS = "{http://www.w3.org/2000/svg}"
W, H = 1280, 1024


def block(n_images: int, corners: int = 6, seed: int = 0) -> dict:
    """A scene camera block: every image sees `corners` pixels; image i's residuals grow with i (worst last)."""
    rng = np.random.default_rng(seed)
    px = rng.uniform([50, 40], [W - 50, H - 40], (n_images * corners, 2))
    after = rng.normal(0, 1, px.shape) * np.repeat(0.1 * (1 + np.arange(n_images)), corners)[:, None]
    return {"name": "cam 1", "camera": {"pixels": px.tolist(), "image_size": [W, H]},
            "terms": [[i] for i in range(n_images) for _ in range(corners)],
            "residual_before": (10 * after).tolist(), "residual_after": after.tolist()}


def panel_pixels(root, index: int, element: str, colour: str) -> np.ndarray:
    """Pixel (u, v) of the marks of one series in panel `index`, mapped back through that panel's frame."""
    group = [g for g in root.iter(f"{NS}g") if g.get("clip-path")][index]
    rect = next(r for r in root.iter(f"{NS}clipPath") if r.get("id") == group.get("clip-path")[5:-1])[0]
    x0, y0, pw, ph = (float(rect.get(k)) for k in ("x", "y", "width", "height"))
    d = next(p for p in group.iter(f"{NS}path") if p.get("stroke") == colour).get("d")
    pattern = r"M([-\d.]+) ([-\d.]+)h0" if element == "dot" else r"M([-\d.]+) ([-\d.]+)l"
    xy = np.array(re.findall(pattern, d), float)
    if element == "cross":
        xy += 1.5                                        # the cross's start is its centre - size / 2
    return np.column_stack([(xy[:, 0] - x0) / pw * W - 0.5, (xy[:, 1] - y0) / ph * H - 0.5])


def test_panels_show_each_worst_image_where_its_pixels_are():
    b = block(15)
    images = svg_camera.camera_images(b)
    svg, scale, shown = svg_camera.reprojection_panels(images, (W, H), title="t", ident=b["name"])
    root = ET.fromstring(svg)                                         # well-formed
    assert shown == svg_camera.MAX_PANELS == 12
    titles = [t.text for t in root.iter(f"{NS}text") if t.text and t.text.startswith("sample ")]
    rms = sorted(((im["rms_after"], im["sample"]) for im in images), reverse=True)[:12]
    assert titles == [f"sample {s + 1}: RMS {r:.3g} px" for r, s in rms]           # worst first
    assert [t.text for t in root.iter(f"{NS}text")].count("u [px]") == 4 and "v [px]" in svg
    assert f"residual x{scale:g} (arrow)" in svg
    # the largest arrow is ARROW_FRACTION of the width / scale, the factor the largest 1-2-5 number below
    biggest = max(np.max(np.linalg.norm(images[s]["reprojected"] - images[s]["detected"], axis=1)) for _, s in rms)
    assert scale <= svg_camera.ARROW_FRACTION * W / biggest < 2.5 * scale
    px = np.array(b["camera"]["pixels"]).reshape(15, 6, 2)
    res = np.array(b["residual_after"]).reshape(15, 6, 2)
    for index, (_, sample) in enumerate(rms):
        # coordinates are written to 0.01 SVG px: 0.01 x 1280 / 140 = 0.1 image px
        assert np.allclose(panel_pixels(root, index, "dot", svg_camera.DETECTED), px[sample], atol=0.1)
        assert np.allclose(panel_pixels(root, index, "cross", AFTER), px[sample] + res[sample], atol=0.1)
        arrows = next(p for p in [g for g in root.iter(f"{NS}g") if g.get("clip-path")][index].iter(f"{NS}path")
                      if p.get("stroke") == RED).get("d")
        assert arrows.count("M") == 2 * 6                              # a shaft and a head per corner


@pytest.mark.parametrize("n", [1, 3])
def test_few_images_make_one_row(n):
    svg, _, shown = svg_camera.reprojection_panels(svg_camera.camera_images(block(n)), (W, H))
    root = ET.fromstring(svg)
    assert shown == n and len([g for g in root.iter(f"{NS}g") if g.get("clip-path")]) == n
    assert [t.text for t in root.iter(f"{NS}text")].count("u [px]") == n
