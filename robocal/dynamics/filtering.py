"""Signal processing of an irregularly sampled joint log before identification.

Steps, each reported in `ProcessedLog.choices` so that a result says how its data were made:
1. resample onto a uniform grid at the median step: a cubic spline for positions and velocities
   (smooth signals), linear interpolation for efforts (noisy: a spline would overshoot). A zero-phase
   IIR filter needs a uniform step; the interpolation error sits far above the cut-off and is
   removed with the noise by step 3.
2. cut-off from the spectrum: the Welch spectrum of each joint's de-meaned logged velocity, the
   smallest frequency holding `power_fraction` of its power, the largest over the joints, times
   `cutoff_margin` (velocities weigh the high harmonics that accelerations need more than positions do).
3. zero-phase Butterworth low-pass (scipy.signal.butter + sosfiltfilt: no lag between the
   regressor and the torques), the same filter on positions, velocities and efforts (parallel
   filtering keeps them consistent).
4. accelerations by central differences of the filtered velocities (logged or differentiated
   positions, `velocity_source`); the two velocity sources are compared in `velocity_check`. With
   `auto` the differentiated positions are used when the logged velocities lag them by more than
   AUTO_LAG_STEPS grid steps on some joint (a logger's own filter: its lag would tilt friction and inertia
   alike), else the logged ones.
5. the filter's edge transients trimmed (`edge_periods` / cut-off seconds at both ends), then
   decimation by an integer factor keeping the new Nyquist frequency >= `nyquist_ratio` x cut-off.
See docs/dynamics_tiago.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import butter, sosfiltfilt, welch

from robocal.errors import InputError

VELOCITY_SOURCES = ("logged", "differentiated", "auto")
#: velocity_source auto: logged velocities lagging by more than this many grid steps are not used
AUTO_LAG_STEPS = 1.5
#: largest delay (s) looked for between logged and differentiated velocities
MAX_LAG_S = 0.5


@dataclass
class SignalOptions:
    """cutoff_hz: None = from the spectrum (rule in the module docstring); power_fraction,
    cutoff_margin: that rule's constants; order: Butterworth order (doubled by filtfilt);
    decimate: integer factor, None = largest keeping Nyquist >= nyquist_ratio x cut-off;
    velocity_source: 'logged' (filtered logged velocities), 'differentiated' (of filtered positions) or
    'auto' (step 4 of the module docstring);
    edge_periods: cut-off periods trimmed at each end of the log; max_rate_hz: logs sampled faster are
    first reduced to at most this rate (rate_reduction.py, kHz logs)."""

    cutoff_hz: float | None = None
    power_fraction: float = 0.999
    cutoff_margin: float = 2.0
    order: int = 4
    decimate: int | None = None
    nyquist_ratio: float = 2.0
    velocity_source: str = "logged"
    edge_periods: float = 2.0
    max_rate_hz: float = 250.0

    def __post_init__(self):
        if self.velocity_source not in VELOCITY_SOURCES:
            raise InputError(f"velocity_source must be one of {VELOCITY_SOURCES}, got '{self.velocity_source}'",
                             source="config", field="signal.velocity_source")
        if not 0 < self.power_fraction < 1:
            raise InputError("power_fraction must lie in (0, 1)", source="config", field="signal.power_fraction")
        if self.cutoff_margin < 1 or self.order < 1 or self.nyquist_ratio < 1 or self.edge_periods < 0:
            raise InputError("cutoff_margin, order and nyquist_ratio must be >= 1, edge_periods >= 0",
                             source="config", field="signal")
        if not self.max_rate_hz > 0:
            raise InputError("max_rate_hz must be > 0", source="config", field="signal.max_rate_hz")
        if self.decimate is not None and int(self.decimate) < 1:
            raise InputError("decimate must be a positive integer", source="config", field="signal.decimate")


@dataclass
class ProcessedLog:
    """Uniformly sampled, filtered log at the grid's full rate (edges trimmed): t (T,) s, q, v, a,
    effort (T, n). fs_raw: the grid's rate (Hz); cutoff_hz; decimation: the factor the
    identification applies after parallel filtering (`decimate`); order: the filter's; choices: one sentence per step;
    velocity_check: per joint RMS of (differentiated - logged) filtered velocities, the delay (s)
    of the logged velocities behind the differentiated positions maximising their correlation, and
    the RMS of the logged velocities' high-frequency part."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    effort: np.ndarray
    fs_raw: float
    cutoff_hz: float
    decimation: int
    order: int
    choices: list[str] = field(default_factory=list)
    velocity_check: dict = field(default_factory=dict)
    inner_trim: int = 0
    velocity_source: str = "logged"

    def decimated(self, x: np.ndarray) -> np.ndarray:
        """The samples the identification uses, of an array over `t` (T, ...): `inner_trim` more samples
        dropped at each end (where the second low-pass of parallel filtering has its own edge transients),
        then every `decimation`-th."""
        return x[self.inner_trim:len(x) - self.inner_trim][::self.decimation]


