"""`robocal identify` writes the input URDF with the consistent model's inertias: reloaded and reduced to
the same joints it carries exactly the identified bodies; it is not written when an edited link would
not be realisable on its own, nor when the solver stopped short; the input URDF is never touched."""
import dataclasses
import hashlib
from pathlib import Path

import numpy as np
import pytest

from robocal.dynamics.reduced_model import reduced_model
from robocal.workflows.identify_outputs import summary_text, urdf_of, write_identification
from robocal.workflows.identify import identify_from_config
from robocal.dynamics.inertial import parameter_vector
from robocal.dynamics.urdf_inertials import identified_urdf
from tiago_dynamics_cases import JOINTS, urdf_path
from ur5_dynamics_cases import write_ur5_log


@pytest.fixture(scope="module")
def ur5(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ur5_log")
    path, _, _ = write_ur5_log(folder)
    return identify_from_config(path)


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_the_written_urdf_carries_the_identified_bodies(ur5, tmp_path):
    before = digest(ur5.config.urdf)
    files = write_identification(ur5, tmp_path / "out")
    name, _, remarks = urdf_of(ur5)
    assert remarks == [] and name in files and "Identified URDF" in summary_text(ur5)
    model = reduced_model(files[name], ur5.config.joints)
    scale = np.abs(ur5.consistent.inertial).max()
    np.testing.assert_allclose(parameter_vector(model), ur5.consistent.inertial, rtol=0, atol=1e-12 * scale)
    # friction as <dynamics damping friction>, which Pinocchio reads into model.damping and model.friction
    extra = dict(zip(ur5.consistent_extra_names(), ur5.consistent.extra))
    for joint in ur5.recorded:
        iv = model.joints[model.getJointId(joint)].idx_v
        assert model.damping[iv] == pytest.approx(extra[f"{joint}.viscous"], rel=1e-12)
        assert model.friction[iv] == pytest.approx(extra[f"{joint}.coulomb"], rel=1e-12)
    # the CAD model itself round-trips to its own parameters (the edit is the change, nothing else)
    cad = parameter_vector(ur5.model)
    same, _ = identified_urdf(Path(ur5.config.urdf).read_text(), ur5.model, cad, cad)
    (tmp_path / "cad.urdf").write_bytes(same)
    np.testing.assert_allclose(parameter_vector(reduced_model(tmp_path / "cad.urdf", ur5.config.joints)), cad,
                               rtol=0, atol=1e-12 * np.abs(cad).max())
    assert digest(ur5.config.urdf) == before


def test_a_change_no_link_can_carry_alone_is_shared_and_named(tmp_path):
    """The TIAGo's arm_7 body holds 11 URDF links (arm_7_link, the wrist sensor, the locked gripper): at half its
    CAD mass distribution, sharing the change by CAD mass would leave a link unrealisable, so the body's links
    carry the identified body scaled by their mass shares; the file still reduces exactly to the identified
    bodies, and every other body (arm_1's inconsistent CAD link included) is left as it was."""
    model = reduced_model(urdf_path(), JOINTS)
    cad = parameter_vector(model)
    lighter = cad.copy()
    lighter[70:80] = 0.5 * cad[70:80]
    data, remarks = identified_urdf(urdf_path().read_text(), model, lighter, cad)
    assert len(remarks) == 1 and "arm_7_joint" in remarks[0], remarks
    (tmp_path / "light.urdf").write_bytes(data)
    np.testing.assert_allclose(parameter_vector(reduced_model(tmp_path / "light.urdf", JOINTS)), lighter, rtol=0,
                               atol=1e-12 * np.abs(cad).max())


def test_no_urdf_when_the_solver_stopped_short(ur5, tmp_path):
    stopped = dataclasses.replace(ur5, consistent=dataclasses.replace(ur5.consistent, converged=False,
                                                                      status="MaxIterations"))
    files = write_identification(stopped, tmp_path / "out")
    assert not any(str(n).endswith(".urdf") for n in files)
    assert "No identified URDF written: the consistent fit's solver stopped short" in summary_text(stopped)
