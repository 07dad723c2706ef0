"""Interactive HTML pages of a run's or a report's figures (``plots.html``, ``report.html``).

A run's figures are its plots' specs (:mod:`.plots`), the ones its PNGs are drawn from
(by :mod:`.raster`); a report's are its figures' specs, the ones its PNGs are drawn from
(by :mod:`.mpl`). Either way what a figure shows is defined once, in its spec.
:func:`write_page` writes them into one self-contained file that BokehJS draws in the
browser (:mod:`.page_script`: bokeh's JavaScript inline from the installed package,
nothing fetched, no bokeh imported in Python); each figure zooms (box and wheel), shows
values on hover and hides a series clicked in its legend. No data are downsampled.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .page_script import PageError, page_scripts

#: the ``class`` of each figure's ``<div>`` in a page (a test counts them after load)
FIGURE_CLASS = "glider-figure"


def _legend_width(specs: Sequence[dict[str, Any]]) -> int:
    """The legend's label width, px: one for every panel of the page's one-column figures,
    so that their x axes line up (a grid's legend is under it)."""
    names = [ln["name"] for s in specs if all(p["col"] == 0 for p in s["panels"])
             for p in s["panels"] for ln in p["lines"] if ln["legend"]]  # fmt: skip
    return 6 * max((len(n) for n in names), default=0)


def _text(value: Any) -> str:
    """``{"plant": "python", ...}`` -> ``plant python, ...``; an empty one -> ``none``."""
    if isinstance(value, dict):
        return ", ".join(f"{k} {_text(v)}" for k, v in value.items()) or "none"
    return str(value)


def _settings_html(settings: dict[str, Any]) -> str:
    """A table; for many runs (a report), one collapsed block per run."""
    nested = all(isinstance(v, dict) for v in settings.values())
    if nested:
        blocks = [  # a block without a status (how a report was made) starts open
            f"<details{'' if 'status' in v else ' open'}><summary>{html.escape(str(k))}"
            f"{': ' + html.escape(_text(v['status'])) if 'status' in v else ''}"
            f"</summary>{_settings_html(v)}</details>"
            for k, v in settings.items()
        ]
        return "<h2>Runs and their settings</h2>" + "".join(blocks)
    rows = [f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(_text(v))}</td></tr>"
            for k, v in settings.items()]  # fmt: skip
    return "<table class='settings'>" + "".join(rows) + "</table>"


_CSS = """body{font-family:sans-serif;margin:1em 2em;color:#222}
h2{font-size:1.1em;margin:1.6em 0 .2em;white-space:pre-line}
p.notes{color:#555;font-size:.85em;margin:.2em 0}
span.key{display:inline-block;width:1.6em;height:.9em;margin-right:.3em;vertical-align:middle}
table.settings{border-collapse:collapse;font-size:.85em}
table.settings th{text-align:left;padding:2px 12px 2px 0;vertical-align:top}
table.settings td{font-family:monospace;word-break:break-all}
details{font-size:.85em;margin:.1em 0}summary{cursor:pointer}
p.help{color:#555;font-size:.85em}
h3.glider-row{font-size:1em;margin:.9em 0 .1em;padding-bottom:.1em;border-bottom:1px solid #ccc}
div.glider-legend{display:flex;flex-wrap:wrap;gap:.2em 1.2em;font-size:.85em;margin:.4em 0 0}
button.glider-key{background:none;border:0;padding:0;font:inherit;color:inherit;cursor:pointer;
display:inline-flex;align-items:center;gap:.3em}
button.glider-key.off{opacity:.35;text-decoration:line-through}"""


