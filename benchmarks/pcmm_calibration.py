"""Speed of the 4-PUU CMM self-calibration (spec seed-003): 8 placements x 4 spheres x 9 hits, analytic
Jacobians, one core. Prints a table; target: whole self-calibration under 1 s.

    OMP_NUM_THREADS=1 python benchmarks/pcmm_calibration.py
"""
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from robocal import load_urdf  # noqa: E402
from robocal.model.kinematics import ModelState  # noqa: E402
from robocal.systems.pcmm import error_model as pe  # noqa: E402
from robocal.systems.pcmm.machine import (generic_parameters, reference_artefact, reference_geometry,  # noqa: E402
                                     reference_placements, reference_raw, simulate_probing)
from robocal.systems.pcmm.calibration import calibrate_pcmm, check_acquisition, evaluate  # noqa: E402


def best(f, repeat=5):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


nominal, art = reference_geometry(), reference_artefact()
cen, yaw = reference_placements()
raw = pe.random_raw_errors(reference_raw(), np.random.default_rng(3))
hits = simulate_probing(raw, art, cen, yaw, np.random.default_rng(4), noise=1e-6)
n = len(hits.readings)

t_eval, _ = best(lambda: evaluate(nominal, hits, art, jacobian=False))
t_jac, _ = best(lambda: evaluate(nominal, hits, art))
t_check, _ = best(lambda: check_acquisition(nominal, hits, art))
t_cal, res = best(lambda: calibrate_pcmm(nominal, hits, art), repeat=3)

robot = load_urdf(os.path.join(os.path.dirname(__file__), "..", "urdf", "pcmm_4puu.urdf"))
ms = ModelState(robot, generic_parameters()[0], robot.loops.actuated)
t0 = time.perf_counter()
for k in range(40):
    s = ms.sample(hits.readings[k], label=k)
    s.frame_parameter_jacobian("probe_tip")
t_generic = (time.perf_counter() - t0) / 40

print(f"4-PUU CMM self-calibration benchmark: {n} hits, {len(res.evaluation.rows)} rows, 32 parameters")
print(f"| {'step':44s} | {'time':>10s} |")
print(f"|{'-' * 46}|{'-' * 12}|")
print(f"| {'residuals (FK of all hits + 32 sphere fits)':44s} | {t_eval * 1e3:7.1f} ms |")
print(f"| {'residuals + analytic Jacobian':44s} | {t_jac * 1e3:7.1f} ms |")
print(f"| {'acquisition check (rank, warnings)':44s} | {t_check * 1e3:7.1f} ms |")
print(f"| {f'whole self-calibration ({len(res.history)} LM iterations)':44s} | {t_cal * 1e3:7.1f} ms |")
print(f"| {'generic URDF path, per hit (assembly + J)':44s} | {t_generic * 1e3:7.2f} ms |")
print(f"target: whole self-calibration < 1 s -> {'met' if t_cal < 1.0 else 'NOT met'}")
