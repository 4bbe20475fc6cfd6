"""Rod-end-floating hexapod: compensated IK, Newton FK, what ignoring the nut roll costs, URDF.

Source: Chinese invention patent (number lost in the surviving text), "Kinematics solution method with angle
compensation for a class of rod-end-floating six-degree-of-freedom parallel robots" (docs/floating_nut_hexapod.md).
Ends with the markdown table "spec figure / robocal figure / how computed" of that page; --write-docs writes
its tables into the page, --check-docs checks that the page shows them.
Run: OMP_NUM_THREADS=1 python examples/floating_nut_hexapod.py [output.urdf] [--write-docs | --check-docs]
"""
import sys
from pathlib import Path

import numpy as np

from robocal.io import page_differences, update_page

from robocal.systems.floating_nut import reference_fixture
from robocal.systems.floating_nut import FloatingNutKinematics
from robocal.systems.floating_nut import write_urdf

DEG = np.pi / 180
PAGE = Path(__file__).resolve().parents[1] / "docs" / "floating_nut_hexapod.md"
COMMAND = "OMP_NUM_THREADS=1 python examples/floating_nut_hexapod.py"
flags = {a for a in sys.argv[1:] if a.startswith("--")}
paths = [a for a in sys.argv[1:] if not a.startswith("--")]

# the reference fixture of docs/floating_nut_hexapod.md: lead 10 mm, sigma +1, radial axes
geometry = reference_fixture()
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
box = ["| box about p0 | max abs(theta) [deg] | max abs(l_a) [um] | uncompensated FK position error, max [um] |",
       "|---|---|---|---|"]
for half_t, half_r in [(0.05, 0.0), (0.0, 5 * DEG), (0.05, 5 * DEG), (0.1, 10 * DEG)]:
    offsets = np.hstack([rng.uniform(-half_t, half_t, (2000, 3)), rng.uniform(-half_r, half_r, (2000, 3))])
    poses = geometry.p0 + offsets
    lc, det = kin.ik(poses, return_details=True)
    err = np.linalg.norm(kin.fk(lc, compensate=False).pose[:, :3] - poses[:, :3], axis=1)
    label = ", ".join(([f"+-{half_t * 1e3:.0f} mm"] if half_t else ["no translation"])
                      + ([f"+-{half_r / DEG:.0f} deg"] if half_r else ["no rotation"]))
    box.append(f"| {label} | {np.abs(det.theta).max() / DEG:.2f} | {np.abs(det.additional).max() * 1e6:.1f} | "
               f"{err.max() * 1e6:.1f} |")
print("\n" + "\n".join(box))

# 4. The spec's reference figures (reference fixture) against robocal's, as a markdown table
SPEC_POSES = {  # pose (x, y, z m; alpha, beta, gamma deg): (theta deg, l_a um) as printed in the spec
    "P1": ((0, 0, 0.8, 0, 0, 10), [8.503557, 7.849111] * 3, [236.2099, 218.0309] * 3),
    "P2": ((0.1, 0, 0.8, 0, 0, 0), [-0.174655, 0.174655, 1.757807, 1.740926, -1.740926, -1.757807],
           [-4.8515, 4.8515, 48.8280, 48.3591, -48.3591, -48.8280]),
    "P3": ((0, 0, 0.9, 0, 0, 0), [-0.427037, 0.427037] * 3, [-11.8621, 11.8621] * 3),
    "P4": ((0, 0, 0.8, 10, 0, 0), [-2.961719, -3.195136, 3.243630, -0.559935, -0.826456, 4.420604],
           [-82.2700, -88.7538, 90.1008, -15.5538, -22.9571, 122.7946]),
    "P5": ((0.05, -0.05, 0.85, 5, -5, 8), [7.295120, 5.597100, 9.447946, 8.855239, 4.075170, 7.002543],
           [202.6422, 155.4750, 262.4429, 245.9789, 113.1992, 194.5151]),
}
SPEC_UNCOMPENSATED = {"P1": "dz = +253.44 um, dgamma = -0.49 mdeg", "P2": "dy = -95.98 um, dalpha = +5.39 mdeg",
                      "P3": "dgamma = +4.32 mdeg, no position error", "P4": "dx = +260.23 um",
                      "P5": "d = (88.5, -159.5, 201.4) um, rotation 2-3.6 mdeg"}
