"""The HTML page of a fleet report: the same page machinery as a calibration's report.html
(robocal.viz.report), with the fleet's tables and plots (robocal.viz.fleet_plots)."""
from __future__ import annotations

import html

import numpy as np

from robocal.workflows.fleet.report import FleetReport

MAX_DRIFT_PANELS = 6


def fleet_page(rep: FleetReport, title: str = "robocal fleet report") -> str:
    import robocal.viz.fleet_plots as fleet_plots   # matplotlib: the optional [viz] extra
    from robocal.viz.report import figure_html, format_value, html_page, html_table, png_base64

    status = [[s, n] for s, n in sorted(rep.statuses.items())]
    parts = [f"<h1>{html.escape(title)}</h1>", "<h2>Summary</h2>",
             f"<p>{rep.rows} calibrations; {len(rep.converged)} converged take part in the comparison. A unit is "
             f"an outlier in a parameter beyond {rep.threshold:g} robust standard deviations (1.4826 MAD, at least "
             "the median standard error) from the fleet median; a unit drifts when a parameter moved by more than "
             f"{rep.threshold:g} combined standard errors between its first and last calibration. Values are SI "
             "(m, rad).</p>", html_table(["status", "calibrations"], status, "summary")]
    parts += ["<h2>Failures</h2>",
              html_table(["unit", "status", "message"], [[r["key"], r["status"], r.get("message") or ""]
                                                          for r in rep.failures], "failures")
              if rep.failures else "<p>None.</p>"]
    out_rows = [[o.key, n, format_value(v, "+.5g"), format_value(m, "+.5g"), format_value(z, "+.1f")]
                for o in rep.outliers for n, v, m, z in o.parameters]
    parts += ["<h2>Outliers</h2>",
              html_table(["unit", "parameter", "estimate", "fleet median", "robust z"], out_rows, "outliers")
              if out_rows else "<p>None.</p>"]
    drift_rows = [[d.unit, d.parameter, d.first_date, d.last_date, format_value(d.first, "+.5g"),
                   format_value(d.last, "+.5g"), format_value(d.z, "+.1f"), format_value(d.per_year, "+.4g")]
                  for d in rep.drifts]
    parts += ["<h2>Drift</h2>",
              html_table(["unit", "parameter", "first", "last", "first estimate", "last estimate", "change / se",
                          "change per year"], drift_rows, "drift") if drift_rows else "<p>None.</p>"]
    parts += ["<h2>Parameters across the fleet</h2>",
              html_table(["parameter", "calibrations", "median", "robust sd", "min", "max"],
                         [[s.name, s.n, format_value(s.median, "+.5g"), format_value(s.scale, ".3g"),
                           format_value(s.low, "+.5g"), format_value(s.high, "+.5g")] for s in rep.spreads],
                         "parameters")]
    if rep.robust_z:
        names = list(rep.robust_z)
        z = np.column_stack([rep.robust_z[n] for n in names])
        flagged = np.abs(np.nan_to_num(z)) > rep.threshold
        parts.append(figure_html("Each unit's estimate of every parameter, in robust standard deviations from the "
                                 "fleet median; outliers marked",
                                 png_base64(fleet_plots.parameter_spread, names, z, flagged, rep.threshold)))
    if rep.drifts:
        parts.append(figure_html("Largest drifts: estimate with +-1 standard error at each calibration",
                                 png_base64(fleet_plots.drift_histories, rep.drifts[:MAX_DRIFT_PANELS])))
    return html_page(title, parts)
