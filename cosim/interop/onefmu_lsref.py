"""The one-FMU export's FMI-LS-REF folder: the container carries its own tests too.

The loop is run with our master and Jacobi coupling, the container's own scheme (its
outputs equal that run bit for bit, :mod:`glider_cosim.interop.onefmu`), and every output
of every instance (the container's outputs, named ``instance.variable``) is recorded:

- ``smoke-test.exp`` (``experiment/smoke-test``): the first :data:`SMOKE_SECONDS` s;
- ``validation.exp`` (``experiment/validation``): the scenario's whole run;
- ``parameters/<scenario>.ssv`` (``parameter``): each shipped scenario of the same loop
  (feedback, observer; no events, disturbances or swapped FMUs) whose values of the
  container's exposed parameters differ from the exported scenario's;
- ``README.md`` (``document``): what the container is and the scenario it was built from.

No stimuli: the container's inputs (the disturbances) stay at their start values, 0.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .lsref_write import (
    SSV_MIME,
    VALIDATION_TOLERANCE,
    Experiment,
    Related,
    experiment_files,
    ssv_bytes,
    zip_entries,
)

#: the smoke test's span, s (the whole run if shorter)
SMOKE_SECONDS = 10.0


def _exposed_values(sc: Any, exposed: tuple[str, ...]) -> dict[str, Any]:
    from ..scenarios.sampling import has_our_observer, with_sampling

    values = with_sampling(sc.parameters, sc.step, sc.source, has_our_observer(sc))
    return {ref: values.get(ref.split(".", 1)[0], {}).get(ref.split(".", 1)[1]) for ref in exposed}


def _parameter_sets(sc: Any, exposed: tuple[str, ...], types: dict[str, str]) -> list[Related]:
    from ..scenarios.scenario import load_scenario, one_line_summary, shipped_scenarios

    mine = _exposed_values(sc, exposed)
    out = []
    for name in shipped_scenarios():
        other = load_scenario(name)
        if name == sc.name or other.events or other.disturbances or other.fmus:
            continue
        if (other.feedback, other.observer) != (sc.feedback, sc.observer):
            continue
        theirs = _exposed_values(other, exposed)
        values = {k: v for k, v in theirs.items() if v is not None and v != mine.get(k)}
        if values:
            out.append(Related(f"parameters/{name}.ssv", "parameter", SSV_MIME,
                               f"scenario {name}: {one_line_summary(other, 200)}",
                               ssv_bytes(name, values, types), (("scenario", name),)))  # fmt: skip
    return out


def loop_entries(
    sc: Any, fmu_dir: Path, model: str, exposed: tuple[str, ...], types: dict[str, str]
) -> dict[str, bytes]:
    """Zip path -> bytes of the container's LS-REF folder (``types``: its variables' FMI
    types, for the parameter sets)."""
    import numpy as np

    from ..master.cosimulation import CoSimulation
    from ..scenarios.system import system_for

    system = system_for(sc, fmu_dir, sc.step)
    sim = CoSimulation(system, step=sc.step, coupling="jacobi")
    rec = _Rows()
    try:
        sim.run(sc.stop_time, rec)
    finally:
        sim.close()
    data = np.array(rec.rows, dtype=float)
    cols = list(rec.columns)
    smoke_n = min(len(data), int(round(SMOKE_SECONDS / sc.step)) + 1)
    runs = (("smoke-test", "experiment/smoke-test", data[:smoke_n], "the first "
             f"{(smoke_n - 1) * sc.step:g} s"), ("validation", "experiment/validation", data,
             "the whole run"))  # fmt: skip
    related: list[Related] = []
    for folder, role, rows, span in runs:
        ex = Experiment(sc.name, f"{model}, scenario {sc.name!r}: {span}, the disturbance "
                        "inputs at 0", 0.0, float(rows[-1, 0]), sc.step, VALIDATION_TOLERANCE,
                        (cols, rows))  # fmt: skip
        related += experiment_files(folder, [ex], types, role, f"{model} {folder}",
                                    f"{model}: the loop of scenario {sc.name!r}, {span} "
                                    "(our master, Jacobi coupling)")  # fmt: skip
    related += _parameter_sets(sc, exposed, types)
    text = (f"# {model}\n\nThe closed loop of glider-cosim's scenario `{sc.name}` as one FMI 2.0 "
            f"co-simulation FMU (an FMU container of the plant, observer and controller "
            f"FMUs, Jacobi coupling at {sc.step:g} s).\n\n{sc.description or sc.summary}\n\n"
            "Its experiments were recorded from our master's run of the same loop; "
            "`glider-cosim verify` runs them.\n")  # fmt: skip
    related.append(Related("README.md", "document", "text/markdown",
                           f"{model}: what the container is", text.encode()))  # fmt: skip
    return zip_entries(related)


class _Rows:
    """A recorder keeping the rows (time first)."""

    def start(self, columns: Any) -> None:
        self.columns = list(columns)
        self.rows: list = []

    def row(self, values: Any) -> None:
        self.rows.append(list(values))

    def close(self) -> None:
        pass