def write_page(
    path: str | Path,
    title: str,
    figures: Sequence[dict[str, Any]],
    settings: dict[str, Any],
) -> Path:
    """Write one self-contained HTML page of ``figures`` (specs: :mod:`.spec`).

    Parameters
    ----------
    path : str or Path
        The ``.html`` file written (replaced whole: written beside it, then renamed).
    title : str
        The page's heading.
    figures : sequence of dict
        One spec per figure, drawn in this order.
    settings : dict
        What the page records about the run(s): shown as a table and kept as JSON in
        the ``<script type="application/json" id="run-settings">`` element.
    """
    if not figures:
        raise PageError(f"{path}: no figures to write; expected at least one")
    path = Path(path)
    scripts = page_scripts(figures, _legend_width(figures))
    body = []
    for i, spec in enumerate(figures):
        body.append(f"<h2>{html.escape(spec['title'])}</h2>")
        if spec["notes"]:
            keys = [(f"<span class='key' style='background:{n['color']}'></span>" if n["color"]
                     else "") + html.escape(n["text"]) for n in spec["notes"]]  # fmt: skip
            body.append(f"<p class='notes'>{' &nbsp; '.join(keys)}</p>")
        body.append(f"<div class='{FIGURE_CLASS}'><div id='glider-figure-{i}'></div></div>")
    data = json.dumps(settings, default=str).replace("</", "<\\/")
    text = (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{_CSS}</style>"
        f"{scripts}</head><body><h1>{html.escape(title)}</h1>"
        "<p class='help'>Drag to zoom (toolbar: x-only or box zoom), wheel to zoom, "
        "double-click or reset to restore; hover a curve for its values; click a legend "
        "entry to hide or show that series (a legend under a grid: in each of its panels).</p>"
        f"{_settings_html(settings)}{''.join(body)}"
        f"<script type='application/json' id='run-settings'>{data}</script></body></html>\n"
    )
    tmp = path.with_name(path.name + ".part")
    try:
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    except OSError as err:
        tmp.unlink(missing_ok=True)
        raise PageError(f"{path}: cannot write the page ({err.strerror or err})") from None
    return path


def run_settings(metrics: dict[str, Any]) -> dict[str, Any]:
    """A run's settings as ``metrics.json`` records them: scenario, overrides, options,
    each FMU's flavor and FMI version, the package version."""
    run = metrics.get("run") or {}
    fmus = run.get("fmus") or {}
    return {
        "scenario": run.get("scenario", metrics.get("scenario", "?")),
        "scenario_source": run.get("scenario_source", ""),
        "overrides": run.get("overrides", {}),
        "options": run.get("options", {}),
        "flavor": {k: v.get("flavor") for k, v in fmus.items()},
        "fmi_version": {k: v.get("fmi_version") for k, v in fmus.items()},
        "fmu_version": {k: v.get("version") for k, v in fmus.items()},
        "package": f"{run.get('package', 'glider-cosim')} {run.get('package_version', '?')}",
        "status": metrics.get("status", ""),
    }


def write_run_page(result: Any, out: Path, specs: Sequence[dict[str, Any]]) -> dict[str, Path]:
    """``plots.html`` of a run from its plots' specs (:func:`~.plots.build_specs`), in this
    order. A page that cannot be written is a logged warning: the run's results and PNGs
    stay as written."""
    path = Path(out) / "plots.html"
    try:
        name = result.scenario.name
        return {"page": write_page(path, f"glider-cosim run: {name}", specs,
                                   run_settings(result.metrics))}  # fmt: skip
    except (PageError, OSError, ValueError, TypeError) as err:
        page_not_written(err)
        return {}


def page_not_written(err: BaseException | str) -> None:
    """The warning of a ``plots.html`` that could not be written."""
    import logging

    logging.getLogger(__name__).warning("plots.html not written (%s); the run's results "
                                        "and PNGs are kept", err)  # fmt: skip


def write_report_page(out: Path, specs: Sequence[dict[str, Any]], settings: dict[str, Any]) -> dict:
    """``report.html`` from the report's figure specs (the ones its PNGs are drawn from:
    :mod:`.mpl`), in this order; a failure is a logged warning (report.md, report.json and
    the PNGs stay as written)."""
    import logging

    path = Path(out) / "report.html"
    try:
        return {"page": write_page(path, "glider-cosim report", specs, settings)}
    except (PageError, OSError, ValueError, TypeError, ImportError) as err:
        logging.getLogger(__name__).warning("report.html not written (%s); report.md and "
                                            "its PNGs are kept", err)  # fmt: skip
        return {}
