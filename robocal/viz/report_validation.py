"""Report sections of issue-18's figures: refusals with their fixes, findings, the default prior, what the
data determine, and the score of a calibrated model on another session (`robocal evaluate`)."""
from __future__ import annotations

import html
import json

from robocal.estimation.registration import sigma_text

SCALE = {"m": (1e3, "mm"), "rad": (1e3, "mrad"), "rad/(N m)": (1e3, "mrad/(N m)"), "m/N": (1e3, "mm/N")}


def bullets(lines, cls: str) -> str:
    return f"<ul class=\"{cls}\">" + "".join(f"<li>{html.escape(str(s))}</li>" for s in lines) + "</ul>"


def refusal_section(result: dict) -> list[str]:
    """What went wrong and how to fix it (before any figure), the findings, and the default prior's decision."""
    parts = []
    refusals = result.get("refusals") or []
    if refusals:
        parts += ["<h2>Refused: what went wrong and how to fix it</h2>",
                  bullets([refusal_text(r) for r in refusals], "refusals")]
    findings = result.get("findings") or []
    if findings:
        parts += ["<h2>Findings: check these on the robot</h2>",
                  "<p>Parameters the data determine firmly, far from nominal ("
                  + html.escape(result.get("finding_rule", "")) + "); they are in the calibrated model.</p>",
                  bullets([finding_text(f) for f in findings], "findings")]
    prior = result.get("default_prior")
    if prior:
        if prior.get("applied"):
            text = (f"{len(prior['parameters_given_prior'])} robot parameters without a prior of their own got one of "
                    f"{sigma_text(prior['strength_in_physical_scales'], prior.get('strength_by_family') or {})}, "
                    f"chosen by the "
                    f"{prior['method']}; {prior['reason']}.")
        else:
            text = f"Default prior {prior.get('mode')}: {prior.get('reason') or 'not applied'}."
        parts += ["<h2>Default prior</h2>", f"<p>{html.escape(text)}</p>"]
    ident = result.get("identifiability") or {}
    if ident.get("weak_directions"):
        parts += ["<h2>Weak directions (data-only standard error against the threshold)</h2>",
                  bullets(ident["weak_directions"], "weak-directions")]
    return parts


def refusal_text(r: dict) -> str:
    names = "; ".join(r.get("parameters") or [])
    changes = " or ".join(json.dumps(c) for c in r.get("config_changes") or [])
    return f"{r['problem']}{': ' + names if names else ''}. Fix: {r['fix']}{' ' + changes if changes else ''}."


def finding_text(f: dict) -> str:
    k, u = SCALE.get(f.get("unit", ""), (1.0, f.get("unit", "")))
    return (f"{f['parameter']} = {k * f['value']:+.4g} {u} +- {k * f['stderr']:.3g} (data alone +- "
            f"{k * f['stderr_data_only']:.3g}), nominal {k * f['nominal']:+.4g}: {f['in_physical_scales']:.3g} "
            f"physical scales (scale {k * f['physical_scale']:.3g} {u}"
            + (f"; {f['scale_basis']}" if f.get("scale_basis") else "")
            + f"), {f['in_standard_errors']:.3g} standard errors from nominal. Check {f['check']}.")


def evaluation_section(evaluation: dict) -> list[str]:
    """The `robocal evaluate` figures: per block, all samples / inside / outside the training ranges."""
    rows = []
    for b in evaluation.get("blocks", []):
        for part in ("all", "inside_training_range", "outside_training_range"):
            st = b.get(part) or {}
            if st.get("n"):
                rows.append(f"<tr><td>{html.escape(b['name'])}</td><td>{part.replace('_', ' ')}</td>"
                            f"<td>{st['n']}</td><td>{st['rms_norm']:.4g} {b['unit']}</td>"
                            f"<td>{st['max_norm']:.4g} {b['unit']}</td></tr>")
    refit = ", ".join(evaluation.get("refitted") or []) or "none"
    return ["<h2>Evaluation on another session</h2>",
            f"<p>{html.escape(evaluation.get('data', ''))}: RMS and maximum of the error norm; refitted on this "
            f"session: {html.escape(refit)}.</p>",
            "<table class=\"evaluation\"><tr><th>block</th><th>samples</th><th>n</th><th>RMS |e|</th>"
            "<th>max |e|</th></tr>" + "".join(rows) + "</table>"]
