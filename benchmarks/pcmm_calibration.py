"""Speed of the 4-PUU CMM self-calibration (docs/pcmm_calibration.md): 8 placements x 4 spheres x 9 hits,
analytic Jacobians, one core, through the generic layer (Problem + calibrate) with the closed-form residual
plug-in. The baseline in the same run is the other kinematics engine the generic layer offers: the URDF
closed chain (assembly of every hit). Prints a table; target: whole self-calibration under 1 s.

    OMP_NUM_THREADS=1 python benchmarks/pcmm_calibration.py
"""
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from robocal import load_urdf  # noqa: E402
from robocal.model.kinematics import ModelState  # noqa: E402
from robocal.systems.pcmm import error_model as pe  # noqa: E402
from robocal.systems.pcmm.calibration import (artefact_residual, calibrate_pcmm, check_acquisition,  # noqa: E402
                                              pcmm_problem)
from robocal.systems.pcmm.machine import (generic_parameters, reference_artefact, reference_geometry,  # noqa: E402
                                          reference_placements, reference_raw, simulate_probing)
from robocal.systems.pcmm.scene import urdf_problem  # noqa: E402


def best(f, repeat=5):
    times = []
    for k in range(repeat):
        t = time.perf_counter()
        out = f(k)
        times.append(time.perf_counter() - t)
    return min(times), out


nominal, art = reference_geometry(), reference_artefact()
cen, yaw = reference_placements()
raw = pe.random_raw_errors(reference_raw(), np.random.default_rng(3))
hits = simulate_probing(raw, art, cen, yaw, np.random.default_rng(4), noise=1e-6)
n = len(hits.readings)
problem = pcmm_problem(nominal, hits, art)


def evaluate_at_new_point(k):
    # each repetition at another parameter vector, as in the solver (the plug-in caches one machine)
    problem.params["limb1.l"].value = 1e-9 * (k + 1)
    return problem.evaluate()


t_jac, ev = best(evaluate_at_new_point)
t_check, _ = best(lambda k: check_acquisition(nominal, hits, art))
t_cal, res = best(lambda k: calibrate_pcmm(nominal, hits, art), repeat=3)
t_prior, prior = best(lambda k: calibrate_pcmm(nominal, hits, art, gauge="prior"), repeat=3)

# the URDF closed-chain engine: the same rows from assembling every hit (warm-started at the closed form)
urdf = urdf_problem(nominal, nominal, hits, art, os.path.join(os.environ.get("TMPDIR", "/tmp"), "pcmm_bench.urdf"),
                    artefact_residual(problem).kinematics(problem.aux_values(artefact_residual(problem))).poses)
t_urdf, _ = best(lambda k: urdf.evaluate(), repeat=1)
robot = load_urdf(os.path.join(os.path.dirname(__file__), "..", "urdf", "pcmm_4puu.urdf"))
ms = ModelState(robot, generic_parameters()[0], robot.loops.actuated)
t0 = time.perf_counter()
for k in range(40):
    s = ms.sample(hits.readings[k], label=k)
    s.frame_parameter_jacobian("probe_tip")
t_generic = (time.perf_counter() - t0) / 40

print(f"4-PUU CMM self-calibration benchmark: {n} hits, {len(ev.r)} rows, 32 parameters")
print(f"| {'step':56s} | {'time':>10s} |")
print(f"|{'-' * 58}|{'-' * 12}|")
print(f"| {'residuals + analytic Jacobian (closed-form plug-in)':56s} | {t_jac * 1e3:7.1f} ms |")
print(f"| {'acquisition check (rank, warnings)':56s} | {t_check * 1e3:7.1f} ms |")
print(f"| {f'whole self-calibration, gauge fix ({len(res.history)} LM iterations)':56s} | {t_cal * 1e3:7.1f} ms |")
label = f'whole self-calibration, gauge prior ({len(prior.history)} LM iterations)'
print(f"| {label:56s} | {t_prior * 1e3:7.1f} ms |")
print(f"| {'baseline: residuals + Jacobian on the URDF closed chain':56s} | {t_urdf * 1e3:7.1f} ms |")
print(f"| {'baseline: URDF path, per hit (assembly + J, cold start)':56s} | {t_generic * 1e3:7.2f} ms |")
print(f"closed-form plug-in vs URDF closed chain, one evaluation: {t_urdf / t_jac:.0f}x faster")
print(f"target: whole self-calibration < 1 s -> {'met' if t_cal < 1.0 else 'NOT met'}")
