"""Logs at kHz rates brought down to a working rate before identification, in blocks of bounded size.

A 5 kHz log holds ~20x more samples than its dynamics need; the identification builds its regressor at every
grid sample (parallel filtering), so it first runs at the working rate: the log is reduced by the smallest
integer factor r bringing it to at most `max_rate_hz` (signal.max_rate_hz, default 250 Hz). The anti-alias
filter is a linear-phase FIR (scipy.signal.firwin, Kaiser window beta 8.6: about -86 dB in the stop band) of
2 r K + 1 taps (K = TAPS_PER_SIDE), cut-off at 0.8 x the new Nyquist frequency, applied centred on each kept
row (zero phase) by scipy.signal.upfirdn, which computes only the kept outputs. Its pass band (flat to about
0.6 x the new Nyquist frequency) holds the identification's cut-offs; what it lets fold back lands near the
new Nyquist frequency, far above them, and the identification's low-pass removes it.

The reducer is fed blocks of rows as they are read (motor_log.py streams a CSV file) and keeps only the
filter's reach of raw rows between blocks: its memory is O(block + taps) rows of the log's columns plus the
reduced output, whatever the log's length. Each output row is a raw row of the log (every r-th, starting
where a whole filter window fits): its time stamp and its raw readings are kept with it, so a figure against
"the logged value" compares with a reading, not a filtered one. The result equals filtering the whole log at
once (tests/test_dynamics_rate_reduction.py).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import firwin, upfirdn

#: half the FIR's length in output samples (taps = 2 r K + 1)
TAPS_PER_SIDE = 16
KAISER_BETA = 8.6
#: the anti-alias cut-off as a fraction of the new Nyquist frequency
CUTOFF_FRACTION = 0.8


def reduction_factor(rate_hz: float, max_rate_hz: float) -> int:
    """The smallest integer r with rate / r <= max_rate (1 when the log is slow enough already)."""
    return max(1, int(np.ceil(rate_hz / max_rate_hz - 1e-9)))


def anti_alias_taps(factor: int) -> np.ndarray:
    return firwin(2 * factor * TAPS_PER_SIDE + 1, CUTOFF_FRACTION / factor, window=("kaiser", KAISER_BETA))


@dataclass
class RateReducer:
    """Feed blocks with push(rows (n,), values (n, c)); read t/rows/values/raw after finish(). factor 1
    passes rows through. keep_raw: the columns (indices into values) whose raw readings at the kept rows are
    kept too (`raw`)."""

    factor: int
    keep_raw: list[int] = field(default_factory=list)

    def __post_init__(self):
        self.taps = anti_alias_taps(self.factor) if self.factor > 1 else np.ones(1)
        self.reach = (len(self.taps) - 1) // 2                       # raw rows each side of a kept row
        self._buffer = None                                          # raw rows not yet past the filter's reach
        self._first = 0                                              # raw index of the buffer's first row
        self._next = self.reach                                      # raw index of the next kept row
        self._out_rows, self._out_values, self._out_raw = [], [], []

    def push(self, values: np.ndarray) -> None:
        values = np.asarray(values, float)
        self._buffer = values if self._buffer is None else np.concatenate([self._buffer, values])
        end = self._first + len(self._buffer)                         # one past the last raw index held
        last = end - 1 - self.reach                                   # the last centre whose window is held
        if last < self._next:
            return
        centres = np.arange(self._next, last + 1, self.factor)
        if self.factor == 1:
            filtered = self._buffer[centres - self._first]
        else:
            start = centres[0] - self.reach - self._first
            stop = centres[-1] + self.reach + 1 - self._first
            # upfirdn's n-th output is sum_k h[k] x[n r - k]: the window centred on start + reach + j r is its
            # output j + 2 reach / r (reach = r K, so 2 reach / r = 2K)
            out = upfirdn(self.taps, self._buffer[start:stop], 1, self.factor, axis=0)
            filtered = out[2 * TAPS_PER_SIDE:2 * TAPS_PER_SIDE + len(centres)]
        self._out_rows.append(centres)
        self._out_values.append(filtered)
        self._out_raw.append(self._buffer[centres - self._first][:, self.keep_raw])
        self._next = int(centres[-1]) + self.factor
        drop = self._next - self.reach - self._first                   # rows no later window reaches
        self._buffer = self._buffer[drop:]
        self._first += drop

    def finish(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(raw row index of each kept row (m,), filtered values (m, c), raw readings of keep_raw (m, k))."""
        if not self._out_rows:
            cols = 0 if self._buffer is None else self._buffer.shape[1]
            return np.zeros(0, int), np.zeros((0, cols)), np.zeros((0, len(self.keep_raw)))
        return (np.concatenate(self._out_rows), np.concatenate(self._out_values), np.concatenate(self._out_raw))


def describe(factor: int, rate_hz: float, rows: int, kept: int, block: int) -> str:
    """The reduction in one sentence, for the summary's signal-processing choices."""
    if factor == 1:
        return f"log rate {rate_hz:.5g} Hz: at or below signal.max_rate_hz, not reduced"
    return (f"log rate {rate_hz:.5g} Hz reduced by {factor} to {rate_hz / factor:.5g} Hz ({rows} rows -> {kept}): "
            f"zero-phase FIR anti-alias low-pass ({2 * factor * TAPS_PER_SIDE + 1} taps, Kaiser beta {KAISER_BETA:g}, "
            f"cut-off {CUTOFF_FRACTION * rate_hz / factor / 2:.4g} Hz) centred on every {factor}th row, read in blocks "
            f"of {block} rows; the filter's reach ({TAPS_PER_SIDE * factor} rows) dropped at each end")
