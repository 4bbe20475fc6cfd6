"""The closed-loop examples of docs/closed_loops.md: the gripper built in Python as a Pinocchio model with
constraint models and a coupling recovers its simulated truth."""
import importlib.util
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "closed_loops"


def load_example(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_gripper_built_in_python_recovers_its_truth(capsys):
    """20 um camera noise on both tips, 30 samples: every parameter within 4 standard errors of the truth (11
    parameters, a chance of ~1e-3 that a correct fit lands beyond)."""
    result, worst = load_example("gripper_four_bar").main(samples=30, seed=5)
    assert result.success and len(result.params.free_names) >= 11
    assert worst < 4.0
    assert "gear.ratio" in capsys.readouterr().out
