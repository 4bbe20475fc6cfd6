"""`robocal calibrate --no-report` timed from process start to exit, robocal as a user has it installed.

pip compiles a package's bytecode when it installs it (FIGAROH's virtual environment has every .pyc); an
editable checkout run with PYTHONDONTWRITEBYTECODE set (as on the benchmark machine) would compile every
robocal module from source at each start instead, ~0.1 s of a ~0.6 s run. So the tree's bytecode is compiled
once first (into robocal/**/__pycache__, ignored by git), then each run is a fresh process.
"""
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_compiled: set = set()


def compile_bytecode(root: Path) -> None:
    """What `pip install` does for a package: its modules' .pyc written once."""
    if root not in _compiled:
        subprocess.run([sys.executable, "-m", "compileall", "-q", str(root / "robocal")], check=True)
        _compiled.add(root)


def robocal_cli_seconds(root: Path, config: Path) -> float:
    """Seconds of `robocal calibrate CONFIG -o DIR --no-report -q` with the tree at `root`, files written."""
    compile_bytecode(root)
    with tempfile.TemporaryDirectory(prefix="robocal_cli_") as tmp:
        out = Path(tmp) / "out"          # a new folder: robocal refuses to write into one it did not make
        cmd = [sys.executable, "-c", "import sys; sys.path.insert(0, sys.argv[1]); from robocal.cli.main import main; "
               "sys.exit(main(sys.argv[2:]))", str(root), "calibrate", str(config), "-o", str(out), "--no-report", "-q"]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        seconds = time.perf_counter() - t0
        if not out.is_dir() or not any(out.iterdir()):
            raise RuntimeError("robocal calibrate wrote nothing")
        return seconds
