"""Repeated postures: a row that repeats a posture of its block adds no information about the robot's geometry.

Two terms of a block measure the same posture when every joint reading of their samples agrees to
POSTURE_TOLERANCE (rad or m: the same row written again, possibly rounded differently) and, when backlash
is modelled, every joint was approached from the same side (data.approach), and, with sessions whose frame
is re-registered, they belong to the same session. A repeated posture
with a new measurement is usable data (it averages noise) and gets a note; a row that copies an earlier one
(same readings, same measured values) gets a note saying it counts that measurement twice, which makes the
standard errors too small. Either counts once toward what the data can determine. The rule, before any fit
(docs/config.md, "Bad input"): the measurement rows of the distinct postures, plus one per parameter with a
prior, must outnumber the free parameters. Equal numbers are refused too: the distinct postures then fit
exactly, and the repeats' zero residuals would pass for a noise estimate (standard errors of 1e-17 m).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError
from robocal.io.wording import plural

#: joint readings closer than this (rad or m) are one posture
POSTURE_TOLERANCE = 1e-6
#: repeated rows a note lists by number before it says how many more there are
LISTED_ROWS = 8


@dataclass
class PostureCount:
    """One block's terms against its distinct postures: the file rows that repeat an earlier posture of the
    block, and the measurement rows its distinct postures give."""

    block: str
    files: list[str]
    n_terms: int
    n_distinct: int
    repeated_rows: list[int]          # file line numbers of rows that repeat a posture with a new measurement
    copied_rows: list[int]            # ... and of rows that copy an earlier row (readings and measured values)
    distinct_rows: int


def posture_labels(values: np.ndarray) -> np.ndarray:
    """A label per sample: equal labels for readings that agree to POSTURE_TOLERANCE (rounded onto its grid)."""
    grid = np.round(np.asarray(values, dtype=float) / POSTURE_TOLERANCE)
    return np.unique(grid, axis=0, return_inverse=True)[1].reshape(-1) if len(grid) else np.zeros(0, int)


def posture_counts(setup) -> list[PostureCount]:
    """PostureCount of every block of the setup."""
    problem = setup.problem
    # an approach direction (-1, 0, +1) differs by 1 or 2: far off the grid, so it splits postures; so does a
    # session whose frame is re-registered (the same posture seen from another frame is new information)
    columns = [problem.values] + ([] if problem.directions is None else [problem.directions])
    if problem.sessions is not None and problem.sessions.corrected:
        columns.append(problem.sessions.of_sample[:, None].astype(float))
    labels = posture_labels(np.hstack(columns))
    out = []
    for res in problem.residuals:
        seen: dict[tuple, list[np.ndarray]] = {}
        repeated, copied = [], []
        for k in range(res.n_terms):
            key = tuple(int(labels[i]) for i in res.term_samples(k)) + res.term_feature(k)
            measured = res.measurements[k] if len(res.measurements) == res.n_terms else np.zeros(0)
            if key in seen:
                file, row = setup.sample_rows[res.term_samples(k)[0]]
                line = setup.tables[file].line(row) if file in setup.tables else row + 2
                same = any(np.array_equal(measured, m) for m in seen[key])
                (copied if same else repeated).append(line)
            seen.setdefault(key, []).append(measured)
        kept = int(np.count_nonzero(res.row_scale()))
        files = sorted({setup.sample_rows[int(i)][0] for i in np.unique(res.samples)})
        out.append(PostureCount(res.name, files, res.n_terms, len(seen), repeated, copied, len(seen) * kept))
    return out


def repeated_posture_notes(counts: list[PostureCount]) -> list[str]:
    """A note per block with repeated postures: how many rows, which ones, and what they do to the fit."""
    notes = []
    for c in counts:
        if not c.repeated_rows and not c.copied_rows:
            continue
        parts = []
        if c.repeated_rows:
            parts.append(f"{plural(len(c.repeated_rows), 'row')} {verb(c.repeated_rows, 'repeat')} an earlier posture "
                         "with a new measurement "
                         f"({listed(c.repeated_rows)}), averaging noise")
        if c.copied_rows:
            parts.append(f"{plural(len(c.copied_rows), 'row')} {verb(c.copied_rows, 'copy')} an earlier row, readings "
                         "and measured values "
                         f"({listed(c.copied_rows)}), so the fit counts those measurements twice and its standard "
                         "errors come out too small: remove them")
        notes.append(f"{', '.join(c.files)}: block '{c.block}' has {plural(c.n_terms, 'row')} at "
                     f"{plural(c.n_distinct, 'distinct posture')}; " + "; ".join(parts) +
                     "; a posture counts once toward what the data can determine")
    return notes


def verb(rows: list, word: str) -> str:
    """The verb agreeing with the number of rows: '1 row copies', '2 rows copy'."""
    return word if len(rows) != 1 else (word[:-1] + "ies" if word.endswith("y") else word + "s")


def listed(rows: list[int]) -> str:
    """'row 5', 'rows 5, 6', 'rows 5, 6, ... and 40 more' (the first LISTED_ROWS, then the count)."""
    more = len(rows) - LISTED_ROWS
    return (("row " if len(rows) == 1 else "rows ") + ", ".join(str(r) for r in rows[:LISTED_ROWS])
            + (f" and {more} more" if more > 0 else ""))


def check_distinct_postures(setup, counts: list[PostureCount]) -> None:
    """Refuse a fit whose distinct postures give no more measurement rows than it has free parameters (a
    parameter with a prior brings its own row)."""
    params = setup.problem.params
    free = params.free_names
    with_prior = sum(1 for n in free if params[n].prior_sigma is not None)
    rows = sum(c.distinct_rows for c in counts) + with_prior
    if rows > len(free):
        return
    terms, distinct = sum(c.n_terms for c in counts), sum(c.n_distinct for c in counts)
    repeats = terms - distinct
    files = sorted({f for c in counts for f in c.files})
    said = (f"{plural(terms, 'row')} hold {plural(distinct, 'distinct posture')} ({repeats} repeat an earlier "
            "posture)" if repeats else plural(distinct, "distinct posture"))
    priors = f" and {with_prior} prior rows" if with_prior else ""
    raise InputError(f"{said}, whose {rows - with_prior} measurement rows{priors} cannot determine {len(free)} free "
                     "parameters and the noise (more rows than parameters are needed); record more distinct postures, "
                     "or fix parameters (parameters.fix)",
                     source=", ".join(files) or setup.source)
