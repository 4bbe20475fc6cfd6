"""Generated blocks of a documentation page: the tables an example prints, kept between two marker lines.

A page holds, for each block NAME,

    <!-- generated: NAME, by COMMAND; do not edit, run the command with --write-docs -->
    ...the text the example printed...
    <!-- end generated: NAME -->

`update_page` rewrites the text between the markers (the rest of the page untouched, the file written
whole); `page_differences` says where a page no longer shows what an example prints. Numbers may differ by
one unit in their last printed digit (a figure computed on another CPU or libm can round the other way,
robocal.io.text_files); anything else must be identical. docs/architecture.md, "Docs from examples".
"""
from __future__ import annotations

import re
from pathlib import Path

from robocal.errors import InputError
from robocal.io.text_files import write_atomic

_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def begin_marker(name: str, command: str) -> str:
    return f"<!-- generated: {name}, by {command}; do not edit, run the command with --write-docs -->"


def end_marker(name: str) -> str:
    return f"<!-- end generated: {name} -->"


def _span(text: str, name: str, source: str) -> tuple[int, int, int]:
    """(start of the begin line, start of the content, start of the end line) of block `name`."""
    begins = [m for m in re.finditer(r"^<!-- generated: (.+?), by .*-->$", text, flags=re.M) if m.group(1) == name]
    end = end_marker(name)
    ends = [m.start() for m in re.finditer(re.escape(end), text)]
    if len(begins) != 1 or len(ends) != 1:
        raise InputError(f"the page needs exactly one generated block '{name}' (found {len(begins)} begin and "
                         f"{len(ends)} end markers)", source=source, field=name)
    b = begins[0]
    if ends[0] < b.end():
        raise InputError(f"generated block '{name}' ends before it begins", source=source, field=name)
    return b.start(), b.end() + 1, ends[0]


def read_block(text: str, name: str, source: str = "page") -> str:
    """The content of block `name` (without its markers)."""
    _, start, stop = _span(text, name, source)
    return text[start:stop]


def replace_block(text: str, name: str, content: str, command: str, source: str = "page") -> str:
    """The page with block `name` holding `content` (its begin marker naming `command`)."""
    first, _, stop = _span(text, name, source)
    body = content if content.endswith("\n") else content + "\n"
    return text[:first] + begin_marker(name, command) + "\n" + body + text[stop:]


def update_page(path, blocks: dict[str, str], command: str) -> Path:
    """Write every block {name: content} into the page at `path` (whole file or nothing)."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    for name, content in blocks.items():
        text = replace_block(text, name, content, command, source=str(path))
    return write_atomic(path, text)


def _last_digit_unit(token: str) -> float:
    """One unit in the last printed digit of a number as text ("0.0091" -> 1e-4, "2.3e-05" -> 1e-06)."""
    mantissa, _, exponent = token.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (-decimals + (int(exponent) if exponent else 0))


def same_figures(shown: str, printed: str) -> list[str]:
    """Differences between a block as the page shows it and as the example prints it: the text around the
    numbers must be identical, and each number within one unit of its last printed digit."""
    def split(text):
        return _NUMBER.sub("#", text), _NUMBER.findall(text)
    (skel_a, nums_a), (skel_b, nums_b) = split(shown.strip()), split(printed.strip())
    if skel_a != skel_b or len(nums_a) != len(nums_b):
        for k, (a, b) in enumerate(zip(shown.strip().splitlines(), printed.strip().splitlines())):
            if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
                return [f"line {k + 1} differs: page '{a}', example '{b}'"]
        return ["the page and the example have different numbers of lines"]
    out = []
    for a, b in zip(nums_a, nums_b):
        if abs(float(a) - float(b)) > 1.0001 * max(_last_digit_unit(a), _last_digit_unit(b)):
            out.append(f"page shows {a}, example prints {b}")
    return out


def page_differences(path, blocks: dict[str, str]) -> list[str]:
    """For each block {name: content the example prints}: what the page at `path` shows differently."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    out = []
    for name, content in blocks.items():
        out += [f"{path.name}, block '{name}': {d}" for d in same_figures(read_block(text, name, str(path)), content)]
    return out
