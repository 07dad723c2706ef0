"""``glider-cosim report``: run every figure's scenario, the analysis and the accuracy
checks, and write ``report.md`` with PNG figures, a metrics table and a section that
states where our results agree with the paper and where they do not.

Every number in the report is computed when it runs, from the code in this repository.
This module is the command: it checks the options, runs every part under one progress
bar, draws each figure's spec to its PNG and ``report.html``, and writes ``report.md``
and ``report.json`` with the record of how the report was made. The parts: the paper's
figures (:mod:`~glider_cosim.studies.figures`: their runs;
:mod:`~glider_cosim.studies.report_plots`: their specs;
:mod:`~glider_cosim.studies.report_text`: their tables, the analysis and the agreement
with the paper, in markdown), and the studies, each with its runs, figure and section:
:mod:`~glider_cosim.studies.sec52`, :mod:`~glider_cosim.studies.kc_map`,
:mod:`~glider_cosim.studies.steps`, :mod:`~glider_cosim.studies.roa`."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..figures.mpl import draw_png
from ..figures.pages import run_settings, write_report_page
from ..progress import Progress, dask_start, home
from ..runner.run import RunResult, simulate
from ..scenarios.overrides import apply_overrides
from ..scenarios.scenario import load_scenario
from .figures import FIGURES, Run
from .kc_map import kc_map
from .report_plots import figure_spec, sec53_spec
from .report_text import provenance_markdown, report_markdown
from .sec52 import held_tail_study, run_sec52, sec52_markdown, sec52_spec
from .steps import step_study, steps_markdown, steps_spec


def report_settings(results: dict[str, list[tuple[Run, RunResult]]]) -> dict[str, Any]:
    """What report.html records: each figure run's settings, as its metrics.json would."""
    return {f"{key}: {run.label}": run_settings(r.metrics) for key, runs in results.items()
            for run, r in runs}  # fmt: skip


def report_provenance(
    runs: list[RunResult],
    options: dict[str, Any],
    roa_grid: tuple[int, int] | None,
    maps: list[Any],
    command: str | None = None,
) -> dict[str, Any]:
    """How a report was made: its options (as ``glider-cosim report`` takes them), the
    region-of-attraction grid or that it was skipped, the FMUs' flavor and FMI version
    (as the runs' FMUs record them), the package and Python versions and the SHA-256 of
    every scenario run (``metrics.json``'s ``run.scenario_sha256``). ``command``: the
    command as the user typed it (the CLI's arguments as given); by default one made
    from ``options``."""
    import platform

    from ..fmus.files import package_version
    from ..runner.provenance import scenario_sha256

    def seen(key: str) -> str:
        found = {f.get(key) or "?" for r in runs
                 for f in ((r.metrics.get("run") or {}).get("fmus") or {}).values()}  # fmt: skip
        return ", ".join(sorted(found)) or "?"

    words = " ".join(k if v is True else f"{k} {v}" for k, v in options.items() if v is not False)
    if roa_grid is None:
        roa = "skipped (--roa-grid none)"
    else:
        runs_per_map = roa_grid[0] * roa_grid[1]
        roa = (f"{roa_grid[0]} glide angles x {roa_grid[1]} speeds, {len(maps)} map(s) of "
               f"{runs_per_map} runs")  # fmt: skip
    scenarios = {"default": scenario_sha256(load_scenario(None))}  # the step study, K_c map
    scenarios.update({m.case.scenario: scenario_sha256(load_scenario(m.case.scenario))
                      for m in maps})  # fmt: skip
    for r in runs:
        rec = r.metrics.get("run") or {}
        if rec.get("scenario") and rec.get("scenario_sha256"):
            scenarios.setdefault(rec["scenario"], rec["scenario_sha256"])
    return {
        "command": command or f"glider-cosim report {words}".strip(),
        "region of attraction": roa,
        "flavor": seen("flavor"),
        "FMI version": seen("fmi_version"),
        "package version": f"glider-cosim {package_version()}",
        "Python": platform.python_version(),
        "scenarios": dict(sorted(scenarios.items())),
    }


