"""The shipped TIAGo log through the config alone: the physically consistent model predicts the
held-out torques better than the CAD model on every recorded joint, every body is realisable, and
the free-motion external force is smaller than with the CAD model. Figures: docs/dynamics_tiago.md."""
import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from robocal.dynamics.reduced_model import velocity_index
from robocal.dynamics.constraint_cost import MEASURABLE_COST
from robocal.workflows.identify_outputs import summary_text
from robocal.workflows.identify import identify_from_config
from robocal.dynamics.inertial import is_physically_consistent, parameter_vector
from robocal.dynamics.regression import build_regressor
from tiago_dynamics_cases import CONFIG, base_config


@pytest.fixture(scope="module")
def result():
    return identify_from_config(base_config(), CONFIG.parent)      # the example's own config


def test_consistent_model_beats_cad_and_stays_near_ols(result):
    rmse = {m: np.array(v["rmse"]) for m, v in result.validation.items()}
    assert np.all(rmse["consistent"] < rmse["cad"])
    ratio = rmse["consistent"] / rmse["ols"]
    # the criterion, on the shipped split (the log's last 20 s held out) and prior rule; measured
    # 1.034, 0.882, 0.959, 0.507, 0.897 against the filtered torque, 1.020, 0.960, 1.037, 0.844, 0.992
    # against the logged one (docs/dynamics_tiago.md)
    assert np.all(ratio <= 1.05), ratio
    logged = {m: np.array(v["rmse_against_logged"]) for m, v in result.validation.items()}
    assert np.all(logged["consistent"] < logged["cad"])
    assert np.all(logged["consistent"] / logged["ols"] <= 1.05)


def test_every_body_is_physically_consistent(result):
    bodies = result.consistent.inertial.reshape(-1, 10)
    assert all(is_physically_consistent(b) for b in bodies)
    assert all(ok for _, ok in result.consistency.values())


def test_free_motion_force_is_smaller_with_the_identified_model(result):
    cad, fit = np.array(result.wrench_rms["cad"]), np.array(result.wrench_rms["consistent"])
    assert np.linalg.norm(fit) < np.linalg.norm(cad)
    assert np.all(fit[:2] < cad[:2])


def test_consistent_model_reproduces_the_fit_through_rnea(result):
    """The exported pin.Model (inertias + rotor inertias) plus the friction terms gives the same
    torques as the fitted regressor model, so the model can be used for simulation as is."""
    model = result.consistent_model()
    p = result.processed
    rec = [velocity_index(model, j) for j in result.recorded]
    rows = np.arange(0, len(p.t), 400)
    reg = build_regressor(result.model, p.q[rows], p.v[rows], p.a[rows], rec, result.config.terms, 0.01)
    data = model.createData()
    rnea = np.array([pin.rnea(model, data, p.q[k], p.v[k], p.a[k])[rec] for k in rows])
    non_inertial = [i for i, n in enumerate(reg.names[reg.n_inertial:]) if not n.endswith("armature")]
    extra = (reg.X[:, reg.n_inertial:][:, non_inertial] @ result.consistent.extra[non_inertial]).reshape(-1, len(rec))
    assert np.allclose(rnea + extra, result.consistent.predict(reg), atol=1e-9 * np.abs(rnea).max())


def test_a_solver_stopping_short_is_said_before_any_figure(result):
    stopped = dataclasses.replace(result, consistent=dataclasses.replace(result.consistent, converged=False,
                                                                         status="MaxIterations"))
    text = summary_text(stopped)
    assert text.index("WARNING") < text.index("Held-out torque RMSE")
    assert "MaxIterations" in text
    assert "WARNING" not in summary_text(result)


def test_no_validation_data_reaches_the_fit(result):
    """The cut-off comes from the training window's spectrum, and training samples closer to the validation
    window than the filter's reach (edge_periods cut-off periods) are left out."""
    cfg, p = result.config, result.processed
    assert any(f"over the window {list(cfg.train)} s" in c for c in p.choices)
    t = p.decimated(p.t)
    reach = cfg.signal.edge_periods / p.cutoff_hz
    assert t[result.train].max() < cfg.validate[0] - reach
    assert t[result.train].min() >= cfg.train[0]
    assert np.all((t[result.check] >= cfg.validate[0]) & (t[result.check] < cfg.validate[1]))


