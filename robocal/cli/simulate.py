"""`robocal simulate CONFIG`: a synthetic dataset and its truth from the config's `simulation:` section."""
from __future__ import annotations

from robocal.workflows.simulate import simulate_dataset


def cmd_simulate(args) -> int:
    written = simulate_dataset(args.config, args.output, seed=args.seed, force=args.force)
    if not args.quiet:
        print("Wrote " + ", ".join(str(p) for p in written))
    return 0


def add_parser(subparsers) -> None:
    s = subparsers.add_parser("simulate", help="write a synthetic dataset (and its truth) from a YAML config")
    s.add_argument("config", help="calibration YAML with a simulation: section (docs/config.md)")
    s.add_argument("-o", "--output", help="CSV to write (default: the config's data.csv)")
    s.add_argument("--seed", type=int, default=None, help="seed of the random readings, parameter errors and noise; the same seed "
                   "gives the same file (default: the config's simulation.seed, else 0)")
    s.add_argument("--force", action="store_true", help="replace the CSV and its truth JSON if they exist")
    s.add_argument("-q", "--quiet", action="store_true", help="print only errors")
    s.set_defaults(handler=cmd_simulate)
