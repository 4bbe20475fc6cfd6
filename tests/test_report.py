"""`robocal report` / `robocal view --html`: one self-contained HTML file with tables, plots and scene."""
import argparse
import base64
import html
import json
import re
import shutil

import pytest

from robocal.errors import InputError
from robocal.viz.report import report_bytes, write_report
from robocal.cli.view import add_parser, cmd_report, cmd_view
from test_viz_scene_data import all_types_case, all_types_scene, demo_result_dir


def _parse(argv):
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def _tables(page):
    return re.findall(r'<table class="(\w+)">', page)


def test_report_of_the_demo_result_has_tables_plots_statements_and_scene(tmp_path):
    folder = demo_result_dir()
    out = tmp_path / "report.html"
    args = _parse(["report", str(folder), "-o", str(out), "--no-meshes"])
    assert cmd_report(args) == 0
    page = out.read_text()
    assert _tables(page) == ["summary", "residuals", "parameters"]
    result = json.loads((folder / "result.json").read_text())
    for statement in result["identifiability"]["statements"]:
        assert html.escape(statement) in page
    assert "Of 54 requested parameters, 30 are identifiable from the data alone" in page
    assert "<td>identifiable from the data alone</td><td>30 of 54 requested</td>" in page
    images = re.findall(r"<figure>(<svg .*?</svg>)<figcaption>", page)
    assert len(images) == 4          # residual per sample, histograms, parameters, singular values
    assert all(len(i) > 3000 and "<path d=" in i for i in images)
    assert '<iframe class="scene"' in page and "MeshCat.Viewer" in html.unescape(page)
    # every estimated parameter has a row, in mm / mrad
    n_est = sum(p["vary"] for p in result["parameters"])
    assert page.count("<td>determined</td>") == n_est == 30     # the demo's data determine every kept one
    assert "<td>mrad</td>" in page and "<td>mm</td>" in page


def test_report_without_scene_still_has_tables(tmp_path):
    folder = tmp_path / "result"
    shutil.copytree(demo_result_dir(), folder)
    (folder / "scene.json").unlink()
    page = write_report(folder).read_text()
    assert (folder / "report.html").is_file()
    assert _tables(page) == ["summary", "residuals", "parameters"]
    assert page.count("<figure><svg") == 1 and "<iframe" not in page


def test_report_bytes_from_objects_in_memory():
    problem, result, before = all_types_case()
    from robocal.viz.scene import scene_bytes
    page = report_bytes(result, scene_bytes(problem, result, before), meshes=False).decode()
    # one residual plot per block (6) + histograms + parameters + singular values
    assert page.count("<figure><svg") == 9
    for name in ("tracker", "table", "ball", "bore", "dbb", "laser"):
        assert f"<td>{name}</td>" in page


def test_report_of_a_folder_that_is_not_a_result(tmp_path):
    with pytest.raises(InputError, match="result.json") as e:
        write_report(tmp_path)
    assert e.value.source.endswith("result.json")


def test_view_html_writes_a_page_for_the_chosen_sample(tmp_path):
    out = tmp_path / "scene.html"
    assert cmd_view(_parse(["view", str(demo_result_dir()), "--html", str(out), "--sample", "7", "--no-meshes"])) == 0
    page = out.read_text()
    assert "robocalShow(m ? parseInt(m[1]) : 6)" in page
    with pytest.raises(InputError) as e:
        cmd_view(_parse(["view", str(demo_result_dir()), "--html", str(out), "--sample", "61"]))
    assert e.value.field == "--sample"


def test_scene_page_is_deterministic():
    """Same data, same bytes: meshcat's random object ids are replaced by ids derived from the node path."""
    from robocal.viz.meshcat_check import SceneView
    pages = [SceneView(all_types_scene(), meshes=False).static_html() for _ in range(2)]
    assert pages[0] == pages[1]


def test_evaluate_replaces_only_the_evaluation_sections(tmp_path):
    """`robocal evaluate` rewrites the evaluation sections of report.html and keeps the rest as the fit wrote
    it (plots, scene: no second rendering); the same session evaluated again replaces its section."""
    from robocal.viz.report import EVALUATIONS, report_with_new_evaluations

    folder = tmp_path / "result"
    shutil.copytree(demo_result_dir(), folder)
    write_report(folder, meshes=False)
    before = (folder / "report.html").read_text()
    assert before.count(EVALUATIONS[0]) == 1 and "Evaluation on another session" not in before

    def evaluation(rms):
        return {"data": "/data/other.csv", "refitted": [], "blocks": [
            {"name": "tracker", "unit": "mm", "all": {"n": 5, "rms_norm": rms, "max_norm": 2 * rms}}]}
    page = report_with_new_evaluations(folder, [evaluation(0.123)]).decode()
    head, tail = before.split(EVALUATIONS[0])[0], before.split(EVALUATIONS[1])[1]
    assert page.startswith(head) and page.endswith(tail)
    assert page.count("Evaluation on another session") == 1 and "0.123 mm" in page
    (folder / "evaluation_other.json").write_text(json.dumps(evaluation(0.123)))
    (folder / "report.html").write_text(page)
    again = report_with_new_evaluations(folder, [evaluation(0.456)]).decode()
    assert again.count("Evaluation on another session") == 1 and "0.456 mm" in again and "0.123 mm" not in again
    # a report written before the markers existed is made anew, with the evaluation
    (folder / "report.html").write_text(before.replace(EVALUATIONS[0], "").replace(EVALUATIONS[1], ""))
    fresh = report_with_new_evaluations(folder, [evaluation(0.456)]).decode()
    assert fresh.count(EVALUATIONS[0]) == 1 and "0.456 mm" in fresh and '<iframe class="scene"' in fresh
