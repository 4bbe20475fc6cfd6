"""Fitting: the stacked problem, the solver, identifiability, the result, held-out errors and model selection,
ISO 9283 figures, and the general parallel map.

The fit itself is `robocal.calibrate` (a name here would be shadowed by the module robocal.estimation.calibrate)."""
from robocal.estimation.calibrate import CalibrationOptions
from robocal.estimation.camera_block import (CameraSetup, camera_problem, camera_setup, hand_eye_of,
                                            separable_hand_eye)
from robocal.estimation.camera_report import camera_summary
from robocal.estimation.cross_validation import (RANGE_MARGIN, CVTable, CrossValidation, cross_validate, cv_table,
                                                 edge_folds, kfold, posture_groups, range_excess)
from robocal.estimation.identifiability import BaseSelection, covariance, select_base_parameters
from robocal.estimation.iso9283 import iso9283_figures
from robocal.estimation.model_criteria import (Criteria, HeldOut, Linearised, ModelEvidence, approximate_loo,
                                               information_criteria, inside_others, linearise, log_evidence,
                                               nominal_evidence)
from robocal.estimation.model_selection import Rung, Selection, ladder, one_standard_error
from robocal.estimation.session_holdout import held_out_figure, score_session
from robocal.estimation.parallel_map import map_tasks, monte_carlo
from robocal.estimation.problem import Problem
from robocal.estimation.result import CalibrationResult
from robocal.estimation.prediction_errors import BlockErrors, PointStats, norm_errors, point_stats, term_errors

__all__ = ["CalibrationOptions", "CameraSetup", "camera_problem", "camera_setup", "hand_eye_of", "separable_hand_eye",
           "camera_summary",
           "RANGE_MARGIN", "CVTable", "CrossValidation", "cross_validate", "cv_table",
           "edge_folds", "kfold", "posture_groups", "range_excess", "BaseSelection", "covariance",
           "select_base_parameters", "iso9283_figures", "Criteria", "HeldOut", "Linearised", "ModelEvidence",
           "approximate_loo", "information_criteria", "inside_others", "linearise", "log_evidence", "nominal_evidence",
           "Rung", "Selection", "ladder", "one_standard_error", "held_out_figure", "score_session",
           "map_tasks", "monte_carlo", "Problem", "CalibrationResult", "BlockErrors", "PointStats", "norm_errors",
           "point_stats", "term_errors"]
