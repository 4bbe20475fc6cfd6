"""From a config file to written outputs: read and check the YAML once, build the set-up, run, write.

One module per command's workflow (calibrate, evaluate, cv, select, plan, simulate, iso9283, identify, fleet);
`robocal.cli` only parses arguments and prints what these return."""
from robocal.workflows.config import Setup, load_config, setup_from_config
from robocal.workflows.evaluate import evaluate_result, setup_for_data
from robocal.workflows.outputs import write_results

__all__ = ["Setup", "evaluate_result", "load_config", "setup_for_data", "setup_from_config", "write_results"]