def parallel_filter(proc: ProcessedLog, columns: np.ndarray) -> np.ndarray:
    """The log's low-pass applied along axis 0 of `columns` (T, ...) at its full rate, then the samples of
    `proc.decimated`. The columns are computed from the filtered log, valid only inside its trimmed
    edges: this second filtering has edge transients of its own, which `proc.inner_trim` removes.
    Columns that are zero at every sample (a joint's row of a body it does not carry, another joint's friction:
    over half of a regressor) are left at zero, which is what the filter makes of them, exactly; the others are
    filtered in one call, each as it would be alone."""
    flat = columns.reshape(len(columns), -1)
    used = np.flatnonzero(np.any(flat != 0.0, axis=0))
    kept = proc.decimated(flat[:, used[:1]])                       # the samples kept (decimation is by rows)
    out = np.zeros((len(kept), flat.shape[1]))
    out[:, used] = proc.decimated(lowpass(flat[:, used], proc.fs_raw, proc.cutoff_hz, proc.order))
    return out.reshape((len(kept),) + columns.shape[1:])


def uniform_grid(t: np.ndarray) -> tuple[np.ndarray, float]:
    """Grid from t[0] at the median step (s), and that step."""
    dt = float(np.median(np.diff(t)))
    return t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1), dt


def spectral_cutoff(signal: np.ndarray, fs: float, power_fraction: float, margin: float) -> tuple[float, np.ndarray]:
    """(cut-off Hz, per-column frequency holding `power_fraction` of the de-meaned power)."""
    x = signal - signal.mean(axis=0)
    freq, psd = welch(x, fs=fs, nperseg=min(len(x), 2048), axis=0)
    cumulative = np.cumsum(psd, axis=0)
    total = cumulative[-1]
    if np.any(total <= 0):
        raise InputError("a column has no variation: its spectrum is empty", field="velocity")
    per_column = np.array([freq[np.searchsorted(cumulative[:, j] / total[j], power_fraction)]
                           for j in range(x.shape[1])])
    return float(min(margin * per_column.max(), 0.45 * fs)), per_column


def lowpass(signal: np.ndarray, fs: float, cutoff_hz: float, order: int) -> np.ndarray:
    """Zero-phase Butterworth low-pass along axis 0."""
    sos = butter(order, cutoff_hz, btype="low", fs=fs, output="sos")
    return sosfiltfilt(sos, signal, axis=0)


def best_lag(reference: np.ndarray, other: np.ndarray, max_lag: int) -> int:
    """Shift k (samples, |k| <= max_lag) maximising sum reference[i] other[i + k]: k > 0 means
    `other` lags behind `reference`."""
    n = len(reference)
    scores = [float(np.dot(reference[max(0, -k): n - max(0, k)], other[max(0, k): n - max(0, -k)]))
              for k in range(-max_lag, max_lag + 1)]
    return int(np.argmax(scores)) - max_lag


