"""Write the simulated motor-side logs of the two examples (docs/dynamics_motors.md):

  ur5_coupled   a UR5 whose joint 6 is driven by motors 5 and 6 (q6 = m6 / 100 + 0.003 m5 + c6), every joint
                through a 100:1 gear; no time column (sample_period_s in the config)
  tiago_wrist   a TIAGo arm (arm_1..7, torso locked) whose wrist is differential: q6 = (m7 - m6)/2 + c6,
                q7 = (m6 + m7)/2 + c7 (the relations its controller's log satisfies), arm_1..5 through 100:1
                gears; a time column

each as two 20 s sessions at 5 kHz (100000 rows: motor encoder positions quantised to 2^14 counts a motor turn,
motor currents with 20 mA of white noise), session 1 for `robocal identify`, session 2 for `robocal evaluate`.
The transmission is the one of the example's config (read from it), the truth robot the URDF's with a point mass
added to every body, and the motors' rotor inertia, friction and offsets are TRUTH below.

    python examples/motor_dynamics/make_logs.py            # writes examples/motor_dynamics/data/ (~14 MB a log)
    robocal identify examples/motor_dynamics/ur5_coupled.yaml -o out_ur5
    robocal evaluate out_ur5 examples/motor_dynamics/ur5_coupled_session2.yaml
"""
from __future__ import annotations

import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robocal import load_example
from robocal.dynamics import motor_simulation as sim
from robocal.dynamics import reduced_model as reduced
from robocal.workflows import identify_config

HERE = Path(__file__).resolve().parent
RATE_HZ, SECONDS = 5000.0, 20.0
COUNTS_PER_REV = 2 ** 14
CURRENT_NOISE = 0.02                        # A, white, every motor
TRUTH = {
    "ur5_coupled": sim.MotorTerms(rotor_inertia=np.array([8e-5, 8e-5, 6e-5, 2e-5, 2e-5, 2e-5]),
                              coulomb=np.array([0.05, 0.05, 0.04, 0.02, 0.02, 0.02]),
                              viscous=np.array([4e-4, 4e-4, 3e-4, 1e-4, 1e-4, 1e-4]),
                              offset=np.array([0.01, -0.01, 0.005, 0.0, 0.002, -0.003])),
    "tiago_wrist": sim.MotorTerms(rotor_inertia=np.array([6e-5, 6e-5, 4e-5, 4e-5, 2e-5, 4e-3, 4e-3]),
                              coulomb=np.array([0.03, 0.04, 0.02, 0.02, 0.01, 0.1, 0.1]),
                              viscous=np.array([3e-4, 3e-4, 2e-4, 2e-4, 1e-4, 0.05, 0.05]),
                              offset=np.array([0.005, -0.005, 0.0, 0.002, 0.0, 0.02, -0.01])),
}


@dataclass
class Truth:
    """What the logs were made of: the truth robot (the config's joints free), the motors' terms, the Coulomb
    widths (rad/s), the config read."""

    robot: object
    motors: sim.MotorTerms
    width: np.ndarray
    config: object


def write_case(case: str, folder: Path, seed: int = 0, seconds: float = SECONDS, config: Path | None = None,
               noise_seed: int | None = None) -> Truth:
    """Write `case`'s two sessions (and its URDF) into `folder`; the config's paths are relative to `folder`'s
    parent, as the shipped configs'. seed: the truth robot, the trajectories and (unless noise_seed) the noise.
    Returns the truth."""
    folder.mkdir(parents=True, exist_ok=True)
    config = config or HERE / f"{case}.yaml"
    if case == "ur5_coupled":
        shutil.copyfile(load_example("ur5").urdf_path, folder / "ur5_robot.urdf")
    else:
        shutil.copyfile(HERE.parent / "tiago_mocap" / "data" / "tiago_48_schunk.urdf", folder / "tiago_48_schunk.urdf")
    cfg = identify_config.load_identify_config(config, folder.parent)
    tr = cfg.transmission
    model = reduced.reduced_model(cfg.urdf, cfg.joints)
    truth = sim.perturbed_model(model, seed + 100)
    t = np.arange(int(round(seconds * RATE_HZ))) / RATE_HZ
    spec = cfg.logs[0]
    width = None
    for session in (1, 2):
        q, v, a = sim.excitation(t, model, seed + 10 * session)
        if width is None:                   # the truth's tanh width: the identification's rule on session 1
            width = sim.coulomb_widths(tr, v, (t >= spec.train[0][0]) & (t < spec.train[0][1]), cfg.coulomb_width)
        tau_m = sim.motor_torques(truth, tr, TRUTH[case], q, v, a, width)
        m, current = sim.logged_signals(tr, q, tau_m, COUNTS_PER_REV, np.full(len(tr.motors), CURRENT_NOISE),
                                    np.random.default_rng((seed if noise_seed is None else noise_seed) + session))
        columns = [f"{x}_position" for x in tr.motors] + [f"{x}_current" for x in tr.motors]
        values = np.column_stack([m, current])
        if spec.sample_period is None:
            columns, values = ["t"] + columns, np.column_stack([t, values])
        path = folder / f"{case}_session{session}.csv"
        np.savetxt(path, values, delimiter=",", header=",".join(columns), comments="", fmt="%.9g")
    return Truth(truth, TRUTH[case], width, cfg)


if __name__ == "__main__":
    for name in sys.argv[1:] or list(TRUTH):
        write_case(name, HERE / "data")
        print(f"wrote {HERE / 'data' / name}_session1.csv, _session2.csv")
