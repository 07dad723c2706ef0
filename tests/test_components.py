"""The component registry (``cosim/components.toml`` and each folder's
``component.toml``): what it holds, and the one-line errors for a wrong registry, a wrong
``component.toml``, an unknown component and a scenario's wrong ``components`` or
``[connections]``. Written to pass with components added to the registry as well
(tests/integration/test_add_a_component.py runs it in a clone with a fourth one)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from glider_cosim import components as reg
from glider_cosim.components import (
    COMPONENTS,
    ComponentError,
    UnknownComponentError,
    component,
    default_connections,
    every_run,
    registry,
)
from glider_cosim.scenarios.fields import ScenarioError
from glider_cosim.scenarios.scenario import parse_scenario


def test_each_registry_line_is_a_component_folder():
    lines = registry()
    assert [c.name for c in COMPONENTS] == list(lines)
    assert len({c.model for c in COMPONENTS}) == len(lines), "two components, one model name"
    for c in COMPONENTS:
        assert c.package == f"glider_{c.name}"
        assert (c.folder / "component.toml").is_file()
        assert c.folder.as_posix().endswith(lines[c.name]) or c.folder.name == c.package
        assert c.slave_class().__name__ == c.model
        assert component(c.name) is c


def test_the_default_loop_is_the_papers():
    assert [c.model for c in every_run()] == ["GliderPlant", "GliderObserver", "GliderController"]
    assert [c.name for c in COMPONENTS if c.native] == ["plant", "observer", "controller"]


def test_the_wiring_is_the_component_files_inputs():
    """The loop's default connections are each component's ``[inputs]``, nothing else."""
    want = [(src, f"{c.name}.{inp}") for c in every_run() for inp, src in c.inputs.items()]
    assert default_connections() == want
    assert ("plant.theta_meas", "observer.theta_meas") in want
    assert ("observer.theta_g_hat", "controller.theta_g_hat") in want
    state = default_connections(feedback="state")
    assert ("plant.theta_g", "controller.theta_g_hat") in state
    assert ("observer.theta_g_hat", "controller.theta_g_hat") not in state
    # an instance left out takes its connections with it
    assert all("observer." not in s + t for s, t in default_connections(["plant", "controller"]))


def test_an_unknown_component_names_the_known_ones():
    known = ", ".join(registry())
    with pytest.raises(UnknownComponentError) as err:
        component("depth")
    assert str(err.value) == f"component 'depth' is unknown: expected one of {known}"
    assert isinstance(err.value, ValueError)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x = 1", 'expected a [components] table of name = "src/<name>"'),
        ("[components]\nNoise = 'src/noise'", "component 'Noise' = 'src/noise' is invalid"),
        ("[components]\nnoise = ''", "component 'noise' = '' is invalid: expected a lower-case"),
        ("[components\n", "cannot be read"),
    ],
)
def test_a_wrong_registry_is_one_line(tmp_path, text, message):
    path = tmp_path / "components.toml"
    path.write_text(text)
    with pytest.raises(ComponentError, match=re.escape(message)) as err:
        registry(path)
    assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)


GOOD = 'model = "GliderDepth"\n'


@pytest.mark.parametrize(
    ("text", "key", "expected"),
    [
        ('modle = "GliderDepth"', "modle", "one of bundles, c_sources"),
        ('model = "Glider Depth"', "model", "the FMU's model name"),
        (GOOD + 'bundles = ["sonar"]', "bundles", "fmi or components of the registry"),
        (GOOD + 'c_sources = ["sonar:sonar.c"]', "c_sources", "'<component>:<file>'"),
        (GOOD + '[inputs]\ntheta_ref = "plant"', "inputs", 'input = "instance.output"'),
        (GOOD + '[driven]\nw = "0"', "driven", "input = a number"),
        (GOOD + '[interface]\nz = ["input", "m", "maybe"]', "interface", "need one of"),
        (GOOD + "[reference]\nparameters = 3", "reference", "parameters = {"),
    ],
)
def test_a_wrong_component_file_names_the_key(tmp_path, monkeypatch, text, key, expected):
    """A ``component.toml`` with a wrong key: the file, the key and what was expected."""
    monkeypatch.setattr(reg, "REGISTRY", tmp_path / "cosim" / "components.toml")
    folder = tmp_path / "src" / "depth"
    folder.mkdir(parents=True)
    (folder / "__init__.py").write_text("")
    (folder / "component.toml").write_text(text)
    lines = {**registry(), "depth": "src/depth"}
    with pytest.raises(ComponentError) as err:
        reg._load("depth", "src/depth", lines)
    msg = str(err.value)
    assert msg.startswith(f"{folder / 'component.toml'}: key {key!r} is invalid: expected ")
    assert expected in msg and "\n" not in msg


def test_a_missing_folder_says_to_reinstall(tmp_path, monkeypatch):
    monkeypatch.setattr(reg, "REGISTRY", tmp_path / "cosim" / "components.toml")
    with pytest.raises(ComponentError, match=r"reinstall after adding one: pip install -e \."):
        reg._load("depth", "src/depth", {"depth": "src/depth"})


SCENARIO = 'name = "x"\n'


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('components = "noise"', "key 'components': expected a list of component names"),
        ('components = ["depth"]', "key 'components': component 'depth' is unknown: expected"),
        ('components = ["plant"]', "key 'components': 'plant' is already in the loop"),
        ('[connections]\n"observer.theta_meas" = "noise.theta_out"',
         "key 'connections.observer.theta_meas': 'noise.theta_out' is invalid: expected "
         "'instance.output' of an instance of the loop (plant, observer, controller)"),
        ('[connections]\n"observer" = "plant.theta_meas"',
         "'observer' is invalid: expected 'instance.input'"),
        ("[connections]\n'observer.theta_meas' = 3", "'3' is invalid: expected 'instance.output'"),
    ],
)  # fmt: skip
def test_a_wrong_components_or_connections_key_is_one_line(text, message):
    with pytest.raises(ScenarioError, match=re.escape(message)) as err:
        parse_scenario(__import__("tomllib").loads(SCENARIO + text), "x.toml")
    assert str(err.value).startswith("x.toml: ") and "\n" not in str(err.value)


def test_a_connection_over_the_default_replaces_it():
    import tomllib

    from glider_cosim.scenarios.system import scenario_connections

    sc = parse_scenario(
        tomllib.loads(SCENARIO + '[connections]\n"controller.theta_g_hat" = "plant.theta_g"'),
        "x.toml",
    )
    conns = scenario_connections(sc)
    assert ("plant.theta_g", "controller.theta_g_hat") in conns
    assert ("observer.theta_g_hat", "controller.theta_g_hat") not in conns
    assert len(conns) == len(default_connections())


def test_the_registry_file_is_the_one_setup_packages():
    assert Path(reg.REGISTRY).name == "components.toml"
    assert reg.package_dirs()["glider_cosim"] == "cosim"
    assert {f"glider_{n}" for n in registry()} <= set(reg.package_dirs())


@pytest.mark.parametrize("module", ["reference", "lsref_ours"])
def test_the_reference_commands_name_an_unknown_component(module, capsys):
    """``python -m glider_cosim.verify.reference|lsref_ours --component NAME``: an unknown
    name is a usage error (exit 2) naming the known ones, before anything is built."""
    import importlib

    main = importlib.import_module(f"glider_cosim.verify.{module}").main
    argv = ["--component", "depth"] + (["--check"] if module == "lsref_ours" else [])
    with pytest.raises(SystemExit) as err:
        main(argv)
    assert err.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    known = ", ".join(registry())
    assert last.endswith(f"error: component 'depth' is unknown: expected one of {known}")


def test_the_pitch_plot_shows_what_the_observer_reads():
    """A scenario that feeds the observer another component's pitch (the how-to's noise
    block): the pitch plot draws that column as the measurement, named, not the plant's
    sensor; without such a connection the plot is as it was."""
    import numpy as np
    from report_fakes import FakeRun

    from glider_cosim.figures.plots import PLOTS

    pitch = next(fn for name, _, fn in PLOTS if name == "pitch")
    t = np.linspace(0.0, 10.0, 501)
    cols = {
        "plant.theta": -0.38 + 0 * t,
        "plant.theta_meas": -0.38 + 0 * t,
        "observer.theta_hat": -0.37 + 0 * t,
        "noise.theta_out": -0.37 + 1e-3 * np.sin(t),
    }
    run = FakeRun(cols, t=t)

    def names(spec):
        return [ln["name"] for p in spec["panels"] for ln in p["lines"] if ln.get("name")]

    assert names(pitch(run))[:2] == ["true = measured (noise std 0 deg)", "estimate"]
    run.scenario.connections = {"observer.theta_meas": "noise.theta_out"}
    shown = names(pitch(run))
    assert shown[:3] == ["noise.theta_out (samples, the observer's input)", "true", "estimate"]
    assert "noise.theta_out - true" in shown
