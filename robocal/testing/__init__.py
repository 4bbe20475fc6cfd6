"""Checks of robot models for users' own test suites (plain asserts or pytest), the pytest plugin, and
monte_carlo: a synthetic-truth trial repeated over seeds, serially or on Dask (docs/fleet.md)."""
from robocal.testing.assertions import (SyntheticCase, assert_calibration_recovers, assert_frame_jacobians,
                                        assert_jacobian_matches_fd, assert_problem_jacobian, assert_reproduces_dataset,
                                        assert_same_text_and_numbers,
                                        assert_urdf_loads, dataset_setup, finite_difference_jacobian, load_robot,
                                        synthetic_pose_case)
from robocal.estimation.parallel_map import monte_carlo

__all__ = ["SyntheticCase", "assert_calibration_recovers", "assert_frame_jacobians", "assert_jacobian_matches_fd",
           "assert_problem_jacobian", "assert_reproduces_dataset", "assert_same_text_and_numbers",
           "assert_urdf_loads", "dataset_setup",
           "finite_difference_jacobian", "load_robot", "monte_carlo", "synthetic_pose_case"]
