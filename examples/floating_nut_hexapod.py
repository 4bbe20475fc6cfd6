"""Rod-end-floating hexapod: compensated IK, Newton FK, what ignoring the nut roll costs, URDF.

Run: OMP_NUM_THREADS=1 python examples/floating_nut_hexapod.py [output.urdf]
"""
import sys

import numpy as np

from robocal.systems.floating_nut.geometry import reference_fixture
from robocal.systems.floating_nut.kinematics import FloatingNutKinematics
from robocal.systems.floating_nut.urdf import write_urdf

DEG = np.pi / 180

geometry = reference_fixture()                      # seed-002 fixture: lead 10 mm, sigma +1, radial axes
kin = FloatingNutKinematics(geometry)

# 1. IK at a pose: effective length, nut rotation, additional length, motor command length
pose = np.array([0.05, -0.05, 0.85, 5 * DEG, -5 * DEG, 8 * DEG])
command, d = kin.ik(pose, return_details=True)
print("leg   l [m]      theta [deg]   l_a [um]   l_c [m]     motor [turns]")
for i in range(6):
    turns = kin.lengths_to_motor(command)[i] / (2 * np.pi)
    print(f"{i + 1:3d}  {d.lengths[i]:.6f}  {d.theta[i] / DEG:11.5f}  {d.additional[i] * 1e6:9.3f}"
          f"  {command[i]:.6f}  {turns:10.4f}")

# 2. FK from the command lengths, and the error an uncompensated model would make
fk = kin.fk(command)
wrong = kin.fk(command, compensate=False).pose - pose
print(f"\nFK: {fk.iterations} Newton iterations, pose error {np.abs(fk.pose - pose).max():.1e}")
print(f"ignoring the nut roll: position error {np.linalg.norm(wrong[:3]) * 1e6:.1f} um, "
      f"orientation error {np.abs(wrong[3:]).max() / DEG * 1e3:.2f} mdeg")

# 3. Compensation magnitude over workspace boxes about the home pose
rng = np.random.default_rng(0)
print("\nbox (translation, rotation)   max |theta| [deg]   max |l_a| [um]   uncompensated FK error max [um]")
for half_t, half_r in [(0.05, 0.0), (0.0, 5 * DEG), (0.05, 5 * DEG), (0.1, 10 * DEG)]:
    offsets = np.hstack([rng.uniform(-half_t, half_t, (2000, 3)), rng.uniform(-half_r, half_r, (2000, 3))])
    poses = geometry.p0 + offsets
    lc, det = kin.ik(poses, return_details=True)
    err = np.linalg.norm(kin.fk(lc, compensate=False).pose[:, :3] - poses[:, :3], axis=1)
    print(f"+-{half_t * 1e3:3.0f} mm, +-{half_r / DEG:4.1f} deg"
          f"{np.abs(det.theta).max() / DEG:18.2f}{np.abs(det.additional).max() * 1e6:17.1f}{err.max() * 1e6:22.1f}")

# 4. The machine's URDF (tree + <loop_joint> closures + <screw_transmission> per leg)
if len(sys.argv) > 1:
    print(f"\nwrote {write_urdf(geometry, sys.argv[1])}")
