"""The verification kit's cases as data (no FMU): the core interface of each component."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from glider_cosim.verify import COMPONENTS, case_names, load_case
from glider_cosim.verify.cases import CORE

README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.parametrize("component", COMPONENTS)
def test_the_core_is_in_every_case_and_one_case_needs_only_the_core(component):
    core = CORE[component].items()
    cases = {n: load_case(component, n).variables.items() for n in case_names(component)}
    assert [n for n, v in cases.items() if not core <= v] == []
    assert [n for n, v in cases.items() if v <= core], f"no {component} case of the core only"


def test_the_readme_lists_each_core_interface():
    """README "Verification kit": one line per component, inputs -> outputs, as CORE."""
    text = README.read_text()
    for component, core in CORE.items():
        ins = ", ".join(f"`{n}`" for n, c in core.items() if c == "input")
        outs = ", ".join(f"`{n}`" for n, c in core.items() if c == "output")
        line = f"| {component} | {ins} | {outs} |"
        assert line in text, line
    assert re.search(r"\| component \| core inputs \| core outputs \|", text)
