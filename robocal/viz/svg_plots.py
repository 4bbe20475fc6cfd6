"""The report's plots as inline SVG, written directly (no matplotlib).

matplotlib costs 0.3 s to import and 0.2-0.4 s per figure (text layout), 1.4 s of a 2 s report; these four
plots are lines, dots, bars and text, which SVG draws as they are, sharp at any zoom. Each function takes
the same arrays as its PNG twin in robocal.viz.plots (which keeps matplotlib for PNG files) and returns one
`<svg>` element. Dots are zero-length path segments with round caps (one element per series, however many
samples); text widths are estimated (0.6 em a character) to size the margins.
"""
from __future__ import annotations

import html

import numpy as np

from robocal.errors import InputError

BEFORE, AFTER, RED, GREEN, GREY = "#ff8c00", "#1f77b4", "#d62728", "#2ca02c", "#7f7f7f"
FONT = 12


def text_width(s: str, size: float = FONT) -> float:
    return 0.6 * size * len(s)


def num(v: float) -> str:
    return f"{v:.2f}".rstrip("0").rstrip(".")


def label(v: float) -> str:
    """A tick label: 3 significant digits, no exponent for ordinary sizes."""
    return "0" if v == 0 else f"{v:.3g}" if 1e-3 <= abs(v) < 1e5 else f"{v:.0e}".replace("e+0", "e").replace("e-0", "e-")


def linear_ticks(lo: float, hi: float, n: int = 6) -> np.ndarray:
    """Round ticks (1, 2, 5 x 10^k apart) inside [lo, hi]."""
    if not hi > lo:
        return np.array([lo])
    raw = (hi - lo) / max(n - 1, 1)
    e = 10.0 ** np.floor(np.log10(raw))
    step = next(m * e for m in (1, 2, 5, 10) if m * e >= raw)
    ticks = np.arange(np.ceil(lo / step) * step, hi + 1e-9 * step, step)
    return np.where(np.abs(ticks) < 1e-9 * step, 0.0, ticks)


