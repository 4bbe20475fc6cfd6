"""Regenerate docs/architecture.md's "Every module" section from the first docstring line of each module.

Usage: python3 scripts/architecture_table.py   (tests/test_architecture.py checks the page is current)
"""
import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "architecture.md"
HEADING = "## Every module"
INTRO = ("The first line of each module's docstring (regenerate with `python3 scripts/architecture_table.py`;\n"
         "`tests/test_architecture.py` checks that the table is current).\n")


def first_line(path: Path) -> str:
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    line = doc.strip().split("\n\n", 1)[0].replace("\n", " ").strip()
    return line.replace("|", "\\|")


def section() -> str:
    package = ROOT / "robocal"
    folders = sorted({p.parent for p in package.rglob("*.py")}, key=lambda d: d.relative_to(package).parts)
    out = [HEADING, "", INTRO]
    for folder in folders:
        rel = "/".join(folder.relative_to(package).parts)
        out += [f"**`robocal/{rel + '/' if rel else ''}`**", "", "| module | job |", "|---|---|"]
        out += [f"| `{p.name}` | {first_line(p)} |" for p in sorted(folder.glob("*.py"))]
        out.append("")
    return "\n".join(out)


def current_page() -> str:
    text = PAGE.read_text(encoding="utf-8")
    head, _, rest = text.partition(HEADING)
    tail = rest.split("\n## ", 1)
    after = "\n## " + tail[1] if len(tail) > 1 else ""
    return head + section() + after


if __name__ == "__main__":
    PAGE.write_text(current_page(), encoding="utf-8")
    sys.exit(0)
