"""The real TIAGo motion-capture recordings load and calibrate through a config alone (no code)."""
from pathlib import Path

import numpy as np

from robocal.estimation.calibrate import calibrate
from robocal.workflows.setup import load_config

CONFIG = Path(__file__).parents[1] / "examples" / "tiago_mocap" / "offsets_bl.yaml"


def test_tiago_offsets_model_reproduces_the_published_training_fit():
    setup = load_config(CONFIG)
    assert len(setup.problem.values) == 37
    result = calibrate(setup.problem, setup.options)
    assert result.success
    raw = result.solve.fun * 5e-4                         # rows back in metres (sigma 0.5 mm in the config)
    rmse_norm = np.sqrt(np.mean(np.sum(raw.reshape(-1, 3) ** 2, axis=1)))
    # FIGAROH's joint_offset model on this training file: norm RMSE 2.88 mm, arm_5 = -49.8 +- 10.1 mrad
    assert abs(rmse_norm * 1e3 - 2.88) < 0.1
    arm5 = result.params["arm_5_joint.offset"]
    assert abs(arm5.value * 1e3 + 49.8) < 1.0 and abs(arm5.stderr * 1e3 - 10.1) < 1.0
    # not estimable from this data (data README): torso and arm_1 offsets absorbed by the base frame
    assert {"torso_lift_joint.offset", "arm_1_joint.offset"} <= set(result.unidentifiable)
