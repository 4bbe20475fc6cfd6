"""FIGAROH (PyPI `figaroh`) in its own virtual environment, for the side-by-side benchmarks.

FIGAROH never enters robocal's environment: `--figaroh` creates (once) a virtual environment with
`pip install figaroh==1.0.2` (which brings Pinocchio as PyPI `pin`, numpy, scipy, pandas), and the
benchmarks run a driver script from benchmarks/figaroh/ with that environment's python in a subprocess.
Request and answer travel as JSON files. Without `--figaroh` a benchmark prints `skip_message()`.

    add_options(parser)            --figaroh, --figaroh-venv PATH
    figaroh_python(args)           the venv's python (created on first use), or None without --figaroh
    run_driver(python, name, req)  run benchmarks/figaroh/<name> on the request; (answer, wall seconds)
"""
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FIGAROH_VERSION = "1.0.2"
DEFAULT_VENV = Path.home() / ".cache" / "robocal-bench" / "figaroh-venv"
DRIVERS = Path(__file__).resolve().parent / "figaroh"
# what the drivers import; the version check catches a venv left by another FIGAROH release
IMPORT_CHECK = ("import importlib.metadata as m, pinocchio, pandas, scipy; "
                "from figaroh.calibration.base_calibration import BaseCalibration; "
                "from figaroh.identification.base_identification import BaseIdentification; "
                f"assert m.version('figaroh') == '{FIGAROH_VERSION}', m.version('figaroh')")


def add_options(parser) -> None:
    parser.add_argument("--figaroh", action="store_true",
                        help=f"also run FIGAROH {FIGAROH_VERSION}, installed into its own virtual environment")
    parser.add_argument("--figaroh-venv", type=Path, default=DEFAULT_VENV,
                        help="where that virtual environment lives (default: %(default)s)")


def skip_message() -> str:
    return (f"FIGAROH skipped: add --figaroh to install PyPI figaroh=={FIGAROH_VERSION} into its own virtual "
            f"environment (default {DEFAULT_VENV}, --figaroh-venv PATH) and compare.")


def child_env() -> dict:
    """The caller's environment without robocal's import path, one thread for BLAS like the benchmarks."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["OMP_NUM_THREADS"] = "1"
    return env


def _imports_ok(python: Path) -> bool:
    if not python.exists():
        return False
    run = subprocess.run([str(python), "-c", IMPORT_CHECK], env=child_env(), capture_output=True, text=True)
    return run.returncode == 0


def ensure_venv(path: Path) -> Path:
    """The python of a virtual environment at `path` holding figaroh==FIGAROH_VERSION (made if needed)."""
    python = Path(path) / "bin" / "python"
    if _imports_ok(python):
        return python
    print(f"installing figaroh=={FIGAROH_VERSION} into {path} (once) ...", flush=True)
    subprocess.run([sys.executable, "-m", "venv", str(path)], check=True)
    pip = subprocess.run([str(python), "-m", "pip", "install", "--quiet", f"figaroh=={FIGAROH_VERSION}"],
                         env=child_env(), capture_output=True, text=True)
    if pip.returncode != 0:
        raise RuntimeError(f"pip install figaroh=={FIGAROH_VERSION} into {path} failed:\n{pip.stderr[-3000:]}")
    if not _imports_ok(python):
        raise RuntimeError(f"{python}: figaroh=={FIGAROH_VERSION} installed but does not import "
                           f"(try: {python} -c \"{IMPORT_CHECK}\")")
    return python


def figaroh_python(args) -> Path | None:
    """The FIGAROH venv's python when --figaroh was given; otherwise prints the skip message, returns None."""
    if not args.figaroh:
        print(skip_message())
        return None
    return ensure_venv(args.figaroh_venv)


def run_driver(python: Path, driver: str, request: dict) -> tuple[dict, float]:
    """Run benchmarks/figaroh/<driver> with `python` on `request`; (its JSON answer, wall seconds from
    process start to exit)."""
    with tempfile.TemporaryDirectory(prefix="robocal_figaroh_") as tmp:
        req = dict(request, result=str(Path(tmp) / "answer.json"))
        req.setdefault("workdir", str(Path(tmp) / "work"))
        req_path = Path(tmp) / "request.json"
        req_path.write_text(json.dumps(req))
        t0 = time.perf_counter()
        run = subprocess.run([str(python), str(DRIVERS / driver), str(req_path)], env=child_env(),
                             capture_output=True, text=True)
        seconds = time.perf_counter() - t0
        if run.returncode != 0:
            raise RuntimeError(f"FIGAROH driver {driver} failed ({run.returncode}):\n{run.stderr[-3000:]}")
        return json.loads(Path(req["result"]).read_text()), seconds
