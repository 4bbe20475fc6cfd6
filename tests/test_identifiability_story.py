"""Issue 32, part 5: one identifiability story. The summary, result.json and report.html give the same counts in
the same classes; result.json's fields say what they hold; standard errors with and without the prior.

Weak data (two wrist joints barely move) on a simulated UR5 with a tracker at its flange: the default prior is
applied, so every class but "fixed" occurs."""
import html
import json
import re

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.estimation.calibrate import calibrate
from robocal.estimation.determinacy import CLASSES
from robocal.workflows.evaluate import setup_for_data
from validation_cases import write_case

WEAK = {"wrist_2_joint": 0.02, "wrist_3_joint": 0.02}


def test_summary_result_json_and_report_tell_the_same_story(tmp_path):
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(1), n=30, spread=WEAK)
    out = tmp_path / "out"
    assert main(["calibrate", str(cfg), "-o", str(out), "-q"]) == 0
    result = json.loads((out / "result.json").read_text())
    ident = result["identifiability"]
    counts = ident["counts"]
    # one partition of the requested parameters
    assert tuple(counts) == CLASSES and sum(counts.values()) == ident["requested"] == 48
    requested = [p["name"] for p in result["parameters"] if p["identifiable"] is not None]   # not fixed by the config
    assert sorted(ident["classes"]) == sorted(requested)
    assert {c: list(ident["classes"].values()).count(c) for c in CLASSES} == counts
    assert ident["identifiable_from_data"] == counts["determined"] + counts["weakly determined"] + counts["loose"]
    assert counts["set by the prior"] == len(ident["set_by_prior"]) > 0 and counts["loose"] > 0
    # the summary's sentence and the report's table carry the same numbers
    sentence = ident["statements"][0]
    assert sentence in (out / "summary.txt").read_text()
    said = dict((c, int(n)) for n, c in re.findall(r"(\d+) (determined|weakly determined|loose|set by the prior|fixed)",
                                                  sentence))
    assert said == counts
    assert main(["report", str(out), "--no-meshes"]) == 0
    page = (out / "report.html").read_text()
    assert html.escape(sentence) in page
    for cls, n in counts.items():
        assert f"<td>class: {html.escape(cls)}</td><td>{n}</td>" in page
    # field names say what they hold: the default prior's parameters got it; the loose ones explain why
    prior = result["default_prior"]
    with_prior = {p["name"] for p in result["parameters"] if "prior" in p}
    assert set(prior["parameters_given_prior"]) == with_prior
    assert set(prior["loose_at_registered_nominal"]) <= with_prior
    assert "loose_without_prior" not in prior and "rank" not in ident


def test_standard_errors_with_and_without_the_prior(tmp_path):
    """With the prior, the base frame trades off against the structurally confounded placements the prior sets
    (0.36 mm); the data alone, those held, know it to 10 um: what a fit without any prior gives."""
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(1), n=30, spread=WEAK)
    setup = setup_for_data(cfg)
    with_prior = calibrate(setup.problem, setup.options)
    plain = setup_for_data(cfg)
    plain.options.regularisation = "none"
    without = calibrate(plain.problem, plain.options)
    assert with_prior.default_prior.applied
    for n in ("base.tx", "base.ty", "base.tz", "base.rx", "base.ry", "base.rz"):
        p, q = with_prior.params[n], without.params[n]
        assert p.stderr > 10 * p.stderr_data
        # the same data, the same kept set; the linearisation points differ by the weak directions: 15 %
        assert p.stderr_data == pytest.approx(q.stderr, rel=0.15)
    for n in with_prior.prior_only:
        assert np.isinf(with_prior.params[n].stderr_data) and np.isfinite(with_prior.params[n].stderr)
