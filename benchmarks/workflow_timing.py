"""Benchmark: every command on every shipped example, end to end in a fresh process, against a baseline tree.

    OMP_NUM_THREADS=1 python benchmarks/workflow_timing.py [--baseline COMMIT] [--repeats 5] [--only WORD] [--skip WORD]

Each run is `python -c "from robocal.cli.main import main; sys.argv = ['robocal', *ARGS]; main()"` with one
tree first on sys.path, as the `robocal` script runs it, bytecode compiled first (benchmarks/cli_timing.py: what pip leaves installed). The
baseline tree is `git archive COMMIT robocal` (default: the merge base with main) unpacked into a temporary
folder. Baseline and new runs alternate within each repeat, so load from other jobs on the shared machine hits
both alike; the table gives medians of the repeats, wall time and CPU time (user + system of the child, which
waiting for a core does not inflate). "work" is the command's CPU time minus that of `python -c "import
pinocchio"` (interpreter, numpy and Pinocchio: what every command starts with) in the same run.

Examples: the demo (robocal/io/demo/ur5_calibrate.yaml), examples/tiago_mocap/*.yaml (the select_* configs are
timed with `robocal select` and `cv`), examples/closed_loops/*.yaml, examples/camera/camera.yaml (calibrate, report, view --html, evaluate on its second session, select, cv) and camera_sessions.yaml (calibrate, select),
examples/plan_ur5.yaml, an ISO 9283 data set written by this script (tests/test_iso9283_cli.py's recipe), and the
dynamics configs examples/tiago_dynamics/identify.yaml and examples/motor_dynamics/{ur5_coupled,tiago_wrist}.yaml
(identify, then evaluate of its folder).
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from cli_timing import compile_bytecode  # noqa: E402

EX = ROOT / "examples"
TIAGO = EX / "tiago_mocap"
VALIDATION = TIAGO / "data" / "qualisys_2021-11-26_static_postures.csv"
MOTOR = ("ur5_coupled", "tiago_wrist")


def run_once(root: Path, argv: list[str], cwd: Path, may_fail: bool = False) -> tuple[float, float]:
    """(wall s, CPU s) of one command in a fresh process with the tree at `root` first on sys.path; with
    `may_fail` (the baseline tree) a crash gives (nan, nan), printed as such, instead of stopping the run."""
    code = ("import sys; sys.path.insert(0, sys.argv[1]); from robocal.cli.main import main; "
            "sys.argv = ['robocal'] + sys.argv[2:]; sys.exit(main())") if argv is not None else "import pinocchio"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["OMP_NUM_THREADS"] = "1"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code, str(root), *(argv or [])], cwd=cwd, env=env,
                          capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 3) and may_fail:
        return float("nan"), float("nan")
    if proc.returncode not in (0, 3):       # 3: a fit refused or rejected, still a complete run
        raise RuntimeError(f"{root}: robocal {' '.join(argv or [])} exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def iso9283_config(folder: Path) -> Path:
    """The ISO 9283 data set of tests/test_iso9283_cli.py (50 calibration rows, 3 poses x 6 cycles)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from test_iso9283_cli import _write_dataset   # the tests' recipe, not a second copy of it
    folder.mkdir(parents=True, exist_ok=True)
    return _write_dataset(folder)[0]