def build_report(
    out: str | Path = "out/report",
    fmu_dir: str | Path | None = None,
    analysis: Callable[[], dict[str, Any]] | None = None,
    progress: bool = True,
    roa_grid: tuple[int, int] | None = (7, 5),
    workers: int = 2,
    scheduler: str | None = None,
    page: bool = True,
    written: list[Path] | None = None,
    command: str | None = None,
) -> Path:
    """Run everything and write ``report.md`` (returns its path).

    ``roa_grid``: glide angles x speeds of the region-of-attraction map, run as a Dask
    sweep on ``workers`` local processes (or the cluster at ``scheduler``); None skips it.
    ``fmu_dir``: our FMUs (default: the per-user cache), built there if missing or stale.
    ``page``: also write ``report.html``, the figures interactive (zoom, hover, legend).
    ``written``: a list that gets the paths of the documents written: ``report.md``,
    ``report.html`` (if it was written) and ``report.json``.
    ``command``: the command as the user typed it, recorded in "How this report was
    made" (the CLI gives its arguments as given, not the cache's absolute path of the
    FMUs); by default one made from these arguments.
    ``progress``: each step on stderr as it starts (:mod:`glider_cosim.progress`: a bar
    on a terminal, plain lines otherwise; nothing after ``--quiet``).
    """
    from ..fmus.folders import build_all, fmu_folder

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fmu_dir = fmu_folder(fmu_dir)
    build_all(fmu_dir, only_stale=True)
    from .roa import CASES as ROA_CASES

    # every step announced as it starts: the figures' runs, four studies, the map (the
    # Dask workers' start, each case; or its skip), each drawing and the page
    roa = 1 if roa_grid is None else 1 + len(ROA_CASES)
    drawings = len(FIGURES) + 2 + (roa_grid is not None) + page
    total = sum(len(f.runs) for f in FIGURES) + 4 + roa + drawings
    header = f"report: {total} steps into {home(out.absolute())}"
    with Progress(total, "report", header, quiet=not progress) as bar:
        return _build(out, fmu_dir, analysis, roa_grid, workers, scheduler, page, bar, written,
                      command)  # fmt: skip


def report(
    out: str | Path = "out/report",
    fmu_dir: str | Path | None = None,
    *,
    no_progress: bool = False,
    no_plots: bool = False,
    roa_grid: str = "7x5",
    workers: int = 2,
    scheduler: str | None = None,
    argv: Sequence[str] | None = None,
) -> list[Path]:
    """Check the options, then :func:`build_report`: what ``glider-cosim report`` does.

    Parameters
    ----------
    out : path
        The report's folder, checked before anything runs.
    fmu_dir : path, optional
        Our FMUs (default: the per-user cache).
    no_progress : bool
        No step on stderr.
    no_plots : bool
        Skip ``report.html`` (the PNGs stay: ``report.md`` shows them).
    roa_grid : str
        ``"NxM"``: the region-of-attraction map's N glide angles x M speeds; ``"none"``
        skips the map.
    workers : int
        Local Dask workers for the map (>= 1).
    scheduler : str, optional
        Address of an existing Dask scheduler.
    argv : sequence of str, optional
        The command line as given, recorded in "How this report was made".

    Returns
    -------
    list of Path
        ``report.md`` first, then the other documents written (``report.html`` if it
        was, ``report.json``).
    """
    from ..inputs.outputs import check_out_dir
    from ..inputs.text import command_line
    from .analysis import analyze
    from .roa import parse_grid

    check_out_dir(Path(out), "--out")
    grid = None if roa_grid.lower() == "none" else parse_grid(roa_grid)
    if workers < 1:
        raise ValueError(f"--workers {workers}: expected a number >= 1")
    written: list[Path] = []
    command = None if argv is None else command_line(argv)
    path = build_report(out, fmu_dir, analysis=analyze, progress=not no_progress, roa_grid=grid,
                        workers=workers, scheduler=scheduler, page=not no_plots,
                        written=written, command=command)  # fmt: skip
    return [path, *(f for f in written if f != path)]


