"""Bad motor-side input (docs/dynamics_motors.md): a singular transmission, a coupling naming an unknown joint or
motor, currents without torque constants, a log whose motor columns disagree with the transmission's motors, a
kHz log with a dropped sample: each refused before any fit with an error naming the file and the field, and
`robocal identify` writes nothing."""
import numpy as np
import pytest
import yaml

from motor_dynamics_cases import write_case
from robocal.cli.main import main
from robocal.errors import InputError
from robocal.workflows.identify import identify_from_config


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """The UR5 example's config and a 3 s log (the errors come before any fit)."""
    config, _ = write_case("ur5_coupled", tmp_path_factory.mktemp("bad"), seconds=3.0)
    return config


def run_and_expect(cfg: dict, folder, match, tmp_path) -> InputError:
    """The error from identify_from_config, and the CLI's exit 2 with no folder written."""
    path = tmp_path / "dyn.yaml"
    path.write_text(yaml.safe_dump(cfg))
    with pytest.raises(InputError, match=match) as info:
        identify_from_config(path, folder)
    out = tmp_path / "out"
    for entry in cfg["logs"]:                  # the CLI reads paths relative to the YAML: make them absolute
        entry.update({k: str(folder / entry[k]) for k in ("position", "effort")})
    cfg["robot"]["urdf"] = str(folder / cfg["robot"]["urdf"])
    path.write_text(yaml.safe_dump(cfg))
    assert main(["identify", str(path), "-o", str(out)]) == 2
    assert not out.exists() and not list(tmp_path.glob(".out*"))
    return info.value


def config(case) -> dict:
    """The example's config with windows inside the 3 s log."""
    cfg = yaml.safe_load(case.read_text())
    cfg["logs"][0].update(train=[0.5, 2.5])
    del cfg["logs"][0]["validate"]
    return cfg


def test_a_singular_transmission_names_its_dependent_joints(case, tmp_path):
    cfg = config(case)
    # motor 4 turns joint 5 and motor 5 joint 4 by their own joints' shares: the two rows of T become equal
    cfg["transmission"]["coupling"] |= {"wrist_1_joint": {"motor_5": 0.01}, "wrist_2_joint": {"motor_4": 0.01}}
    err = run_and_expect(cfg, case.parent, "singular", tmp_path)
    assert err.field == "transmission.matrix" and err.source == str(tmp_path / "dyn.yaml")
    assert "wrist_1_joint" in str(err) and "wrist_2_joint" in str(err)


@pytest.mark.parametrize("coupling, field", [({"wrist_9_joint": {"motor_5": 0.003}}, "transmission.coupling.wrist_9_joint"),
                                             ({"wrist_3_joint": {"motor_9": 0.003}},
                                              "transmission.coupling.wrist_3_joint.motor_9")])
def test_a_coupling_naming_an_unknown_joint_or_motor(case, tmp_path, coupling, field):
    cfg = config(case)
    cfg["transmission"]["coupling"] = coupling
    err = run_and_expect(cfg, case.parent, "is not one of", tmp_path)
    assert err.field == field and err.source == str(tmp_path / "dyn.yaml")


def test_currents_without_constants(case, tmp_path):
    cfg = config(case)
    del cfg["transmission"]["motor_constant"]["motor_3"]
    err = run_and_expect(cfg, case.parent, "without a torque constant for motor_3", tmp_path)
    assert err.field == "transmission.motor_constant"
    cfg = config(case)
    del cfg["transmission"]["motor_constant"]
    assert run_and_expect(cfg, case.parent, "currents", tmp_path).field == "transmission.motor_constant"


def test_a_log_whose_columns_disagree_with_the_motors(case, tmp_path):
    log = case.parent / "data" / "ur5_coupled_session1.csv"
    data = np.genfromtxt(log, delimiter=",", skip_header=1, max_rows=2000)
    header = log.read_text().splitlines()[0].split(",")
    wider = tmp_path / "seven_motors.csv"        # a seventh motor's columns the transmission does not have
    np.savetxt(wider, np.column_stack([data, data[:, [5, 11]]]), delimiter=",", comments="", fmt="%.9g",
               header=",".join(header + ["motor_7_position", "motor_7_current"]))
    cfg = config(case)
    cfg["logs"][0].update(position=str(wider), effort=str(wider))
    err = run_and_expect(cfg, case.parent, "7 position columns .* where the transmission has 6 motors", tmp_path)
    assert err.source == str(wider) and err.field == "{motor}_position" and "not a motor: motor_7" in str(err)
    narrower = tmp_path / "five_motors.csv"
    keep = [i for i, h in enumerate(header) if not h.startswith("motor_6")]
    np.savetxt(narrower, data[:, keep], delimiter=",", comments="", fmt="%.9g", header=",".join(header[i] for i in keep))
    cfg["logs"][0].update(position=str(narrower), effort=str(narrower))
    err = run_and_expect(cfg, case.parent, "5 position columns", tmp_path)
    assert err.source == str(narrower) and "missing: motor_6_position" in str(err)


def test_a_dropped_sample_in_a_khz_log_names_its_row(case, tmp_path):
    log = case.parent / "data" / "ur5_coupled_session1.csv"
    data = np.genfromtxt(log, delimiter=",", skip_header=1)
    t = np.arange(len(data)) * 2e-4
    keep = np.ones(len(data), bool)
    keep[5000] = False                         # one sample missing: a 0.4 ms step among 0.2 ms ones
    timed = tmp_path / "timed.csv"
    np.savetxt(timed, np.column_stack([t, data])[keep], delimiter=",", comments="", fmt="%.9g",
               header="t," + log.read_text().splitlines()[0])
    cfg = config(case)
    cfg["logs"][0].update(position=str(timed), effort=str(timed), time_column="t")
    del cfg["logs"][0]["sample_period_s"]
    err = run_and_expect(cfg, case.parent, "dropped or repeated sample", tmp_path)
    assert err.source == str(timed) and err.field == "t" and err.row == 5002     # data row 5000 (from 0): line 5002
