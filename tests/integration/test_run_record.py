"""Every output records its run (issue 21): metrics.json's run record, the plots' subtitles
and marked events (read back from the PNGs and from the figures' artists), and a rerun
into the same folder."""

from __future__ import annotations

import hashlib
import json
from importlib import metadata, resources
from pathlib import Path

import pytest

from glider_cosim.cli import main
from glider_cosim.figures.plots import read_png_record, write_plots
from glider_cosim.runner import simulate
from glider_cosim.runner.provenance import OWNED, file_sha256
from glider_cosim.scenarios.scenario import load_scenario, parse_scenario

pytestmark = pytest.mark.integration
PNGS = ("glide_angle", "pitch", "tail_angle", "speed", "depth")
TIME_PLOTS = ("glide_angle", "pitch", "tail_angle", "speed")


def _cli(fmu_dir, *args):
    return main(["run", *args, "--fmu-dir", str(fmu_dir)])


def test_metrics_record_the_run(fmu_dir, tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["--set", "controller.K_c=12", "--set", "plant.theta_g_0=-30 deg", "--stop-time", "4",
            "--coupling", "Jacobi", "--out", str(out)]  # fmt: skip
    assert _cli(fmu_dir, *argv) == 0
    run = json.loads((out / "metrics.json").read_text())["run"]
    text = (resources.files("glider_cosim") / "scenarios" / "default.toml").read_text()
    assert run["scenario"] == "default"
    assert run["scenario_sha256"] == hashlib.sha256(text.encode()).hexdigest()
    assert run["overrides"] == {"controller.K_c": 12, "plant.theta_g_0": "-30 deg"}
    assert run["options"] == {"--coupling": "jacobi", "--stop-time": 4.0,
                              "--fmu-dir": str(fmu_dir)}  # fmt: skip
    assert run["package_version"] == metadata.version("glider-cosim")
    assert set(run["fmus"]) == {"plant", "observer", "controller"}
    for inst, rec in run["fmus"].items():
        assert rec["sha256"] == file_sha256(fmu_dir / f"Glider{inst.capitalize()}.fmu")
        assert len(rec["guid"]) == 36 and rec["flavor"] == "python" and rec["version"]
    for png in PNGS:
        settings = read_png_record(out / f"{png}.png")["settings"]
        assert settings == (
            "scenario default; controller.K_c=12, plant.theta_g_0=-30 deg, --coupling jacobi, "
            f"--stop-time 4, --fmu-dir {fmu_dir}"
        )


def test_no_plots_rerun_removes_only_what_the_run_owns(fmu_dir, tmp_path):
    out = tmp_path / "o"
    assert _cli(fmu_dir, "--stop-time", "2", "--out", str(out)) == 0
    assert all((out / f"{p}.png").exists() for p in PNGS)
    (out / "notes.txt").write_text("mine")
    (out / "other.png").write_bytes(b"not ours")
    assert _cli(fmu_dir, "--stop-time", "1", "--no-plots", "--out", str(out)) == 0
    left = sorted(p.name for p in out.iterdir())
    assert left == ["metrics.json", "notes.txt", "other.png", "results.csv"]
    m = json.loads((out / "metrics.json").read_text())
    assert m["rows"] == 51 and m["run"]["options"]["--no-plots"] is True
    assert set(OWNED) >= {"results.csv", "metrics.json", *(f"{p}.png" for p in PNGS)}


def _lines(spec):
    return [ln for p in spec["panels"] for ln in p["lines"] if ln["gid"][:6] == "event:"]


@pytest.mark.parametrize(
    ("name", "doc", "kinds"),
    [
        ("takeover", {"name": "takeover", "stop_time": 40.0, "plant": {"delta_0": "2 deg"},
                      "controller": {"law": "open-loop", "delta_open": "2 deg", "t_enable": 3.0},
                      "event": [{"when": "plant.z >= 1.0",
                                 "set": {"controller.law": "passivity"}}]},
         ["enable", "takeover"]),
        ("stall", None, ["stall"]),
    ],
)  # fmt: skip
def test_plots_mark_the_events(fmu_dir, tmp_path, name, doc, kinds):
    sc = parse_scenario(doc) if doc else load_scenario("paper-p-gains")
    r = simulate(sc, tmp_path, fmu_dir=fmu_dir, build=False)
    events = json.loads((tmp_path / "metrics.json").read_text())["events"]
    assert [e["kind"] for e in events] == kinds
    if name == "stall":
        assert r.status == "stopped"
        assert events[0]["time_s"] == pytest.approx(5.54)
        assert events[0]["label"] == "observer stalled (fmi2Discard)"
    else:
        assert events[0]["time_s"] == 3.0
        assert events[1]["label"].startswith(
            "takeover at plant.z >= 1 m (controller.law = passivity)"
        )
        z = r.column("plant.z")
        k = list(r.data[:, 0]).index(events[1]["time_s"])
        assert z[k] >= 1.0 > z[k - 1]
    for png in PNGS:  # what each PNG says it marks
        assert read_png_record(tmp_path / f"{png}.png")["events"] == events
    specs: list = []
    (tmp_path / "again").mkdir()
    write_plots(r, tmp_path / "again", keep=specs)
    assert len(specs) == len(PNGS)
    for png, spec in zip(PNGS, specs):
        lines = _lines(spec)
        if png in TIME_PLOTS:  # a vertical line at each event's time, on every panel
            for p in spec["panels"]:
                marks = [(ln["gid"], ln["x"][0], ln["x"][1], tuple(ln["y"])) for ln in p["lines"]
                         if ln["gid"].startswith("event:")]  # fmt: skip
                assert marks == [(f"event:{e['kind']}", e["time_s"], e["time_s"],
                                  tuple(p["ylim"])) for e in events]  # fmt: skip
        else:  # the depth profile: a point on the path at each event
            assert [ln["gid"] for ln in lines] == [f"event:{e['kind']}" for e in events]
        labels = [ln["name"] for ln in spec["panels"][0]["lines"] if ln["legend"]]
        assert all(any(e["label"] in lab for lab in labels) for e in events)


# ------------------------------------------------------------------ issue 28: --out
def test_out_is_written_straight_into_for_every_spelling(fmu_dir, tmp_path, monkeypatch, capsys):
    """``--out out``, ``--out ./out`` and an absolute path all write into that folder;
    without ``--out``, ``out/<scenario>``."""
    monkeypatch.chdir(tmp_path)
    common = ["run", "--stop-time", "0.1", "--no-plots", "--fmu-dir", str(fmu_dir)]
    for spelling, folder in (("out", "out"), ("./dot", "dot"), (str(tmp_path / "abs"), "abs")):
        assert main([*common, "--out", spelling]) == 0
        assert (tmp_path / folder / "metrics.json").is_file(), spelling
        assert not (tmp_path / folder / "default").exists(), spelling
    assert main(common) == 0
    assert (tmp_path / "out" / "default" / "metrics.json").is_file()
    assert f"wrote {Path('out') / 'default' / 'results.csv'}" in capsys.readouterr().out


def test_replacing_results_made_otherwise_says_what_they_were(fmu_dir, tmp_path, capsys):
    out = tmp_path / "out"
    common = ["run", "--stop-time", "0.1", "--no-plots", "--fmu-dir", str(fmu_dir), "--out",
              str(out)]  # fmt: skip
    assert main(common) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert captured.out.startswith("scenario default (<shipped>/default.toml): 6 rows")
    assert main([*common, "--set", "controller.K_c=6"]) == 0
    captured = capsys.readouterr()
    # the summary names the overrides; the note, what the replaced results were made with
    assert captured.out.startswith(
        "scenario default (<shipped>/default.toml) with controller.K_c=6: 6 rows"
    )
    assert captured.err == (
        f"glider-cosim: note: replacing the results in {out} made with other settings: "
        "scenario default, no overrides, --stop-time 0.1, python FMUs, FMI 2.0 (this run: "
        "scenario default, controller.K_c=6, --stop-time 0.1, python FMUs, FMI 2.0)\n"
    )
    assert main([*common, "--set", "controller.K_c=6"]) == 0  # the same settings: no note
    assert capsys.readouterr().err == ""


def test_the_summary_echoes_every_override_with_its_unit(native_dir, tmp_path, capsys):
    """Issue 45: `--set plant.alpha_0=1` ran at 57.3 deg and nothing said so. The summary
    names each override with its variable's unit (from the FMUs' model descriptions), an
    angle in rad in degrees too, one given in degrees in rad too."""
    sets = ["plant.alpha_0=1", "controller.K_c=6", "plant.theta_g_0=-30 deg",
            "plant.V_0=0.2 m/s", "controller.law=2"]  # fmt: skip
    argv = ["run", "--stop-time", "0.1", "--no-plots", "--fmu-dir", str(native_dir), "--out",
            str(tmp_path)]  # fmt: skip
    for item in sets:
        argv += ["--set", item]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1] == (
        "  set: plant.alpha_0 = 1 rad (57.3 deg), controller.K_c = 6, plant.theta_g_0 = -30 "
        "deg (-0.5236 rad), plant.V_0 = 0.2 m/s, controller.law = 2 (p)"
    )


def test_the_units_of_the_echo_are_the_model_descriptions(native_dir, tmp_path):
    """An FMU whose description says another unit is echoed in that unit: no table of
    names in the code."""
    import zipfile

    from glider_cosim.fmus.variables import overrides_echo

    src = native_dir / "GliderPlant.fmu"
    fmu = tmp_path / "GliderPlant.fmu"
    with zipfile.ZipFile(src) as a, zipfile.ZipFile(fmu, "w") as b:
        for item in a.infolist():
            data = a.read(item)
            if item.filename == "modelDescription.xml":
                assert b'unit="m/s"' in data
                data = data.replace(b"m/s", b"km/h")
            b.writestr(item, data)
    assert overrides_echo({"plant.V_0": 0.2}, {"plant": fmu}) == "plant.V_0 = 0.2 km/h"
    assert overrides_echo({"plant.V_0": 0.2}, {"plant": src}) == "plant.V_0 = 0.2 m/s"