def cases(tmp: Path) -> list[tuple[str, str, object]]:
    """(command, example, argv builder(out_dir) or None for the start-up rows)."""
    calibrations = [("demo ur5", ROOT / "robocal" / "io" / "demo" / "ur5_calibrate.yaml")]
    calibrations += [(f"tiago {p.stem}", p) for p in sorted(TIAGO.glob("*.yaml")) if not p.stem.startswith("select")]
    calibrations += [(f"closed {p.stem}", p) for p in sorted((EX / "closed_loops").glob("*.yaml"))]
    out: list[tuple[str, str, object]] = [("import pinocchio", "", None),
                                          ("robocal --version", "", lambda d: ["--version"])]
    for label, cfg in calibrations:
        key = label.replace(" ", "_")
        out.append(("calibrate", label, lambda d, c=cfg, k=key: ["calibrate", str(c), "-o", str(d / k), "--force", "-q"]))
        data = VALIDATION if label.startswith("tiago") else None
        if data is None:   # no second session shipped: score the training data again (same work)
            import yaml
            raw = yaml.safe_load(cfg.read_text())
            data = (cfg.parent / raw["data"]["csv"]).resolve()
        out.append(("evaluate", label, lambda d, k=key, v=data: ["evaluate", str(d / k), str(v)]))
        out.append(("report", label, lambda d, k=key: ["report", str(d / k), "-q"]))
        out.append(("view --html", label, lambda d, k=key: ["view", str(d / k), "--html", str(d / f"{k}.html"), "-q"]))
        out.append(("cv", label, lambda d, c=cfg: ["cv", str(c), "-q"]))
        out.append(("cv --loo", label, lambda d, c=cfg: ["cv", str(c), "--loo", "-q"]))
    for cfg in sorted(TIAGO.glob("select*.yaml")):
        label = f"tiago {cfg.stem}"
        out.append(("select", label, lambda d, c=cfg: ["select", str(c), "-o", str(d / c.stem), "--force", "-q"]))
        out.append(("cv", label, lambda d, c=cfg: ["cv", str(c), "-q"]))
        out.append(("cv --loo", label, lambda d, c=cfg: ["cv", str(c), "--loo", "-q"]))
    camera = EX / "camera" / "camera.yaml"
    out.append(("calibrate", "camera", lambda d: ["calibrate", str(camera), "-o", str(d / "camera_cal"), "--force", "-q"]))
    out.append(("report", "camera", lambda d: ["report", str(d / "camera_cal"), "-q"]))
    out.append(("view --html", "camera", lambda d: ["view", str(d / "camera_cal"), "--html", str(d / "camera.html"), "-q"]))
    out.append(("evaluate", "camera (session 2)", lambda d: [
        "evaluate", str(d / "camera_cal"), str(EX / "camera" / "joints_session2.csv"), "--detections",
        str(EX / "camera" / "detections_session2.csv"), "--refit", "camera.target.*", "-q"]))
    out.append(("select", "camera", lambda d: ["select", str(camera), "-o", str(d / "camera"), "--force", "-q"]))
    out.append(("cv", "camera", lambda d: ["cv", str(camera), "-q"]))
    out.append(("cv --loo", "camera", lambda d: ["cv", str(camera), "--loo", "-q"]))
    sessions = EX / "camera" / "camera_sessions.yaml"
    out.append(("calibrate", "camera sessions", lambda d: ["calibrate", str(sessions), "-o", str(d / "camera_s"),
                                                           "--force", "-q"]))
    out.append(("select", "camera sessions", lambda d: ["select", str(sessions), "-o", str(d / "camera_ss"), "--force",
                                                        "-q"]))
    iso = iso9283_config(tmp / "iso")
    out.append(("iso9283", "ur5 iso (50 + 18 rows)", lambda d: ["iso9283", str(iso), "-q"]))
    out.append(("plan", "plan_ur5.yaml", lambda d: ["plan", str(EX / "plan_ur5.yaml"), "-o", str(d / "plan"),
                                                    "--force", "-q"]))
    out += identify_cases(tmp)
    return out


