"""Fitting: the stacked problem, the solver, identifiability, the result, and validation of a fitted model.

The fleet layer (`robocal.estimation.fleet`, the [fleet] extra) is imported on its own."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "problem": "Problem", "calibrate": "CalibrationOptions calibrate", "result": "CalibrationResult",
    "identifiability": "BaseSelection covariance select_base_parameters",
    "validation": "cv_table evaluate_result", "model_selection": "select_model",
    "evaluation": "cross_validate kfold", "iso9283": "iso9283_figures"})
