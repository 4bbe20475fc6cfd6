"""In a real browser: headless Chromium renders the static scene (WebGL) and the report.

Chromium comes from Debian's packages (scripts/install_browser.sh). WebGL runs on SwiftShader, the CPU
renderer: `--use-angle=swiftshader --enable-unsafe-swiftshader` renders here, whereas `--use-gl=swiftshader`
gives a blank canvas. A page counts as rendered when its 3D area differs from an empty meshcat scene.
"""
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from robocal.viz.report import write_report
from robocal.viz.scene import read_scene
from robocal.viz.meshcat_page import RecordingWindow
from robocal.viz.meshcat_check import SceneView
from test_viz_scene_data import demo_result_dir

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
pytestmark = pytest.mark.skipif(CHROMIUM is None and not os.environ.get("CI"),
                                reason="chromium is not installed (run scripts/install_browser.sh)")


def test_chromium_is_there_in_ci():
    """CI must run the browser tests, not skip them: the set-up installs chromium."""
    assert CHROMIUM is not None, "chromium is missing: scripts/install_browser.sh did not install it"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars"]
SIZE = (900, 600)


def chromium(url: str, *extra: str, timeout: float = 120) -> subprocess.CompletedProcess:
    with tempfile.TemporaryDirectory(prefix="robocal-chromium-") as profile:
        return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *extra, url],
                              capture_output=True, text=True, timeout=timeout, check=True)


def screenshot(page: Path, png: Path, fragment: str = "", budget_ms: int = 6000) -> np.ndarray:
    chromium(page.resolve().as_uri() + fragment, f"--screenshot={png}", f"--window-size={SIZE[0]},{SIZE[1]}",
             f"--virtual-time-budget={budget_ms}")
    img = imread(png)[..., :3]
    assert img.shape[:2] == (SIZE[1], SIZE[0])
    return img


def scene_area(img: np.ndarray) -> np.ndarray:
    """The 3D canvas above the legend box (bottom left) and below meshcat's control bar."""
    return img[30:int(0.62 * img.shape[0])]


@pytest.fixture(scope="module")
def empty_scene(tmp_path_factory) -> np.ndarray:
    page = tmp_path_factory.mktemp("empty") / "empty.html"
    page.write_text(RecordingWindow().get_scene())
    return screenshot(page, page.with_suffix(".png"))


def test_static_scene_renders_the_robot_and_steps_samples(tmp_path, empty_scene):
    scene = read_scene(demo_result_dir())
    page = tmp_path / "scene.html"
    page.write_text(SceneView(scene, meshes=True).static_html(0))
    first = screenshot(page, tmp_path / "sample1.png")
    other = screenshot(page, tmp_path / "sample30.png", "#sample=29")
    for img in (first, other):
        area = scene_area(img)
        colours = np.unique((area * 255).astype(np.uint8).reshape(-1, 3), axis=0)
        assert len(colours) > 500, "the 3D area is (nearly) single-coloured: WebGL did not render"
        drawn = np.abs(area - scene_area(empty_scene)).max(axis=-1) > 0.12
        assert drawn.mean() > 0.02, f"only {drawn.mean():.2%} of the 3D area differs from an empty scene"
    moved = np.abs(scene_area(first) - scene_area(other)).max(axis=-1) > 0.12
    assert moved.mean() > 0.005, "stepping to another sample did not move the robot"


def test_report_opens_with_its_tables_images_and_scene(tmp_path, empty_scene):
    report = write_report(demo_result_dir(), tmp_path / "report.html", meshes=False)
    dom = chromium(report.resolve().as_uri(), "--dump-dom", "--virtual-time-budget=3000").stdout
    for cls in ("summary", "residuals", "parameters"):
        assert f'<table class="{cls}">' in dom
    assert dom.count("<tr>") > 40 and dom.count("<figure><svg") == 4          # the four plots, inline SVG
    assert "are identifiable from the data alone" in dom and '<iframe class="scene"' in dom
    img = screenshot(report, tmp_path / "report.png", budget_ms=3000)
    colours = np.unique((img * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 50 and (img < 0.5).mean() > 0.005      # text and table lines drawn
