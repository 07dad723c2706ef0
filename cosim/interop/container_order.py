"""The one-FMU export's container initialised in the order of the FMUs' model structure.

fmu-manipulation-toolbox (2.0) orders the embedded FMUs for the initialization by their
links alone; :func:`ordered` gives its ``FMUContainer`` the order of the standard's
importers, from the embedded FMUs' ``<InitialUnknowns>`` dependencies
(:func:`initial_inputs`). Used by :mod:`glider_cosim.interop.onefmu`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def initial_inputs(fmu: Path) -> set[str] | None:
    """The inputs that the initial unknowns of ``fmu`` that are outputs depend on (the
    dependencies of its ``<InitialUnknowns>``; a state derivative links nothing); None:
    one declares none (then it depends on every input)."""
    from fmpy import read_model_description

    inputs: set[str] = set()
    for u in read_model_description(str(fmu)).initialUnknowns:
        if u.variable.causality != "output":
            continue
        if u.dependencies is None:
            return None
        inputs |= {d.name for d in u.dependencies if d.causality == "input"}
    return inputs


def ordered(base: type) -> type:
    """fmu-manipulation-toolbox's ``FMUContainer`` with the initialization order of the
    standard's importers.

    The toolbox (2.0) orders the embedded FMUs for the initialization by their links
    alone: plant -> observer -> controller -> plant is a loop to it, which it cuts before
    the plant with the warning "Loop of links through the embedded FMU
    'GliderPlant.fmu'". A link only has to be propagated before its input's FMU when an
    initial unknown of that FMU depends on the input (its ``<InitialUnknowns>``
    dependencies): the plant's outputs depend on none of its inputs, the observer's
    pre-filter on the measured pitch, the controller's command on the estimate. Over
    those links the order is plant, observer, controller, with no loop and no warning;
    the container then sets every input in Initialization Mode from its source's
    value there, as our master does (:mod:`glider_cosim.master.cosimulation`).
    """

    class OrderedContainer(base):  # type: ignore[misc, valid-type]
        #: embedded FMU (file name) -> the inputs its initial unknowns depend on (None:
        #: every input, as the toolbox assumes)
        initial_inputs: dict[str, set[str] | None] = {}

        def _link_graph(self, links: Any, fmu_rank: dict[str, int]) -> dict[int, set[int]]:
            """The toolbox's graph (``FMUContainer._link_graph``) without the links into
            an input that no initial unknown of its FMU depends on."""
            successors: dict[int, set[int]] = {rank: set() for rank in fmu_rank.values()}
            for link in links:
                src = link.cport_from
                if src is None or src.port.clock or src.port.type_name == "clock":
                    continue
                for dst in link.cport_to_list:
                    if dst.port.is_reset or dst.port.clock or dst.fmu.name == src.fmu.name:
                        continue
                    if src.fmu.name not in fmu_rank or dst.fmu.name not in fmu_rank:
                        continue
                    needs = self.initial_inputs.get(dst.fmu.name)
                    if needs is None or dst.port.name in needs:
                        successors[fmu_rank[src.fmu.name]].add(fmu_rank[dst.fmu.name])
            return successors

    return OrderedContainer
