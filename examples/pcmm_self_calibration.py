"""Self-calibration of the 4-PUU parallel CMM from a 4-sphere artefact (spec seed-003, reference run §12.6).

Simulates the reference machine with all 52 raw error sources, probes 8 placements x 4 spheres x 9 hits,
identifies the 32 reduced parameters (noise 0 and 1 um on the axis readings) and prints the table of
docs/pcmm_calibration.md. Units in the table: mm.  Run: python examples/pcmm_self_calibration.py [seed]
"""
import sys

import numpy as np

from robocal.systems.pcmm import error_model as pe
from robocal.systems.pcmm.machine import (reference_artefact, reference_geometry, reference_placements, reference_raw,
                                     simulate_probing)
from robocal.systems.pcmm.kinematics import random_workspace_poses
from robocal.systems.pcmm.calibration import calibrate_pcmm, validate

seed = int(sys.argv[1]) if len(sys.argv) > 1 else 3
nominal, artefact = reference_geometry(), reference_artefact()
centroids, yaws = reference_placements()
raw = pe.random_raw_errors(reference_raw(), np.random.default_rng(seed))
true = pe.reduce(raw, nominal)
poses = random_workspace_poses(300, np.random.default_rng(seed + 100))

runs = {}
for noise in (1e-6, 0.0):
    hits = simulate_probing(raw, artefact, centroids, yaws, np.random.default_rng(seed + 1), noise=noise)
    runs[noise] = calibrate_pcmm(nominal, hits, artefact)
before = validate(true, nominal, poses)
after = {n: validate(true, r.geometry, poses) for n, r in runs.items()}
r1, r0 = runs[1e-6], runs[0.0]
mm = 1e3
rows = [
    ("residual RMS (all rows)", r1.rms_before["all"], r1.rms_after["all"], r0.rms_after["all"]),
    ("distance-error RMS", r1.rms_before["distance"], r1.rms_after["distance"], r0.rms_after["distance"]),
    ("radius-error RMS", r1.rms_before["radius"], r1.rms_after["radius"], r0.rms_after["radius"]),
    ("validation tip RMS (aligned, 300)", before.tip_rms, after[1e-6].tip_rms, after[0.0].tip_rms),
    ("validation tip max", before.tip_max, after[1e-6].tip_max, after[0.0].tip_max),
    ("validation pair-distance RMS", before.pair_rms, after[1e-6].pair_rms, after[0.0].pair_rms),
    ("validation pair-distance max", before.pair_max, after[1e-6].pair_max, after[0.0].pair_max),
]
print(f"4-PUU CMM self-calibration, truth seed {seed}, {len(r1.evaluation.rows)} rows, rank {r1.rank} of 32")
print(f"| {'quantity (mm)':36s} | {'nominal model':>13s} | {'LM, noise 1 um':>14s} | {'LM, noise 0':>11s} |")
print(f"|{'-' * 38}|{'-' * 15}|{'-' * 16}|{'-' * 13}|")
for name, a, b, c in rows:
    print(f"| {name:36s} | {a * mm:13.4g} | {b * mm:14.3g} | {c * mm:11.2g} |")
print(f"| {'LM iterations':36s} | {'-':>13s} | {len(r1.history):14d} | {len(r0.history):11d} |")
print(f"stopped: noise 1 um: {r1.message}; noise 0: {r0.message}")
