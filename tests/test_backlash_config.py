"""Approach directions: derived from the row order or read from columns, and the config errors around them."""
import numpy as np
import pytest

from robocal.model.approach import directions_from_order
from robocal.workflows.setup import load_config
from robocal.errors import InputError

UR5 = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
       "wrist_3_joint"]


def test_direction_is_the_sign_of_the_last_move_above_the_threshold():
    q = np.array([[0.0], [0.5], [0.501], [0.2], [0.2], [0.3]])
    d = directions_from_order(q, np.array([2e-3]))
    # first row unknown; a 1 mrad move is below the threshold: the previous direction carries over
    assert d[:, 0].tolist() == [0, 1, 1, -1, -1, 1]
    assert directions_from_order(q, np.array([2e-3]), initial=np.array([-1.0]))[0, 0] == -1


def test_direction_follows_the_visiting_order_not_the_row_order():
    q = np.array([[0.3], [0.0], [0.5]])
    d = directions_from_order(q, np.array([1e-3]), order=np.array([1, 2, 0]))   # visited 0.0, 0.5, 0.3
    assert d[:, 0].tolist() == [-1, 0, 1]


def _write(tmp_path, approach: str, parameters: str = "backlash: true", d3=None):
    """A UR5 point-measurement config over six rows; d3: an optional direction column 'd3' (cell texts)."""
    q = np.random.default_rng(0).uniform(-1, 1, (6, 6))
    t = [3.0, 1.0, 2.0, 6.0, 5.0, 4.0]                 # rows not in time order
    lines = [",".join(UR5 + ["x", "y", "z", "t"] + (["d3"] if d3 else []))]
    for k, row in enumerate(q):
        lines.append(",".join(f"{v:.6f}" for v in row) + f",0.1,0.2,0.3,{t[k]}" + (f",{d3[k]}" if d3 else ""))
    (tmp_path / "data.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "calib.yaml").write_text(f"""
robot: {{example: ur5}}
data:
  csv: data.csv
  joints: {UR5}
{approach}
parameters:
  preset: offsets
  {parameters}
measurements:
  - {{type: point, frame: tool0, columns: [x, y, z], point_unknown: true}}
""")
    return tmp_path / "calib.yaml", q, np.array(t)


def test_config_derives_directions_from_the_rows_sorted_by_time(tmp_path):
    cfg, q, t = _write(tmp_path, "  approach: {from: order, sort_by: t, threshold: {angle: 0.002}}")
    setup = load_config(cfg)
    want = directions_from_order(q, np.full(6, 2e-3), order=np.argsort(t))
    np.testing.assert_array_equal(setup.problem.directions, want)
    assert sum(p.kind == "joint_backlash" for p in setup.problem.params) == 6
    # the earliest row (t = 1) starts unknown; every other row has a direction for every joint
    assert not setup.problem.directions[1].any() and np.all(np.delete(setup.problem.directions, 1, 0) != 0)


def test_config_reads_directions_from_columns(tmp_path):
    cfg, _, _ = _write(tmp_path, "  approach: {from: columns, columns: {elbow_joint: d3}}",
                       "backlash: [elbow_joint]", d3=["1", "-1", "0", "1", "1", "-1"])
    d = load_config(cfg).problem.directions
    assert d[:, 2].tolist() == [1, -1, 0, 1, 1, -1] and not np.delete(d, 2, 1).any()


def test_missing_direction_column_names_the_file_and_the_column(tmp_path):
    cfg, _, _ = _write(tmp_path, "  approach: {from: columns, columns: {elbow_joint: dir_elbow}}",
                       "backlash: [elbow_joint]")
    with pytest.raises(InputError) as exc:
        load_config(cfg)
    assert exc.value.field == "dir_elbow" and exc.value.source.endswith("data.csv")


def test_direction_outside_minus_one_zero_one_names_the_row(tmp_path):
    cfg, _, _ = _write(tmp_path, "  approach: {from: columns, columns: {elbow_joint: d3}}",
                       "backlash: [elbow_joint]", d3=["1", "1", "0.5", "1", "1", "1"])
    with pytest.raises(InputError) as exc:
        load_config(cfg)
    assert exc.value.row == 4 and exc.value.field == "d3" and "0.5" in exc.value.reason


def test_backlash_joint_without_a_direction_column_is_named(tmp_path):
    cfg, _, _ = _write(tmp_path, "  approach: {from: columns, columns: {elbow_joint: d3}}",
                       "backlash: [wrist_1_joint]", d3=["1"] * 6)
    with pytest.raises(InputError) as exc:
        load_config(cfg)
    assert exc.value.field == "data.approach.columns" and "wrist_1_joint" in exc.value.reason


def test_backlash_without_approach_section_is_refused(tmp_path):
    cfg, _, _ = _write(tmp_path, "")
    with pytest.raises(InputError) as exc:
        load_config(cfg)
    assert exc.value.field == "parameters.backlash" and "data.approach" in exc.value.reason


@pytest.mark.parametrize("approach, field", [("  approach: {from: history}", "data.approach.from"),
                                             ("  approach: {threshold: {angle: -1}}", "data.approach.threshold.angle"),
                                             ("  approach: {initial: {knee: 1}}", "data.approach.initial"),
                                             ("  approach: {sort_by: time}", "time")])
def test_bad_approach_settings_are_named(tmp_path, approach, field):
    cfg, _, _ = _write(tmp_path, approach)
    with pytest.raises(InputError) as exc:
        load_config(cfg)
    assert exc.value.field == field
