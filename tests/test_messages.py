"""The one-line message of each refused class of input, exactly (issue 21)."""

from __future__ import annotations

import pytest

from glider_cosim.cli import main
from glider_cosim.components import registry
from glider_cosim.scenarios.fields import ScenarioError
from glider_cosim.scenarios.overrides import parse_sets
from glider_cosim.scenarios.scenario import parse_scenario

#: the instance names a message lists: the registry's (plant, observer, controller)
NAMES = ", ".join(registry())

LAW = "expected one of 'open-loop', 'passivity', 'p', 'pi' (any case) or an integer 0..3"


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("controller.law=PID",
         f"--set 'controller.law=PID': 'PID' is invalid: {LAW}; did you mean 'pi'?"),
        ("controller.law=7", f"--set 'controller.law=7': '7' is invalid: {LAW}"),
        ("plant.V_0=fast",
         "--set 'plant.V_0=fast': 'fast' is not a number: expected a number (m/s) or "
         "'X m/s'"),
        ("plant.theta_g_0=x", "--set 'plant.theta_g_0=x': 'x' is not a number: expected a number "
         "(rad) or 'X deg'"),
        ("controller.K_c=a", "--set 'controller.K_c=a': 'a' is not a number: expected a number"),
        ("observer.f_sample=x",
         "--set 'observer.f_sample=x': 'x' is not a number: expected a number (Hz) or 'X Hz'"),
        ("plant.not_ours=x", "--set 'plant.not_ours=x': 'x' is not a number: expected a number"),
    ],
)  # fmt: skip
def test_set_messages(item, message):
    with pytest.raises(ScenarioError) as err:
        parse_sets([item])
    assert str(err.value) == message


@pytest.mark.parametrize("text", ["P", "p", " Pi ", "PI", "Open-Loop", "PASSIVITY", "2"])
def test_law_names_any_case(text):
    value = parse_sets([f"controller.law={text}"])["controller.law"]
    assert value == {"p": 2, "pi": 3, "open-loop": 0, "passivity": 1, "2": 2}[text.strip().lower()]


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"coupling": "gs"},
         "s.toml: key 'coupling': 'gs' is invalid: expected 'gauss-seidel' or 'jacobi' (any case)"),
        ({"feedback": "full"},
         "s.toml: key 'feedback': 'full' is invalid: expected 'observer' or 'state' (any case)"),
        ({"controller": {"law": "PID"}},
         f"s.toml: key 'controller.law': 'PID' is invalid: {LAW}; did you mean 'pi'?"),
        ({"controller": {"law": 2.5}}, f"s.toml: key 'controller.law': 2.5 is invalid: {LAW}"),
        ({"event": [{"when": "time >= 1", "set": {"controller.law": "pd"}}]},
         f"s.toml: key event[0].set.controller.law: 'pd' is invalid: {LAW}; did you mean "
         "'p'?"),
        ({"plant": {"V_0": "fast"}},
         "s.toml: key 'plant.V_0': 'fast' is not a number: expected a number (m/s) or "
         "'X m/s'"),
        ({"plant": {"theta_g_0": "steep"}},
         "s.toml: key 'plant.theta_g_0': 'steep' is not a number: expected a number (rad) or "
         "'X deg'"),
        ({"stop_time": "long"}, "s.toml: key 'stop_time': 'long' is not a number: expected a "
         "number"),
    ],
)  # fmt: skip
def test_scenario_messages(doc, message):
    with pytest.raises(ScenarioError) as err:
        parse_scenario(doc, "s.toml")
    assert str(err.value) == message


def test_enumerations_any_case():
    sc = parse_scenario({"coupling": "Jacobi", "feedback": "STATE", "controller": {"law": "Pi"}})
    assert (sc.coupling, sc.feedback, sc.parameters["controller"]["law"]) == ("jacobi", "state", 3)


def test_cli_coupling_message(capsys):
    with pytest.raises(SystemExit) as ex:
        main(["run", "--coupling", "gs"])
    assert ex.value.code == 2
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith(
            "argument --coupling: invalid choice: 'gs' (choose from 'gauss-seidel', 'jacobi')"
        )
    )


# ------------------------------------------------------------------ issue 28, point 6
@pytest.fixture()
def no_fmus(monkeypatch, tmp_path):
    """Commands get an FMU folder without building anything (what is tested here is
    refused before any FMU is read)."""
    import glider_cosim.fmus.folders as folders

    monkeypatch.setattr(folders, "prepare_fmus", lambda *a, **k: tmp_path)