table = ["| quantity | spec figure | robocal figure | how computed |", "|---|---|---|---|"]
home = kin.home_lengths
table.append(f"| home strut length l_i(p_0) | 0.8901116038 m | {home.min():.10f} .. {home.max():.10f} m | "
             f"`FloatingNutKinematics.home_lengths` |")
table.append(f"| home dihedral phi_i(p_0) | -+37.831113 deg | "
             f"{', '.join(f'{v:+.6f}' for v in np.degrees(kin.home_dihedral))} deg | `home_dihedral` |")
for name, (p, theta_spec, la_spec) in SPEC_POSES.items():
    pose_k = np.array(p, float) * np.array([1, 1, 1, DEG, DEG, DEG])
    lc, det = kin.ik(pose_k, return_details=True)
    dth = np.abs(det.theta / DEG - theta_spec).max()
    dla = np.abs(det.additional * 1e6 - la_spec).max()
    table.append(f"| {name} nut roll theta, additional length l_a | printed to 1e-6 deg, 1e-4 um | "
                 f"max difference {dth:.1e} deg, {dla:.1e} um | `kin.ik(pose, return_details=True)` |")
    e = kin.fk(lc, compensate=False).pose - pose_k
    table.append(f"| {name} FK error if the nut roll is ignored | {SPEC_UNCOMPENSATED[name]} | "
                 f"d = ({e[0] * 1e6:+.2f}, {e[1] * 1e6:+.2f}, {e[2] * 1e6:+.2f}) um, rotation "
                 f"({e[3] / DEG * 1e3:+.2f}, {e[4] / DEG * 1e3:+.2f}, {e[5] / DEG * 1e3:+.2f}) mdeg | "
                 f"`kin.fk(ik(pose), compensate=False) - pose` |")
rng = np.random.default_rng(0)
offsets = np.hstack([rng.uniform(-0.1, 0.1, (2000, 3)), rng.uniform(-10 * DEG, 10 * DEG, (2000, 3))])
poses = geometry.p0 + offsets
lc, det = kin.ik(poses, return_details=True)
wrong = kin.fk(lc, compensate=False).pose - poses
pos_err = np.linalg.norm(wrong[:, :3], axis=1)
how = "2000 uniform poses in +-0.1 m / +-10 deg about p_0, seed 0 (the spec's sample is another random draw)"
table += [f"| box: max abs theta; mean of per-pose max | 17.3 deg; 7.6 deg | {np.abs(det.theta).max() / DEG:.1f} deg; "
          f"{np.abs(det.theta).max(axis=1).mean() / DEG:.1f} deg | {how} |",
          f"| box: max abs l_a | 0.48 mm | {np.abs(det.additional).max() * 1e3:.2f} mm | {how} |",
          f"| box: uncompensated FK position error, max; mean | 0.55 mm; 0.26 mm | {pos_err.max() * 1e3:.2f} mm; "
          f"{pos_err.mean() * 1e3:.2f} mm | {how} |",
          f"| box: uncompensated FK orientation error, max | 0.0105 deg | {np.abs(wrong[:, 3:]).max() / DEG:.4f} deg | "
          f"{how} (largest angle component) |",
          f"| FK Newton iterations from p_0 (P5) | 4 (rarely 3) | {fk.iterations} | `kin.fk(command)` |"]
print("\n" + "\n".join(table))
blocks = {"spec figures": "\n".join(table), "box": "\n".join(box)}
if "--check-docs" in flags:
    diffs = page_differences(PAGE, blocks)
    print("\n".join(diffs) or f"{PAGE.name} shows what this example prints")
    sys.exit(1 if diffs else 0)
if "--write-docs" in flags:
    update_page(PAGE, blocks, COMMAND)

# 5. The machine's URDF (tree + <loop_joint> closures + <screw_transmission> per leg)
if paths:
    print(f"\nwrote {write_urdf(geometry, paths[0])}")