def test_the_holdout_rule_keeps_the_filter_reach_between_its_parts():
    """model.prior_rule holdout: the same guard inside the training window, between the part that fits a
    prior weight and the part that scores it; the chosen weight scores best."""
    cfg = base_config()
    cfg["model"]["prior_rule"] = "holdout"
    res = identify_from_config(cfg, CONFIG.parent)
    reach = res.config.signal.edge_periods / res.processed.cutoff_hz
    assert res.prior.rule == "holdout" and res.prior.gap_s > reach
    assert res.prior.scores[res.prior.grid.index(res.prior.chosen)] == min(res.prior.scores)
    assert "scored on the rest" in summary_text(res)


def test_masses_far_from_cad_are_pointed_out(result):
    """Realisable is not plausible: on this log the torso body's mass falls far below the URDF's, and the
    summary says so next to the masses."""
    text = summary_text(result)
    cad_torso = parameter_vector(result.model)[0]
    assert 5.0 < cad_torso < 20.0          # the URDF's torso body: torso_lift_link and the locked head
    assert f"Body masses, CAD -> consistent (kg): torso_lift_joint {cad_torso:.3g} ->" in text
    note = next(line for line in text.splitlines() if line.startswith("NOTE: ") and "CAD mass" in line)
    assert "torso_lift_joint" in note


def test_the_prior_weight_is_the_strongest_within_the_noise(result):
    """The default rule: the chosen weight's fit lies within the bound when any does, every stronger one
    beyond it; when none does, the weakest is taken and the summary says so."""
    prior = result.prior
    assert prior.rule == "within_noise" and prior.bound == pytest.approx(result.within_noise["chi2_95"])
    k = prior.grid.index(prior.chosen)
    assert all(d > prior.bound for d in prior.scores[k + 1:])
    assert result.within_noise["distance_in_noise_units"] == pytest.approx(prior.scores[k], rel=1e-6)
    if prior.attained:
        assert prior.scores[k] <= prior.bound
    else:
        assert k == 0 and "no weight of the grid meets that bound" in summary_text(result)


def test_held_out_figures_against_the_logged_torque_itself(result):
    """The unfiltered target: the CSV efforts x gear ratio x motor constant + offset, interpolated to the
    held-out samples' times; the identified models beat CAD against it too."""
    cfg = result.config
    header = open(cfg.files["effort"]).readline().strip().split(",")
    effort = np.genfromtxt(cfg.files["effort"], delimiter=",", skip_header=1)
    t = effort[:, header.index(cfg.time_column)]
    times, logged = result.curves["t"], result.curves["logged"]
    for k, joint in enumerate(result.recorded):
        column = effort[:, header.index(f"- {joint}_effort")]
        raw = column * cfg.torque_scale[joint] + cfg.torque_offset.get(joint, 0.0)
        np.testing.assert_allclose(logged[:, k], np.interp(times, t, raw), rtol=1e-12, atol=1e-9)
    against = {m: np.array(v["rmse_against_logged"]) for m, v in result.validation.items()}
    assert np.all(against["consistent"] < against["cad"]) and np.all(against["ols"] < against["cad"])
    assert "Against the logged torque itself" in summary_text(result)


def test_the_constraints_that_cost_the_fit_are_named(result):
    """Each reported constraint binds (the fit without it breaks it) and, within the solver's tolerance,
    lowers the fit's objective; the summary lists the costly ones in decreasing cost with units."""
    costs = result.constraint_costs
    assert costs and all(c.value_without < 0 and c.cost > -MEASURABLE_COST for c in costs)
    assert costs[0].cost > 1
    assert [c.cost for c in costs] == sorted((c.cost for c in costs), reverse=True)
    text = summary_text(result)
    assert "Binding physical constraints" in text and costs[0].constraint in text
