"""Import one module of robocal as it was at an earlier commit, so that a benchmark times the old code next to the
current one in the same process (the commit must be in this repository's history)."""
import importlib.util
import os
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def module_at_commit(commit, path, name):
    """The module `path` (relative to the repository) as it was at `commit`, imported from a temporary file."""
    source = subprocess.run(["git", "-C", ROOT, "show", f"{commit}:{path}"], check=True, capture_output=True,
                            text=True).stdout
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as f:
        f.write(source)
    try:
        spec = importlib.util.spec_from_file_location(name, f.name)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        os.unlink(f.name)
    return module