def _error(capsys, argv: list[str]) -> str:
    """``glider-cosim ARGV``'s one error line (exit code 2, argparse's or ours)."""
    try:
        code = main(argv)
    except SystemExit as ex:  # argparse
        code = ex.code
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    return err.rstrip("\n")


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (["rnu"], "glider-cosim: error: argument command: invalid choice: 'rnu' (choose from "
         "'build', 'run', 'serve', 'build-onboard', 'export-ssp', 'host-env', 'export-fmu', "
         "'report', 'explore', 'analyze', 'sweep', 'verify', 'add-experiments', 'compare', "
         "'scenarios', 'cache'); did you mean 'run'?"),
        (["run", "--coupling", "jacobe"], "glider-cosim run: error: argument --coupling: invalid "
         "choice: 'jacobe' (choose from 'gauss-seidel', 'jacobi'); did you mean 'jacobi'?"),
        (["sweep", "--flavor", "natve"], "glider-cosim sweep: error: argument --flavor: invalid "
         "choice: 'natve' (choose from 'python', 'native'); did you mean 'native'?"),
        (["run", "fig34-kc"], "glider-cosim run: error: fig34-kc: scenario file does not exist "
         "(shipped scenarios: default, fig2-closed-loop, fig2-open-loop, fig3-4-kc, "
         "fig5-6-observer-noise, paper-p-gains, paper-pi-gains, sec52-tail15, sec52-tail30, "
         "sec52-tail45, sec53-literal, sec53-protocol); did you mean 'fig3-4-kc'?"),
        (["run", "--set", "contoller.K_c=3"], "glider-cosim run: error: --set 'contoller.K_c=3': "
         f"expected INSTANCE.NAME=VALUE with INSTANCE one of {NAMES}; did you mean "
         "'controller'?"),
        (["run", "--set", "controller.K_c=6", "--set", "controller.K_c = 8"],
         "glider-cosim run: error: --set 'controller.K_c=6' and --set 'controller.K_c = 8': "
         "controller.K_c is set twice: expected one value per name"),
        (["run", "--set", "controller.law=passivty"], "glider-cosim run: error: --set "
         f"'controller.law=passivty': 'passivty' is invalid: {LAW}; did you mean 'passivity'?"),
        (["sweep", "--param", "controller.K_c=-1,5"], "glider-cosim sweep: error: --param "
         "'controller.K_c=-1,5': -1 is invalid: expected a finite value in (0, inf)"),
        (["sweep", "--param", "contoller.K_c=1"], "glider-cosim sweep: error: --param "
         f"'contoller.K_c=1': expected INSTANCE.NAME=SPEC with INSTANCE one of {NAMES}; did "
         "you mean 'controller'?"),
        (["report", "--workers", "0"], "glider-cosim report: error: --workers 0: expected a "
         "number >= 1"),
        # issue 28, point 4: exports refuse what makes no sense
        (["export-fmu", "x.txt"], "glider-cosim export-fmu: error: OUT 'x.txt': expected a file "
         "name ending in .fmu"),
        (["export-ssp", "x.fmu"], "glider-cosim export-ssp: error: OUT 'x.fmu': expected a file "
         "name ending in .ssp"),
        (["export-ssp", "no-such-folder-28/x.ssp"], "glider-cosim export-ssp: error: OUT "
         "'no-such-folder-28/x.ssp': folder 'no-such-folder-28' does not exist: expected an "
         "existing folder (create it first)"),
    ],
)  # fmt: skip
def test_every_error_line_names_its_command(capsys, no_fmus, argv, line):
    assert _error(capsys, argv) == line


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"stop_tme": 5}, "unknown key 'stop_tme': expected one of"),
        ({"coupling": "jacobe"}, "'jacobe' is invalid: expected 'gauss-seidel' or 'jacobi' (any "
         "case); did you mean 'jacobi'?"),
        ({"event": [{"when": "time >= 1", "dealy": 1, "set": {"controller.K_c": 3}}]},
         "key event[0]: unknown key 'dealy'; did you mean 'delay'?"),
    ],
)  # fmt: skip
def test_scenario_files_get_did_you_mean(doc, message):
    with pytest.raises(ScenarioError) as err:
        parse_scenario(doc, "s.toml")
    assert message in str(err.value)
    if "stop_tme" in doc:
        assert str(err.value).endswith("; did you mean 'stop_time'?")


def test_did_you_mean_only_when_close():
    from glider_cosim.inputs.text import did_you_mean

    assert did_you_mean("K_C", ["K_c", "law"]) == "; did you mean 'K_c'?"
    assert did_you_mean("gs", ["gauss-seidel", "jacobi"]) == ""
    assert did_you_mean("x" * 1000, ["x"]) == ""


def test_scenarios_prints_one_line_each(capsys):
    from glider_cosim.scenarios.scenario import load_scenario, shipped_scenarios

    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = shipped_scenarios()
    assert [line.split()[0] for line in lines] == names
    for name, line in zip(names, lines, strict=True):
        summary = load_scenario(name).summary
        assert summary and "\n" not in summary and len(summary) <= 80, name
        assert line.endswith(f"  {summary}")
    assert lines[0] == (
        "default                Sec. 3.3: from -35 deg back to the steady glide, passivity law "
        "K_c = 10"
    )


