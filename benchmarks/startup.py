"""Benchmark: start-up of the `robocal` command against `python -c "import pinocchio"`, this tree and a baseline.

    OMP_NUM_THREADS=1 python benchmarks/startup.py [--baseline COMMIT] [--repeats 5] [--profile]

Rows: `python -c "import pinocchio"` (interpreter, numpy, Pinocchio: every command's floor), `robocal --version`,
and the first line of `robocal calibrate` on the demo config (the "robocal: ur5: 60 samples, ..." line on
stderr, printed once the config is read), timed from process start to that line. Each is a fresh process
with the tree first on sys.path and its bytecode compiled (benchmarks/cli_timing.py); wall time and CPU time
(user + system, from /proc/PID/stat when the line arrives, so other jobs' load does not count), medians of
`repeats`, baseline and new alternating. The goal (issue 37): within 0.1 s of `import pinocchio`.
`--profile` adds `-X importtime` of the first line's imports, grouped by package (this tree).
"""
from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from cli_timing import compile_bytecode  # noqa: E402
from workflow_timing import baseline_tree  # noqa: E402

DEMO = ROOT / "robocal" / "io" / "demo" / "ur5_calibrate.yaml"
TICK = os.sysconf("SC_CLK_TCK")
CODE = "import sys; sys.path.insert(0, sys.argv[1]); from robocal.cli.main import main; sys.exit(main(sys.argv[2:]))"


def cpu_of(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK          # utime + stime


def first_line(cmd: list[str], env: dict, cwd: Path) -> tuple[float, float]:
    """(wall s, CPU s) from start until the process writes its first line on stderr (or exits)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    proc.stderr.readline()
    wall = time.perf_counter() - t0
    cpu = cpu_of(proc.pid)
    proc.communicate()
    return wall, cpu


def whole(cmd: list[str], env: dict, cwd: Path) -> tuple[float, float]:
    """(wall s, CPU s) of a process run to its end."""
    t0 = time.perf_counter()
    before = os.times()
    subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, check=True)
    after = os.times()
    return time.perf_counter() - t0, (after.children_user - before.children_user) + (after.children_system -
                                                                                      before.children_system)


def import_profile(root: Path, env: dict) -> None:
    """-X importtime of `robocal calibrate`'s imports up to its first line, grouped by top package."""
    out = subprocess.run([sys.executable, "-X", "importtime", "-c", "import sys; sys.path.insert(0, sys.argv[1]); "
                          "import robocal.cli.calibrate", str(root)], env=env, capture_output=True, text=True).stderr
    groups: dict[str, int] = {}
    for m in re.finditer(r"import time:\s+(\d+) \|\s+\d+ \|\s*(\S+)", out):
        name = m[2]
        key = ".".join(name.split(".")[:2]) if name.startswith(("robocal", "scipy")) else name.split(".")[0]
        groups[key] = groups.get(key, 0) + int(m[1])
    print("\nimports of `robocal calibrate` before its first line (-X importtime, self time grouped, ms):")
    for key, us in sorted(groups.items(), key=lambda kv: -kv[1])[:16]:
        print(f"  {key:<28}{us / 1e3:8.1f}")
    print(f"  {'total':<28}{sum(groups.values()) / 1e3:8.1f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", default=None, help="commit of the baseline tree (default: merge base with main)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    commit = args.baseline or subprocess.run(["git", "-C", str(ROOT), "merge-base", "HEAD", "main"], check=True,
                                             capture_output=True, text=True).stdout.strip()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["OMP_NUM_THREADS"] = "1"
    with tempfile.TemporaryDirectory(prefix="robocal_startup_") as tmp:
        tmp = Path(tmp)
        trees = {"base": baseline_tree(commit, tmp / "base"), "new": ROOT}
        for root in trees.values():
            compile_bytecode(root)
        rows = {}
        for rep in range(args.repeats):
            rows.setdefault(("import pinocchio", ""), []).append(
                whole([sys.executable, "-c", "import pinocchio"], env, tmp))
            for name, root in (trees.items() if rep % 2 == 0 else reversed(trees.items())):
                rows.setdefault(("robocal --version", name), []).append(
                    whole([sys.executable, "-c", CODE, str(root), "--version"], env, tmp))
                out = tmp / f"out_{name}"
                rows.setdefault(("first line of robocal calibrate", name), []).append(first_line(
                    [sys.executable, "-c", CODE, str(root), "calibrate", str(DEMO), "-o", str(out), "--force"],
                    env, tmp))
        if args.profile:
            import_profile(ROOT, env)
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in rows.items()}
    floor = med[("import pinocchio", "")]
    print(f"\nbaseline: robocal at {commit[:7]}; new: this tree; medians of {args.repeats}, baseline and new "
          f"alternating; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores\n")
    print(f"{'':<42}{'wall s':>8}{'CPU s':>8}{'CPU - import pinocchio':>24}")
    label = 'python -c "import pinocchio"'
    print(f"{label:<42}{floor[0]:>8.3f}{floor[1]:>8.3f}{0:>24.3f}")
    for what in ("robocal --version", "first line of robocal calibrate"):
        for name in trees:
            wall, cpu = med[(what, name)]
            print(f"{what + ' (' + name + ')':<42}{wall:>8.3f}{cpu:>8.3f}{cpu - floor[1]:>+24.3f}")


if __name__ == "__main__":
    main()
