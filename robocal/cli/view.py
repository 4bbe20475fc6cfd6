"""`robocal view RESULT` and `robocal report RESULT`: the command-line side of the visual checks.

`add_parser(subparsers)` registers both sub-commands; robocal.cli.main dispatches to `cmd_view` / `cmd_report`.
Like robocal.cli.main, this module owns the terminal; the library modules it calls only log.
"""
from __future__ import annotations

import sys
import webbrowser
from pathlib import Path

from robocal.errors import InputError
from robocal.io.output_folder import add_to_manifest
from robocal.viz.scene import read_scene


def add_parser(subparsers) -> None:
    v = subparsers.add_parser("view", help="show a calibration result in meshcat (or write it as a static HTML page)")
    v.add_argument("result", help="output folder of `robocal calibrate` (with scene.json)")
    v.add_argument("--html", metavar="FILE", help="write a self-contained HTML page of the scene and exit "
                                                  "(no server, works headless)")
    v.add_argument("--sample", type=int, default=1, help="sample shown first (1-based, default 1)")
    v.add_argument("--no-meshes", action="store_true", help="simple shapes instead of the URDF's meshes")
    v.add_argument("--open", action="store_true", help="open the page (or the live viewer) in a web browser")
    r = subparsers.add_parser("report", help="write the HTML report of a calibration result")
    r.add_argument("result", help="output folder of `robocal calibrate`")
    r.add_argument("-o", "--output", help="report file (default: RESULT/report.html)")
    r.add_argument("--no-meshes", action="store_true", help="simple shapes in the 3D scene (a much smaller file)")
    for p in (v, r):
        p.add_argument("-q", "--quiet", action="store_true", help="print only errors")
    v.set_defaults(handler=cmd_view)
    r.set_defaults(handler=cmd_report)


def _scene(folder: str):
    path = Path(folder)
    if not path.exists():
        raise InputError("no such folder (give the output folder of `robocal calibrate`)", source=str(path))
    if path.is_dir() and not (path / "scene.json").is_file():
        raise InputError("no scene.json in this folder: give the output folder of `robocal calibrate`",
                         source=str(path))
    return read_scene(path)


def cmd_view(args) -> int:
    from robocal.viz.meshcat_check import SceneView   # meshcat: the optional [viz] extra

    scene = _scene(args.result)
    n = len(scene["values"])
    if not 1 <= args.sample <= n:
        raise InputError(f"--sample must be between 1 and {n}", field="--sample")
    if args.html:
        view = SceneView(scene, meshes=not args.no_meshes)
        out = Path(args.html).resolve()
        out.write_text(view.static_html(args.sample - 1), encoding="utf-8")
        if not args.quiet:
            print(f"Wrote {out}")
        if args.open:
            webbrowser.open(out.as_uri())
        return 0
    import meshcat   # the optional [viz] extra

    vis = meshcat.Visualizer()          # starts meshcat-server and prints its URL
    if args.open:
        vis.open()
    view = SceneView(scene, vis, meshes=not args.no_meshes).draw(args.sample - 1)
    return _step(view, n, args.sample - 1)


def _step(view, n: int, k: int) -> int:
    """Terminal stepping: Enter or n = next sample, p = previous, a number = that sample, q = quit."""
    print("Enter/n: next sample, p: previous, <number>: go to sample, q: quit", file=sys.stderr)
    while True:
        print(view.sample_label(k), file=sys.stderr)
        try:
            line = input("> ").strip().lower()
        except (EOFError, KeyboardInterrupt):
            return 0
        if line == "q":
            return 0
        if line.isdigit() and 1 <= int(line) <= n:
            k = int(line) - 1
        elif line == "p":
            k = (k - 1) % n
        elif line in ("", "n"):
            k = (k + 1) % n
        else:
            print(f"  not understood: {line!r}", file=sys.stderr)
            continue
        view.show_sample(k)


def cmd_report(args) -> int:
    from robocal.viz.report import write_report   # matplotlib: the optional [viz] extra

    path = write_report(args.result, args.output, meshes=not args.no_meshes)
    add_to_manifest(path)       # a report written into a result folder is robocal's: --force may replace it
    if not args.quiet:
        print(f"Wrote {path}")
    return 0