def process_log(t: np.ndarray, q: np.ndarray, v: np.ndarray | None, effort: np.ndarray,
                options: SignalOptions | None = None, spectrum_window: tuple[float, float] | None = None
                ) -> ProcessedLog:
    """Resample, filter, differentiate, trim and decimate a log (t (T,) s; q, v, effort (T, n); v None for a
    log without velocities, e.g. motor encoders: the differentiated positions stand for them throughout, whatever
    velocity_source says).
    spectrum_window: the time window, or list of windows, whose spectrum chooses the cut-off (the training
    windows: a choice made on the data the fit sees; default the whole log)."""
    opt = options or SignalOptions()
    grid, dt = uniform_grid(t)
    fs = 1.0 / dt
    qg = CubicSpline(t, q, axis=0)(grid)
    vg = np.gradient(qg, dt, axis=0) if v is None else CubicSpline(t, v, axis=0)(grid)
    eg = np.column_stack([np.interp(grid, t, effort[:, j]) for j in range(effort.shape[1])])
    if opt.cutoff_hz is None:
        windows = None if spectrum_window is None else (
            [spectrum_window] if np.isscalar(spectrum_window[0]) else list(spectrum_window))
        inside = np.ones(len(grid), bool) if windows is None else np.any(
            [(grid >= w[0]) & (grid < w[1]) for w in windows], axis=0)
        fc, per_joint = spectral_cutoff(vg[inside], fs, opt.power_fraction, opt.cutoff_margin)
        where = "the log" if windows is None else (f"the window {list(windows[0])} s" if len(windows) == 1 else
                                                   "the windows " + ", ".join(str(list(w)) for w in windows) + " s")
        signal = "logged-velocity" if v is not None else "differentiated-position"
        rule = (f"cut-off {fc:.3g} Hz = {opt.cutoff_margin:g} x the largest frequency holding "
                f"{100 * opt.power_fraction:g} % of a joint's {signal} power over {where} (per joint: "
                + ", ".join(f"{f:.3g}" for f in per_joint) + " Hz; Welch spectrum)")
    else:
        fc = float(opt.cutoff_hz)
        rule = f"cut-off {fc:.3g} Hz (configured)"
    if not 0 < fc < 0.5 * fs:
        raise InputError(f"cut-off {fc} Hz must lie in (0, {0.5 * fs:g}) Hz", source="config", field="signal.cutoff_hz")
    qf, vf, ef = (lowpass(x, fs, fc, opt.order) for x in (qg, vg, eg))
    v_num = np.gradient(qf, dt, axis=0)
    trim = int(np.ceil(opt.edge_periods / fc / dt))
    if len(grid) <= 4 * trim + 3:
        raise InputError(f"log of {t[-1] - t[0]:.3g} s is too short for a {fc:.3g} Hz filter", field="t")
    keep = slice(trim, len(grid) - trim)
    check = {} if v is None else _velocity_check(v_num[keep], vf[keep], vg[keep], dt)
    source = opt.velocity_source
    if v is None:
        source, why = "differentiated", " (the log has no velocities)"
    elif source == "auto":
        lag = max(abs(x) for x in check["lag_of_logged_s"])
        source = "differentiated" if lag > AUTO_LAG_STEPS * dt else "logged"
        why = (f" (auto: the logged velocities lag the differentiated positions by up to {lag:.3g} s, "
               f"{'more' if source == 'differentiated' else 'not more'} than {AUTO_LAG_STEPS:g} grid steps)")
    else:
        why = ""
    v_use = vf if source == "logged" else v_num
    a = np.gradient(v_use, dt, axis=0)
    k = int(opt.decimate) if opt.decimate is not None else max(1, int(np.floor(fs / (2 * opt.nyquist_ratio * fc))))
    choices = [
        f"resampled {len(t)} samples (steps {np.diff(t).min() * 1e3:.3g} to {np.diff(t).max() * 1e3:.3g} ms) "
        f"onto a uniform {dt * 1e3:.4g} ms grid: cubic spline for positions and velocities, linear for efforts",
        rule,
        f"zero-phase Butterworth low-pass, order {opt.order} (x2 by sosfiltfilt), on positions, velocities and efforts",
        f"velocities: {source}{why}; accelerations: central differences of those velocities",
        f"{trim} samples ({trim * dt:.3g} s, {opt.edge_periods:g} cut-off periods) trimmed at each end",
        "parallel filtering: the regressor columns, computed at every grid sample, get the same low-pass "
        "as the torques before decimation (a Coulomb step is then smoothed alike on both sides); that second "
        f"low-pass has edge transients of its own: {trim} more samples trimmed at each end",
        f"decimated by {k} to {fs / k:.4g} Hz (Nyquist {fs / k / 2:.3g} Hz >= {opt.nyquist_ratio:g} x cut-off)"
        if opt.decimate is None else f"decimated by {k} (configured) to {fs / k:.4g} Hz",
    ]
    return ProcessedLog(grid[keep], qf[keep], v_use[keep], a[keep], ef[keep], fs, fc, k, opt.order, choices, check,
                        trim, source)


def _velocity_check(v_num: np.ndarray, v_filtered: np.ndarray, v_raw: np.ndarray, dt: float) -> dict:
    max_lag = int(round(MAX_LAG_S / dt))
    lags = [best_lag(v_num[:, j], v_filtered[:, j], max_lag) * dt for j in range(v_num.shape[1])]
    return {
        "rms_differentiated_minus_logged": np.sqrt(np.mean((v_num - v_filtered) ** 2, axis=0)).tolist(),
        "lag_of_logged_s": lags,
        "rms_logged_noise": np.sqrt(np.mean((v_raw - v_filtered) ** 2, axis=0)).tolist(),
        "rms_velocity": np.sqrt(np.mean(v_filtered ** 2, axis=0)).tolist(),
    }