def _build(
    out: Path,
    fmu_dir: Path,
    analysis: Callable[[], dict[str, Any]] | None,
    roa_grid: tuple[int, int] | None,
    workers: int,
    scheduler: str | None,
    page: bool,
    bar: Progress,
    written: list[Path] | None,
    command: str | None = None,
) -> Path:
    """:func:`build_report`'s work, each step announced on ``bar``."""
    results: dict[str, list[tuple[Run, RunResult]]] = {}
    for fig in FIGURES:
        results[fig.key] = []
        for run in fig.runs:
            bar.step(f"report: running {fig.key}: {run.label}")
            sc = apply_overrides(load_scenario(run.scenario), run.overrides)
            r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
            results[fig.key].append((run, r))
    bar.step("report: the analysis (equilibrium, eigenvalues, stable K_c ranges)")
    an = analysis() if analysis is not None else None
    bar.step("report: the K_c map")
    kc_rows = kc_map(fmu_dir)
    bar.step("report: the communication step study")
    study = step_study(fmu_dir)
    # the literal Sec. 5.3 protocol (60 deg held), which the agreement section cites
    literal = simulate(load_scenario("sec53-literal"), None, fmu_dir=fmu_dir, build=False)
    bar.step("report: Sec. 5.2, the held tail")
    held = held_tail_study()
    sec52 = run_sec52(fmu_dir, held["k_star"])
    roa_lines: list[str] = []
    maps = []
    html_page = None
    if roa_grid is None:
        bar.step("report: the region-of-attraction map (skipped: --roa-grid none)")
    else:
        from ..sweeps.sweep import make_client
        from .roa import roa_markdown, roa_spec, run_roa

        bar.step(f"report: {dask_start(workers, scheduler)} for the region-of-attraction map")
        client = make_client(workers, scheduler)
        try:
            maps = run_roa(out / "roa", fmu_dir.resolve(), roa_grid, client,
                           progress=lambda what: bar.step(f"report: {what}"))  # fmt: skip
        finally:
            client.close()
            if not scheduler and client.cluster is not None:
                client.cluster.close()
    options = {"--out": out, "--fmu-dir": fmu_dir,
               "--roa-grid": "none" if roa_grid is None else f"{roa_grid[0]}x{roa_grid[1]}",
               **({} if roa_grid is None else  # the map's cluster
                  {"--scheduler": scheduler} if scheduler else {"--workers": workers}),
               "--no-plots": not page}  # fmt: skip
    every_run = [r for runs in results.values() for _, r in runs]
    every_run += [literal, *(x.result for x in sec52)]
    made = report_provenance(every_run, options, roa_grid, maps, command)
    pngs, specs = {}, []  # specs: the figures' PNGs and the page are drawn from them
    for fig in FIGURES:
        bar.step(f"report: drawing {fig.key}")
        spec = (sec53_spec if fig.key == "fig11-20" else figure_spec)(fig, results[fig.key])
        specs.append(spec)
        pngs[fig.key] = draw_png(spec, out / f"{fig.key}.png")
    bar.step("report: drawing the step study")
    specs.append(steps_spec(study))
    pngs["steps"] = draw_png(specs[-1], out / "communication_step.png")
    bar.step("report: drawing fig8")
    specs.append(sec52_spec(sec52))
    pngs["fig8"] = draw_png(specs[-1], out / "fig8.png")
    if roa_grid is not None:
        bar.step("report: drawing the region-of-attraction map")
    if maps:
        specs.append(roa_spec(maps))
        roa_lines = roa_markdown(maps, draw_png(specs[-1], out / "roa.png"), an)
    if page:
        bar.step("report: writing report.html")
        settings = {"How this report was made": made, **report_settings(results)}
        html_page = write_report_page(out, specs, settings).get("page")
    text = report_markdown(results, an, literal, pngs,
                           sec52_markdown(held, sec52, pngs["fig8"]) + roa_lines, kc_rows,
                           steps_markdown(study, pngs["steps"]))  # fmt: skip
    text += "\n" + "\n".join(provenance_markdown(made))
    (out / "report.md").write_text(text)
    summary = {
        "made": made,
        "metrics": {
            f"{k}: {run.label}": {kk: vv for kk, vv in r.metrics.items() if kk != "message"}
            for k, runs in results.items()
            for run, r in runs
        },
        "step_study": {k: v for k, v in study.items() if k != "traces"},
        "held_tail": {"u_linear_rad": held["u_linear"], "u_release_rad": held["u_release"],
                      "k_star": held["k_star"], "rows": held["rows"]},
        "kc_map": kc_rows,
        "sec52": [{"tail_deg": r.tail_deg, "K_udelta": r.k_udelta, "status": r.result.status,
                   "end_time_s": float(r.result.data[-1, 0]),
                   "est_minus_meas_rms_rad": r.est_minus_meas_rms,
                   "est_minus_true_rms_rad": r.est_minus_true_rms} for r in sec52],
        "region_of_attraction": {
            mp.case.key: {"theta_g0_rad": mp.theta_g0.tolist(), "V0_m_s": mp.V0.tolist(),
                          "outcome": mp.outcome.tolist(), "stop_time_s": mp.stop_time}
            for mp in maps},
    }  # fmt: skip
    (out / "report.json").write_text(json.dumps(summary, indent=1, default=str) + "\n")
    if written is not None:
        written += [out / "report.md", *([html_page] if html_page else []), out / "report.json"]
    return out / "report.md"
