"""Repeated postures: a row that repeats a posture of its block adds no information about the robot's geometry.

Two terms of a block measure the same posture when every joint reading of their samples agrees to
POSTURE_TOLERANCE (rad or m: the same row written again, possibly rounded differently). A repeated posture
is usable data (it averages noise) and gets a note naming how many rows repeat which; but it counts once
toward what the data can determine. The rule, before any fit (docs/config.md, "Bad input"): the
measurement rows of the distinct postures, plus one per parameter with a prior, must be at least the
free parameters, the count the solver needs (robocal.estimation.calibrate) with repeats taken out.
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
    repeated_rows: list[int]          # file line numbers
    distinct_rows: int


def posture_labels(values: np.ndarray) -> np.ndarray:
    """A label per sample: equal labels for readings that agree to POSTURE_TOLERANCE (rounded onto its grid)."""
    grid = np.round(np.asarray(values, dtype=float) / POSTURE_TOLERANCE)
    return np.unique(grid, axis=0, return_inverse=True)[1].reshape(-1) if len(grid) else np.zeros(0, int)


def posture_counts(setup) -> list[PostureCount]:
    """PostureCount of every block of the setup."""
    labels = posture_labels(setup.problem.values)
    out = []
    for res in setup.problem.residuals:
        seen: set[tuple] = set()
        repeated = []
        for k in range(res.n_terms):
            key = tuple(int(labels[i]) for i in res.term_samples(k))
            if key in seen:
                file, row = setup.sample_rows[res.term_samples(k)[0]]
                repeated.append(setup.tables[file].line(row) if file in setup.tables else row + 2)
            seen.add(key)
        kept = int(np.count_nonzero(res.row_scale()))
        files = sorted({setup.sample_rows[int(i)][0] for i in np.unique(res.samples)})
        out.append(PostureCount(res.name, files, res.n_terms, len(seen), repeated, len(seen) * kept))
    return out


def repeated_posture_notes(counts: list[PostureCount]) -> list[str]:
    """A note per block with repeated postures: how many rows, which ones."""
    notes = []
    for c in counts:
        if not c.repeated_rows:
            continue
        rows = ", ".join(str(r) for r in c.repeated_rows[:LISTED_ROWS])
        more = len(c.repeated_rows) - LISTED_ROWS
        notes.append(f"{', '.join(c.files)}: block '{c.block}' has {plural(c.n_terms, 'row')} at "
                     f"{plural(c.n_distinct, 'distinct posture')}: {plural(len(c.repeated_rows), 'row')} repeat "
                     f"an earlier posture (rows {rows}" + (f" and {more} more" if more > 0 else "") + "); a "
                     "repeated posture averages noise but counts once toward what the data can determine")
    return notes


def check_distinct_postures(setup, counts: list[PostureCount]) -> None:
    """Refuse a fit whose distinct postures give fewer measurement rows than it has free parameters (a
    parameter with a prior brings its own row)."""
    params = setup.problem.params
    free = params.free_names
    with_prior = sum(1 for n in free if params[n].prior_sigma is not None)
    rows = sum(c.distinct_rows for c in counts) + with_prior
    if rows >= len(free):
        return
    terms, distinct = sum(c.n_terms for c in counts), sum(c.n_distinct for c in counts)
    repeats = terms - distinct
    files = sorted({f for c in counts for f in c.files})
    said = (f"{plural(terms, 'row')} hold {plural(distinct, 'distinct posture')} ({repeats} repeat an earlier "
            "posture)" if repeats else plural(distinct, "distinct posture"))
    priors = f" and {with_prior} prior rows" if with_prior else ""
    raise InputError(f"{said}, whose {rows - with_prior} measurement rows{priors} cannot determine {len(free)} free "
                     "parameters; record more distinct postures, or fix parameters (parameters.fix)",
                     source=", ".join(files) or setup.source)