def log_ticks(lo: float, hi: float) -> np.ndarray:
    """Decades inside [lo, hi] (every k-th of many); 1, 2, 5 per decade when it spans less than two."""
    a, b = int(np.floor(np.log10(lo))), int(np.ceil(np.log10(hi)))
    if b - a <= 2:
        t = np.array([m * 10.0 ** k for k in range(a, b + 1) for m in (1, 2, 5)])
    else:
        t = 10.0 ** np.arange(a, b + 1, max(1, (b - a) // 6))
    return t[(t >= lo * (1 - 1e-9)) & (t <= hi * (1 + 1e-9))]


class Panel:
    """One plot area at (x, y, w, h) in pixels, mapping data to pixels; collects its SVG elements."""

    def __init__(self, x: float, y: float, w: float, h: float, xlim, ylim, ylog: bool = False):
        self.x, self.y, self.w, self.h, self.ylog = x, y, w, h, ylog
        self.xlim = np.array(xlim, float)
        self.ylim = np.log10(np.array(ylim, float)) if ylog else np.array(ylim, float)
        self.parts: list[str] = []

    def px(self, v) -> np.ndarray:
        return self.x + (np.asarray(v, float) - self.xlim[0]) / np.ptp(self.xlim) * self.w

    def py(self, v) -> np.ndarray:
        v = np.log10(np.asarray(v, float)) if self.ylog else np.asarray(v, float)
        return self.y + self.h - (v - self.ylim[0]) / np.ptp(self.ylim) * self.h

    def line(self, x, y, colour: str, width: float = 1.0, dash: str = "") -> None:
        pts = " ".join(f"{num(a)},{num(b)}" for a, b in zip(self.px(x), self.py(y)))
        self.parts.append(f'<polyline points="{pts}" fill="none" stroke="{colour}" stroke-width="{width}"'
                          + (f' stroke-dasharray="{dash}"' if dash else "") + "/>")

    def dots(self, x, y, colour: str, size: float = 5.0) -> None:
        d = "".join(f"M{num(a)} {num(b)}h0" for a, b in zip(self.px(x), self.py(y)))
        if d:
            self.parts.append(f'<path d="{d}" stroke="{colour}" stroke-width="{size}" stroke-linecap="round"/>')

    def crosses(self, x, y, colour: str, size: float = 4.0) -> None:
        r = size / 2
        d = "".join(f"M{num(a - r)} {num(b - r)}l{size} {size}m0 {-size}l{-size} {size}"
                    for a, b in zip(self.px(x), self.py(y)))
        if d:
            self.parts.append(f'<path d="{d}" stroke="{colour}" stroke-width="1.2" fill="none"/>')

    def rects(self, x0, x1, y0, y1, colour: str, opacity: float = 0.85) -> None:
        """Rectangles between data coordinates (bars, histogram bins)."""
        a, b = self.px(x0), self.px(x1)
        c, d = self.py(y0), self.py(y1)
        d_ = "".join(f"M{num(min(p, q))} {num(min(r, s))}h{num(abs(q - p))}v{num(abs(s - r))}h{num(-abs(q - p))}z"
                     for p, q, r, s in np.broadcast(a, b, c, d))
        if d_:
            self.parts.append(f'<path d="{d_}" fill="{colour}" fill-opacity="{opacity}"/>')

    def vline(self, x: float, colour: str = "black", width: float = 1.0, dash: str = "") -> None:
        p = num(float(self.px(x)))
        self.parts.append(f'<line x1="{p}" x2="{p}" y1="{num(self.y)}" y2="{num(self.y + self.h)}" stroke="{colour}" '
                          f'stroke-width="{width}"' + (f' stroke-dasharray="{dash}"' if dash else "") + "/>")

    def axes(self, xlabel: str = "", ylabel: str = "", title: str = "", grid: str = "xy", size: float = FONT,
             xticks=None, yticks=None, ylabels=None, xlabels=None) -> None:
        """Frame, ticks with labels, grid lines, axis labels and the title."""
        out = []
        xt = linear_ticks(*self.xlim) if xticks is None else np.asarray(xticks, float)
        for k, t in enumerate(xt):
            p = num(float(self.px(t)))
            if "x" in grid:
                out.append(f'<line x1="{p}" x2="{p}" y1="{num(self.y)}" y2="{num(self.y + self.h)}" stroke="#ddd"/>')
            out.append(f'<text x="{p}" y="{num(self.y + self.h + size + 2)}" text-anchor="middle" '
                       f'font-size="{size - 1}">{html.escape(label(t) if xlabels is None else xlabels[k])}</text>')
        lim = 10.0 ** self.ylim if self.ylog else self.ylim
        yt = (log_ticks(*lim) if self.ylog else linear_ticks(*lim)) if yticks is None else np.asarray(yticks, float)
        for k, t in enumerate(yt):
            p = num(float(self.py(t)))
            if "y" in grid:
                out.append(f'<line x1="{num(self.x)}" x2="{num(self.x + self.w)}" y1="{p}" y2="{p}" stroke="#ddd"/>')
            text = label(t) if ylabels is None else ylabels[k]
            out.append(f'<text x="{num(self.x - 4)}" y="{p}" dy="0.35em" text-anchor="end" '
                       f'font-size="{size - 1}">{html.escape(text)}</text>')
        out.append(f'<rect x="{num(self.x)}" y="{num(self.y)}" width="{num(self.w)}" height="{num(self.h)}" '
                   'fill="none" stroke="#333"/>')
        if xlabel:
            out.append(f'<text x="{num(self.x + self.w / 2)}" y="{num(self.y + self.h + 2 * size + 6)}" '
                       f'text-anchor="middle" font-size="{size}">{html.escape(xlabel)}</text>')
        if ylabel:
            cx, cy = self.x - 50, self.y + self.h / 2
            out.append(f'<text transform="translate({num(cx)},{num(cy)}) rotate(-90)" text-anchor="middle" '
                       f'font-size="{size}">{html.escape(ylabel)}</text>')
        if title:
            out.append(f'<text x="{num(self.x + self.w / 2)}" y="{num(self.y - 6)}" text-anchor="middle" '
                       f'font-size="{size + 1}">{html.escape(title)}</text>')
        self.parts = out + self.parts

    def legend(self, entries: list[tuple[str, str, str]], size: float = FONT - 1) -> None:
        """Entries (label, colour, kind: "dot" | "cross" | "dash" | "dash:PATTERN" | "line") in a box at the top
        right."""
        width = max(text_width(t, size) for t, _, _ in entries) + 34
        x0, y0 = self.x + self.w - width - 6, self.y + 6
        out = [f'<rect x="{num(x0)}" y="{num(y0)}" width="{num(width)}" height="{num(len(entries) * (size + 6) + 6)}" '
               'fill="white" fill-opacity="0.85" stroke="#ccc"/>']
        for k, (text, colour, kind) in enumerate(entries):
            y = y0 + 6 + (k + 0.5) * (size + 6)
            if kind == "dot":
                out.append(f'<path d="M{num(x0 + 8)} {num(y)}h14" stroke="{colour}"/><path d="M{num(x0 + 15)} {num(y)}h0"'
                           f' stroke="{colour}" stroke-width="5" stroke-linecap="round"/>')
            elif kind == "cross":
                out.append(f'<path d="M{num(x0 + 12)} {num(y - 3)}l6 6m0 -6l-6 6" stroke="{colour}" stroke-width="1.2"/>')
            else:           # "dash", "dash:PATTERN" (an SVG dash array), "line" (solid)
                dash = "" if kind == "line" else f' stroke-dasharray="{kind.partition(":")[2] or "4 2"}"'
                out.append(f'<path d="M{num(x0 + 8)} {num(y)}h14" stroke="{colour}"{dash}/>')
            out.append(f'<text x="{num(x0 + 28)}" y="{num(y)}" dy="0.35em" font-size="{size}">{html.escape(text)}</text>')
        self.parts += out


def svg(width: float, height: float, parts: list[str], title: str = "") -> str:
    head = f'<text x="{num(width / 2)}" y="{FONT + 4}" text-anchor="middle" font-size="{FONT + 2}">{html.escape(title)}</text>'
    return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {num(width)} {num(height)}" width="{num(width)}" '
            f'height="{num(height)}" font-family="sans-serif" role="img">' + (head if title else "") + "".join(parts)
            + "</svg>")


def positive_range(*arrays) -> tuple[float, float]:
    """A log axis' limits: the positive values' range, widened by 20 % each way (a flat series: a decade)."""
    v = np.concatenate([np.asarray(a, float).ravel() for a in arrays])
    v = v[np.isfinite(v) & (v > 0)]
    if not len(v):
        return 0.1, 10.0
    lo, hi = v.min(), v.max()
    return (lo / 1.2, hi * 1.2) if hi > lo * 1.01 else (lo / 3.0, hi * 3.0)


def padded(lo: float, hi: float, fraction: float = 0.05) -> tuple[float, float]:
    if not hi > lo:
        return lo - 0.5, hi + 0.5
    pad = fraction * (hi - lo)
    return lo - pad, hi + pad


def residuals_per_sample(before, after, unit: str = "mm", title: str = "Residual per sample") -> str:
    """Residual size of each sample before and after calibration (already in `unit`), log scale."""
    before, after = np.asarray(before, float).ravel(), np.asarray(after, float).ravel()
    if len(before) != len(after):
        raise InputError(f"arrays must have the same length: before {len(before)}, after {len(after)}",
                         field="before, after")
    b, a = np.maximum(before, 1e-12), np.maximum(after, 1e-12)
    x = np.arange(1, len(b) + 1)
    p = Panel(72, 30, 610, 270, padded(1, max(len(b), 2)), positive_range(b, a), ylog=True)
    for series, colour in ((b, BEFORE), (a, AFTER)):
        p.line(x, series, colour, 0.8)
        p.dots(x, series, colour, 4.5)
    p.axes("sample", f"|residual| [{unit}]", title)
    p.legend([("before", BEFORE, "dot"), ("after", AFTER, "dot")])
    return svg(700, 350, p.parts)


def error_histograms(before, after, axes=("x", "y", "z"), unit: str = "mm", title: str = "Error per axis",
                     labels=("before", "after")) -> str:
    """Histograms of (n, k) per-axis errors (in `unit`), before and after, one panel per axis; each row its
    own bins (before and after differ by orders of magnitude after a good fit)."""
    before, after = np.atleast_2d(np.asarray(before, float)), np.atleast_2d(np.asarray(after, float))
    if before.shape[1] != len(axes) or after.shape[1] != len(axes):
        raise InputError(f"errors need {len(axes)} columns ({', '.join(axes)}); got {before.shape[1]} and "
                         f"{after.shape[1]}", field="before/after")
    cell_w, cell_h = 250, 190
    parts = []
    for row, (data, colour, name) in enumerate(((before, BEFORE, labels[0]), (after, AFTER, labels[1]))):
        for j, ax in enumerate(axes):
            col = data[:, j]
            counts, edges = np.histogram(col, bins=min(30, max(5, len(col) // 3)))
            p = Panel(45 + j * cell_w, 50 + row * cell_h, cell_w - 65, cell_h - 75, padded(edges[0], edges[-1], 0.02),
                      (0, max(counts.max(), 1) * 1.08))
            p.rects(edges[:-1], edges[1:], 0, counts, colour)
            rms = np.sqrt(np.mean(col ** 2)) if len(col) else np.nan
            p.axes(f"{ax} error [{unit}]", "", f"{ax} {name}: rms {rms:.3g} {unit}", grid="y", size=10,
                   xticks=linear_ticks(edges[0], edges[-1], 5))
            parts += p.parts
    return svg(len(axes) * cell_w, 2 * cell_h + 20, parts, title)


def parameter_estimates(names, values, stderr, units=None, title: str = "Parameter estimates") -> str:
    """Estimates with +-1 standard-error bars, shown in mm (m) and mrad (rad), one row per parameter."""
    values = np.asarray(values, float)
    stderr = np.asarray([np.nan if s is None else s for s in stderr], float)
    if not len(names) == len(values) == len(stderr):
        raise InputError(f"arrays must have the same length: names {len(names)}, values {len(values)}, "
                         f"stderr {len(stderr)}", field="names, values, stderr")
    units = list(units) if units is not None else ["m"] * len(values)
    shown = {"m": "mm", "rad": "mrad"}
    scale = np.array([1e3 if u in ("m", "rad") else 1.0 for u in units])
    v, s = values * scale, stderr * scale
    ok = np.isfinite(s)
    lo = min(0.0, np.min(v - np.where(ok, s, 0)) if len(v) else 0.0)
    hi = max(0.0, np.max(v + np.where(ok, s, 0)) if len(v) else 1.0)
    texts = [f"{n} [{shown.get(u, u)}]" for n, u in zip(names, units)]
    left = 12 + max([text_width(t, 10) for t in texts] + [40])
    row = 16
    height = max(150, row * len(v) + 90)
    y = np.arange(len(v))[::-1]
    p = Panel(left, 30, 690 - left, height - 80, padded(lo, hi), (-0.7, len(v) - 0.3))
    colours = [AFTER if u == "m" else GREEN if u == "rad" else GREY for u in units]
    for c in dict.fromkeys(colours):
        k = np.array([cc == c for cc in colours])
        p.rects(np.zeros(k.sum()), v[k], y[k] - 0.35, y[k] + 0.35, c, 0.5)
    bars = "".join(f"M{num(a)} {num(b)}H{num(c)}M{num(a)} {num(b - 3)}v6M{num(c)} {num(b - 3)}v6"
                   for a, b, c in zip(p.px((v - s)[ok]), p.py(y[ok]), p.px((v + s)[ok])))
    if bars:
        p.parts.append(f'<path d="{bars}" stroke="black" stroke-width="0.8" fill="none"/>')
    p.vline(0.0, "black", 0.6)
    p.axes("estimate (mm for lengths, mrad for angles), bars: +-1 standard error", "", title, grid="x", size=11,
           yticks=y, ylabels=texts)
    return svg(700, height, p.parts)


def singular_values(s, rank: int, title: str = "Identification Jacobian (column-scaled)") -> str:
    """Singular values (largest first, log scale) with the rank the base-parameter selection kept."""
    s = np.sort(np.asarray(s, float).ravel())[::-1]
    if not 0 <= rank <= len(s):
        raise InputError(f"rank {rank} is outside 0..{len(s)}", field="rank")
    floor = max(s.max() * 1e-18, 1e-300) if len(s) else 1.0
    v = np.maximum(s, floor)
    x = np.arange(1, len(s) + 1)
    p = Panel(72, 30, 610, 270, padded(1, max(len(s), 2)), positive_range(v), ylog=True)
    p.dots(x[:rank], v[:rank], AFTER, 6)
    p.crosses(x[rank:], v[rank:], RED, 6)
    p.vline(rank + 0.5, "black", 1.0, "5 3")
    p.axes("index", "singular value", title)
    p.legend([("kept (identifiable)", AFTER, "dot"), ("beyond the rank", RED, "cross"),
              (f"rank cut: {rank} of {len(s)}", "black", "dash")])
    return svg(700, 350, p.parts)
