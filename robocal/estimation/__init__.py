"""Fitting: the stacked problem, the solver, identifiability, the result, and validation of a fitted model.

The fit itself is `robocal.calibrate` (a name here would be shadowed by the module robocal.estimation.calibrate).

The fleet layer (`robocal.estimation.fleet`, the [fleet] extra) is imported on its own."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "identifiability": "BaseSelection covariance select_base_parameters",
    "calibrate": "CalibrationOptions", "result": "CalibrationResult",
    "evaluation": "cross_validate edge_folds kfold posture_groups range_excess RANGE_MARGIN setup_for_data term_errors",
    "validation": "cv_table evaluate_result", "iso9283": "iso9283_figures", "problem": "Problem",
    "model_selection": "select_model"})
