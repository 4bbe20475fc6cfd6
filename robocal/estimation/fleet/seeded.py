"""Monte-Carlo repetitions on the fleet engine: one seed per repetition, so serial and Dask runs agree.

Repetition k draws from its own Generator, seeded by the k-th child of numpy's SeedSequence(seed)
(SeedSequence.spawn): independent streams that depend on (seed, k) only, never on which worker ran
which repetition or in what order. Studies that use it: docs/fleet.md, "Monte-Carlo studies on the cluster".
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from robocal.errors import InputError
from robocal.estimation.fleet.engine import map_tasks


def repetition_seeds(seed, n: int) -> list[np.random.SeedSequence]:
    """The n child seeds of SeedSequence(seed), repetition k's being the k-th."""
    if int(n) != n or n < 0:
        raise InputError(f"the number of repetitions must be a non-negative integer, got {n}", field="n")
    return np.random.SeedSequence(seed).spawn(int(n))


@dataclass
class SeededTrial:
    """trial(Generator) as a function of a repetition's SeedSequence (picklable when trial is)."""
    trial: Callable

    def __call__(self, seed_sequence: np.random.SeedSequence):
        return self.trial(np.random.default_rng(seed_sequence))


def monte_carlo(trial: Callable, n: int, seed=0, scheduler: str | None = None, workers: int | None = None) -> list:
    """[trial(rng_0), ..., trial(rng_{n-1})], rng_k = default_rng(SeedSequence(seed).spawn(n)[k]).

    In this process by default; on a LocalCluster of `workers` processes or on the Dask scheduler at
    `scheduler` otherwise (the optional [fleet] extra), with the same results in the same order, as long
    as `trial` draws only from the Generator it is given. `trial` and what it returns must pickle for Dask.
    """
    return map_tasks(SeededTrial(trial), repetition_seeds(seed, n), scheduler, workers)