def test_a_summary_is_one_line_and_falls_back_to_the_description():
    from glider_cosim.scenarios.scenario import one_line_summary

    with pytest.raises(ScenarioError, match=r"^s.toml: key 'summary': expected one line$"):
        parse_scenario({"summary": "a\nb"}, "s.toml")
    sc = parse_scenario({"description": "First sentence. Second one."})
    assert one_line_summary(sc) == "First sentence"
    sc = parse_scenario({"description": "word " * 40})
    assert one_line_summary(sc).endswith("word...") and len(one_line_summary(sc)) <= 80


def test_api_overrides_take_what_set_takes():
    import math

    from glider_cosim.scenarios.overrides import override_scenario, parse_overrides
    from glider_cosim.scenarios.scenario import load_scenario

    assert parse_overrides({"controller.K_c": 6, "plant.theta_g_0": "-30 deg",
                            "plant.V_0": "0.2 m/s", "controller.law": "PI",
                            "observer.filter_enabled": True}) == pytest.approx({
        "controller.K_c": 6, "plant.theta_g_0": math.radians(-30), "plant.V_0": 0.2,
        "controller.law": 3, "observer.filter_enabled": True})  # fmt: skip
    sc = override_scenario(load_scenario(None), {"controller.K_c": "6", "plant.V_0": "0.2 m/s"})
    assert sc.parameters["controller"]["K_c"] == 6
    assert sc.origins["plant.V_0"] == "overrides['plant.V_0']"
    for overrides, message in [
        ({"controller.K_c": "6 deg"},
         "overrides['controller.K_c']: '6 deg' is invalid: K_c has no unit: expected a plain "
         "number"),
        ({"controller.K_c": -1},
         "overrides['controller.K_c']: -1 is invalid: expected a finite value in (0, inf)"),
        ({"K_c": 1}, "overrides['K_c']: expected INSTANCE.NAME=VALUE with INSTANCE one of "
         f"{NAMES}"),
        ({"plant.V_0": "fast"},
         "overrides['plant.V_0']: 'fast' is not a number: expected a number (m/s) or 'X m/s'"),
    ]:  # fmt: skip
        with pytest.raises(ValueError) as err:
            override_scenario(load_scenario(None), overrides)
        assert str(err.value) == message


def test_a_fmu_dir_that_does_not_exist_gets_one_note(capsys, no_fmus, tmp_path):
    """A typo in --fmu-dir would build a whole new set there: one note says so."""
    folder = tmp_path / "fmuz"
    code = main(["run", "--fmu-dir", str(folder), "--set", "controller.K_c=6", "--set",
                 "controller.K_c=7"])  # fmt: skip
    lines = capsys.readouterr().err.splitlines()
    assert code == 2
    assert lines[0] == (
        f"glider-cosim: note: --fmu-dir '{folder}' does not exist: a fresh set of FMUs is "
        "built there"
    )
    assert len(lines) == 2 and lines[1].startswith("glider-cosim run: error: --set")
    folder.mkdir()
    main(["run", "--fmu-dir", str(folder), "--set", "controller.K_c=6", "--set",
          "controller.K_c=7"])  # fmt: skip
    assert "note" not in capsys.readouterr().err  # an existing folder: no note


def _literals(node) -> str:
    """The text a string or f-string expression starts with (its constant parts)."""
    import ast

    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
    return ""


#: the front door's checks whose second argument says where a message's input came from
WHERE_FIRST = ("regular_file", "read_fmu", "safe_extract", "confined")


def test_one_place_builds_the_prefixes_and_no_message_names_its_command():
    """Every ``glider-cosim [COMMAND]: error|warning|note: `` comes from
    ``inputs.text.prefix``; no error message starts with a command's name (the prefix
    names it)."""
    import ast
    from pathlib import Path

    from glider_cosim.cli.parser import build_parser
    from glider_cosim.inputs.text import prefix

    assert prefix("error", "run") == "glider-cosim run: error: "
    assert prefix("note") == "glider-cosim: note: "
    commands = set(build_parser()._subparsers._group_actions[0].choices)  # noqa: SLF001
    root = Path(__file__).resolve().parents[1] / "cosim"
    bad = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            text = _literals(node)
            where = f"{path.relative_to(root)}:{getattr(node, 'lineno', '?')}"
            for kind in ("error", "warning", "note"):
                if f": {kind}: " in text and "glider-cosim" in text and path.name != "text.py":
                    bad.append(f"{where}: {text!r}")
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call) and node.exc.args:
                head = _literals(node.exc.args[0]).partition(": ")[0]
                if head in commands:
                    bad.append(f"{where}: names its command: {head!r}")
            if isinstance(node, ast.Call) and getattr(node.func, "id", "") in WHERE_FIRST:
                named = [_literals(a) for a in node.args[1:2] if _literals(a) in commands]
                bad += [f"{where}: where={w!r} names its command" for w in named]
    assert bad == []
