"""Report sections of issue-18's figures: refusals with their fixes, the default prior, what the data
determine, and the score of a calibrated model on another session (`robocal evaluate`)."""
from __future__ import annotations

import html


def bullets(lines, cls: str) -> str:
    return f"<ul class=\"{cls}\">" + "".join(f"<li>{html.escape(str(s))}</li>" for s in lines) + "</ul>"


def refusal_section(result: dict) -> list[str]:
    """What went wrong and how to fix it (before any figure), and the default prior's decision."""
    parts = []
    refusals = result.get("refusals") or []
    if refusals:
        parts += ["<h2>Refused: what went wrong and how to fix it</h2>",
                  bullets([f"{r['problem']}. Fix: {r['fix']}." for r in refusals], "refusals")]
    prior = result.get("default_prior")
    if prior:
        if prior.get("applied"):
            text = (f"{len(prior['parameters'])} robot parameters got a prior of sigma = "
                    f"{prior['strength_in_physical_scales']:.3g} x their physical scale, chosen by the {prior['method']}; "
                    f"{prior['reason']}.")
        else:
            text = f"Default prior {prior.get('mode')}: {prior.get('reason') or 'not applied'}."
        parts += ["<h2>Default prior</h2>", f"<p>{html.escape(text)}</p>"]
    det = result.get("determinacy")
    if det and det.get("weak_directions"):
        parts += ["<h2>Weak directions (data-only standard error against the threshold)</h2>",
                  bullets(det["weak_directions"], "weak-directions")]
    return parts


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
