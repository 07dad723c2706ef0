"""One meaning for ``--out`` (issue 28, point 1): the settings a results folder was made
with, and the one-line note when a run replaces results made with other settings."""

from __future__ import annotations

import json

from glider_cosim.cli import build_parser
from glider_cosim.runner.provenance import (
    describe_settings,
    overrides_text,
    replaced_note,
    settings_of,
)


def _run(overrides=None, options=None, flavor="python", fmi="2.0", sha="a" * 64) -> dict:
    fmus = {i: {"flavor": flavor, "fmi_version": fmi} for i in ("plant", "controller")}
    return {"scenario": "default", "scenario_sha256": sha, "overrides": overrides or {},
            "options": options or {}, "fmus": fmus}  # fmt: skip


def test_settings_are_what_changes_results():
    base = settings_of(_run())
    assert settings_of(_run(options={"--no-plots": True, "--format": "parquet"})) == base
    assert settings_of(_run(options={"--fmu-dir": "x", "--flavor": "python"})) == base
    for other in (_run({"controller.K_c": 6}), _run(options={"--stop-time": 4.0}),
                  _run(flavor="native"), _run(fmi="3.0"), _run(sha="b" * 64)):  # fmt: skip
        assert settings_of(other) != base


def test_the_note_names_what_the_replaced_results_were_made_with(tmp_path):
    assert replaced_note(tmp_path, _run()) is None  # nothing there
    (tmp_path / "metrics.json").write_text(json.dumps({"run": _run()}))
    assert replaced_note(tmp_path, _run(options={"--no-plots": True})) is None
    assert replaced_note(tmp_path, _run({"controller.K_c": 6, "plant.theta_g_0": "-30 deg"})) == (
        f"replacing the results in {tmp_path} made with other settings: scenario default, "
        "no overrides, python FMUs, FMI 2.0 (this run: scenario default, controller.K_c=6, "
        "plant.theta_g_0=-30 deg, python FMUs, FMI 2.0)"
    )
    note = replaced_note(tmp_path, _run(flavor="native", fmi="3.0", sha="b" * 64))
    assert note.endswith(
        "scenario default, no overrides, python FMUs, FMI 2.0, scenario sha256 aaaaaaaaaaaa "
        "(this run: scenario default, no overrides, native FMUs, FMI 3.0, scenario sha256 "
        "bbbbbbbbbbbb)"
    )
    (tmp_path / "metrics.json").write_text("{not json")
    assert replaced_note(tmp_path, _run({"controller.K_c": 6})) is None


def test_describe_settings_names_the_law_and_the_options():
    run = _run({"controller.law": 3, "controller.K_P": 2.0}, {"--step": 0.01, "--real-time": True})
    assert describe_settings(run) == (
        "scenario default, controller.law=pi, controller.K_P=2, --step 0.01, --real-time, "
        "python FMUs, FMI 2.0"
    )
    assert overrides_text({"run": run}) == "controller.law=pi, controller.K_P=2"
    assert overrides_text({"run": _run()}) == ""


def test_run_out_has_no_special_spelling():
    """``--out out`` is a folder like any other: no default that a spelling could match."""
    args = build_parser().parse_args(["run"])
    assert args.out is None
    assert build_parser().parse_args(["run", "--out", "out"]).out == "out"
