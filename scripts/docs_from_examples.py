"""Write (or check) every documentation table an example generates (docs/architecture.md, "Docs from examples").

Run:  OMP_NUM_THREADS=1 python scripts/docs_from_examples.py [--check]
Runs each registered example with --write-docs (or --check-docs), one after the other; the Stewart example
takes about 2 min of one core, the others seconds. tests/test_docs_from_examples.py checks the same list.
To register a page: put its markers in the page, give the example the two flags, add its command here.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = [
    ["examples/stewart_calibration.py"],
    ["examples/laser_psd_zero_offsets.py", "--table-only"],
    ["examples/pcmm_self_calibration.py"],
    ["examples/floating_nut_hexapod.py"],
    ["examples/floating_nut_calibration.py"],
    ["examples/force_deburring.py"],
]


def run(command: list[str], flag: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, *command, flag], cwd=ROOT, env=env, capture_output=True, text=True)


def main() -> int:
    flag = "--check-docs" if "--check" in sys.argv[1:] else "--write-docs"
    failed = 0
    for command in EXAMPLES:
        done = run(command, flag)
        print(f"{' '.join(command)} {flag}: {'ok' if done.returncode == 0 else 'FAILED'}")
        if done.returncode:
            failed += 1
            print(done.stdout[-2000:] + done.stderr[-2000:])
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
