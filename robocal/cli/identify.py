"""`robocal identify dyn.yaml`: dynamic identification from a joint log (robocal.workflows.identify)."""
from __future__ import annotations

from robocal.errors import InputError
from robocal.io.output_folder import write_folder


def cmd_identify(args) -> int:
    """Identify, print the summary, write the folder (-o, else the config's `output`); nothing is written
    for bad input (the error propagates to cli.main, which prints it and exits 2)."""
    # imported here: the dynamics stack (scipy.signal, scipy.stats) costs ~0.4 s of start-up that every
    # other command would pay
    from robocal.workflows.identify_outputs import identification_files
    from robocal.workflows.identify import identify_from_config
    res = identify_from_config(args.config)
    target = args.output if args.output is not None else res.config.output
    if target is None:
        raise InputError("no output folder: give -o or set `output` in the config", source=str(args.config),
                         field="output")
    contents, brief = identification_files(res)
    files = write_folder(target, contents, force=args.force)
    if args.quiet:
        print(brief, end="")
        return 0
    print(files["summary.txt"].read_text(encoding="utf-8"), end="")      # what was written, not a second run
    print(f"\nWrote {', '.join(str(f) for f in files.values())}")
    return 0


def evaluate_dynamics(folder, log_yaml, quiet: bool = False) -> int:
    """`robocal evaluate IDENTIFY_DIR LOG.yaml` for an identify output folder (robocal.cli.evaluate hands it
    over): per-joint RMSE of the identified model's prediction at the log's raw rows."""
    from robocal.workflows.identify_evaluate import evaluate_dynamics as run, write_evaluation
    ev = run(folder, log_yaml)
    reduced = ev.choices and ev.choices[0].startswith("log rate") and "reduced by" in ev.choices[0]
    print(f"Identified model of {folder} on {ev.name}: {len(ev.t)} {'rows' if reduced else 'raw rows'} scored "
          f"({ev.rows_total} in the window; the filter's trimmed edges left out"
          + ("; the rows kept by the rate reduction, against their raw readings)" if reduced else ")"))
    print(f"  {'motor' if ev.joints else 'joint':<20}{'RMSE vs logged':>18}{'RMSE vs filtered':>20}")
    fmt = ".4g" if ev.joints else ".3f"           # motor torques are small (N m on the motor shaft)
    for j, u, a, b in zip(ev.recorded, ev.units, ev.rmse_logged, ev.rmse_filtered):
        print(f"  {j:<20}{a:>14{fmt}} {u:<3}{b:>16{fmt}} {u:<3}")
    if ev.joints:
        print("The motors' errors mapped to the joints (tau = T^-T tau_m):")
        print(f"  {'joint':<20}{'RMSE vs logged':>18}{'RMSE vs filtered':>20}")
        for j, u, a, b in zip(ev.joints, ev.joint_units, ev.joint_rmse_logged, ev.joint_rmse_filtered):
            print(f"  {j:<20}{a:>14.3f} {u:<3}{b:>16.3f} {u:<3}")
    files = write_evaluation(folder, ev)
    if not quiet:
        print(f"\nWrote {', '.join(str(f) for f in files.values())}")
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("identify", help="identify inertial and friction parameters from a joint log "
                                               "(positions, velocities, efforts; or motor encoders and currents through a "
                                               "transmission: docs/dynamics_tiago.md, docs/dynamics_motors.md)")
    p.add_argument("config", help="identification YAML (examples/tiago_dynamics/identify.yaml)")
    p.add_argument("-o", "--output", help="output folder (default: the config's output)")
    p.add_argument("--force", action="store_true", help="replace an output folder robocal wrote")
    p.set_defaults(handler=cmd_identify)
