"""term_errors (held-out scoring: evaluate, cv, select) takes the batched pass where the model allows it: its errors
must be the per-term path's to rounding (1e-10 of the largest error, the batched evaluation's bar), with sessions
re-registered and with the hand's rigid point cluster."""
from pathlib import Path

import numpy as np
import pytest

from robocal.estimation import prediction_errors as pe
from robocal.estimation.calibrate import calibrate
from robocal.model.batch_kinematics import BatchKinematics
from robocal.workflows.setup import load_config

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("config", ["examples/tiago_mocap/select_hand_sessions.yaml",
                                    "examples/tiago_mocap/hand_full_compliance_backlash_tilt.yaml",
                                    "robocal/io/demo/ur5_calibrate.yaml"])
def test_batched_term_errors_equal_the_per_term_path(config, monkeypatch):
    setup = load_config(ROOT / config)
    calibrate(setup.problem, setup.options)       # away from nominal: every correction and placement counts
    made = []
    monkeypatch.setattr(pe, "BatchKinematics", lambda *a: made.append(1) or BatchKinematics(*a))
    batched = pe.term_errors(setup.problem)
    assert made, "the batched pass was not taken"
    monkeypatch.setattr(pe, "supports_batch", lambda ms: False)
    per_term = pe.term_errors(setup.problem)
    assert batched.keys() == per_term.keys()
    for name, block in per_term.items():
        assert batched[name].raw.shape == block.raw.shape
        assert np.abs(batched[name].raw - block.raw).max() <= 1e-10 * np.abs(block.raw).max()
