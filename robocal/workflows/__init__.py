"""From a config file to written outputs: read and check the YAML once into typed objects, build the set-up,
run, write.

One module per command's workflow (calibrate, evaluate, cv, select, plan, simulate, iso9283, identify, fleet);
`robocal.cli` only parses arguments and prints what these return. Identification (scipy.signal) and the
fleet (Dask) are imported from their modules: robocal.workflows.identify, robocal.workflows.fleet."""
from robocal.workflows.calibrate import CalibrationRun, run_calibration
from robocal.workflows.config_read import parse_config, read_config
from robocal.workflows.config_types import CalibrationConfig
from robocal.workflows.cv import run_cv
from robocal.workflows.evaluate import evaluate_result, setup_for_data, write_evaluation
from robocal.workflows.iso9283 import iso9283_from_config
from robocal.workflows.outputs import write_results
from robocal.workflows.plan import plan_from_config, write_plan
from robocal.workflows.select import run_selected, select_model
from robocal.workflows.setup import Setup, build_setup, load_config, setup_from_config
from robocal.workflows.simulate import simulate_dataset

__all__ = ["CalibrationConfig", "CalibrationRun", "Setup", "build_setup", "evaluate_result", "iso9283_from_config",
           "load_config", "parse_config", "plan_from_config", "read_config", "run_calibration", "run_cv",
           "run_selected", "select_model", "setup_for_data", "setup_from_config", "simulate_dataset",
           "write_evaluation", "write_plan", "write_results"]