def identify_cases(tmp: Path) -> list[tuple[str, str, object]]:
    """`robocal identify` on each shipped dynamics config, then `robocal evaluate` of its folder on another log:
    the motor examples' second sessions (their 5 kHz logs written by examples/motor_dynamics/make_logs.py when
    missing: not in git, ~14 MB each), the TIAGo's own 60 s log (no second log shipped: the same work)."""
    motor = EX / "motor_dynamics"
    if not all((motor / "data" / f"{n}_session{s}.csv").is_file() for n in MOTOR for s in (1, 2)):
        subprocess.run([sys.executable, str(motor / "make_logs.py")], check=True, capture_output=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    tiago_log = tmp / "tiago_60s.yaml"
    data = EX / "tiago_dynamics" / "data"
    tiago_log.write_text(f"name: tiago_60s\nposition: {data / 'tiago_position.csv'}\n"
                         f"velocity: {data / 'tiago_velocity.csv'}\neffort: {data / 'tiago_effort.csv'}\n"
                         "window: [9.2, 60.0]\n")
    configs = [("tiago_dynamics", EX / "tiago_dynamics" / "identify.yaml", tiago_log)]
    configs += [(f"motor {n}", motor / f"{n}.yaml", motor / f"{n}_session2.yaml") for n in MOTOR]
    out = []
    for label, cfg, log in configs:
        key = "identify_" + label.replace(" ", "_")
        out.append(("identify", label, lambda d, c=cfg, k=key: ["identify", str(c), "-o", str(d / k), "--force",
                                                                "-q"]))
        out.append(("evaluate", f"{label} (identify)", lambda d, k=key, v=log: ["evaluate", str(d / k), str(v)]))
    return out


def baseline_tree(commit: str, into: Path) -> Path:
    into.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit, "robocal"], check=True, capture_output=True)
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive.stdout, check=True)
    return into


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", default=None, help="commit of the baseline tree (default: merge base with main)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--only", action="append", default=[], help="time only rows whose command or example holds this")
    ap.add_argument("--skip", action="append", default=[], help="leave out rows whose 'command example' holds this")
    ap.add_argument("--no-baseline", action="store_true", help="time this tree alone")
    args = ap.parse_args()
    commit = args.baseline or subprocess.run(["git", "-C", str(ROOT), "merge-base", "HEAD", "main"], check=True,
                                             capture_output=True, text=True).stdout.strip()
    with tempfile.TemporaryDirectory(prefix="robocal_workflow_") as tmp:
        tmp = Path(tmp)
        trees = {"new": ROOT}
        if not args.no_baseline:
            trees = {"base": baseline_tree(commit, tmp / "base"), "new": ROOT}
        for root in trees.values():
            compile_bytecode(root)
        rows = [c for c in cases(tmp) if not args.only or c[2] is None or c[0] == "robocal --version"
                or any(w in c[0] or w in c[1] for w in args.only)]
        rows = [c for c in rows if not any(w in f"{c[0]} {c[1]}" for w in args.skip)]
        times: dict[tuple, list] = {}
        load = os.getloadavg()[0]
        for rep in range(args.repeats):
            for name, root in (trees.items() if rep % 2 == 0 else reversed(trees.items())):
                for cmd, label, argv in rows:
                    out = tmp / f"out_{name}"
                    out.mkdir(exist_ok=True)
                    times.setdefault((cmd, label, name), []).append(
                        run_once(root, None if argv is None else argv(out), out, may_fail=name == "base"))
        med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in times.items()}
        same = same_identification(tmp / "out_base", tmp / "out_new") if "base" in trees else []
    print(f"baseline: robocal at {commit[:7]}; new: this tree; medians of {args.repeats}, baseline and new alternating; "
          f"load average {load:.1f} -> {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print("work = CPU s of the command - CPU s of `python -c \"import pinocchio\"` (same run); nan: the baseline "
          "crashed on it\n")
    names = list(trees)
    head = f"{'command':<18}{'example':<46}"
    for n in names:
        head += f"{n + ' wall':>10}{n + ' cpu':>10}"
    head += f"{'new work':>10}" + (f"{'cpu base/new':>14}" if len(names) == 2 else "")
    print(head)
    floor = {n: med[("import pinocchio", "", n)][1] for n in names}
    for cmd, label, _ in rows:
        line = f"{cmd:<18}{label:<46}"
        for n in names:
            line += f"{med[(cmd, label, n)][0]:>10.3f}{med[(cmd, label, n)][1]:>10.3f}"
        line += f"{med[(cmd, label, 'new')][1] - floor['new']:>10.3f}"
        if len(names) == 2:
            line += f"{med[(cmd, label, 'base')][1] / med[(cmd, label, 'new')][1]:>13.2f}x"
        print(line)
    for line in same:
        print(line)


def numbers(x, path=""):
    """Every number of a JSON value, keyed by its path; strings too (a changed word is a changed result)."""
    if isinstance(x, dict):
        return {k: v for key, val in x.items() for k, v in numbers(val, f"{path}/{key}").items()}
    if isinstance(x, list):
        return {k: v for i, val in enumerate(x) for k, v in numbers(val, f"{path}[{i}]").items()}
    return {path: x}


def same_identification(base: Path, new: Path, rtol: float = 1e-9) -> list[str]:
    """The identify folders' result.json and evaluation_*.json of both trees, number by number: the largest
    relative difference (issue 37: a speed change moves no result beyond rounding, 1e-9)."""
    import json
    out = []
    for folder in sorted(new.glob("identify_*")):
        for f in sorted(p for p in folder.glob("*.json") if not p.name.startswith(".")):   # not the manifest
            a, b = numbers(json.loads((base / folder.name / f.name).read_text())), numbers(json.loads(f.read_text()))
            if a.keys() != b.keys():
                raise AssertionError(f"{folder.name}/{f.name}: keys differ: {sorted(a.keys() ^ b.keys())[:5]}")
            worst, where = 0.0, ""
            for k, va in a.items():
                vb = b[k]
                if isinstance(va, (int, float)) and isinstance(vb, (int, float)) and not isinstance(va, bool):
                    d = abs(va - vb) / max(abs(va), abs(vb), 1e-300) if va != vb else 0.0
                    if d > worst:
                        worst, where = d, k
                elif va != vb and not (isinstance(va, str) and base.name in va):    # paths name their tree
                    raise AssertionError(f"{folder.name}/{f.name}{k}: {va!r} against {vb!r}")
            if worst > rtol:
                raise AssertionError(f"{folder.name}/{f.name}{where}: relative difference {worst:.2e} > {rtol}")
            out.append(f"same result: {folder.name}/{f.name}, {len(a)} values, largest relative difference "
                       f"{worst:.1e}{' at ' + where if where else ''}")
    return out


if __name__ == "__main__":
    main()
