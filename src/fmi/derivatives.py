"""State derivatives and directional derivatives in a slave's model description and runtime.

A slave that exposes continuous states lists them as ``derivative variable -> state``
(``GliderSlave.STATE_DERIVATIVES``): :func:`declare` writes the FMI 2.0 ``derivative``
attributes, ``<ModelStructure><Derivatives>`` and their initial unknowns (FMI 3.0's
``<ContinuousStateDerivative>`` is written from these). A slave that provides directional
derivatives names the rows and columns of its Jacobian (``JACOBIAN_ROWS``,
``JACOBIAN_COLUMNS``): :func:`jacobian_tables` gives the FMI layer (``fmi_layer.c``)
each value reference's row and column, from which it forms
``fmi2GetDirectionalDerivative``'s products.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from xml.etree.ElementTree import Element, SubElement


def declare(
    root: Element,
    index: Mapping[str, int],
    state_derivatives: Mapping[str, str],
    provides: bool,
    dependencies: Mapping[str, Sequence[str]] | None = None,
) -> None:
    """Declare the state derivatives in an FMI 2.0 model description ``root``.

    Parameters
    ----------
    root : Element
        The ``fmiModelDescription`` with its ``ModelStructure`` written.
    index : mapping
        Variable name -> its 1-based index in ``ModelVariables``.
    state_derivatives : mapping
        Derivative variable -> state variable (both Real); declared after the outputs.
    provides : bool
        Set ``providesDirectionalDerivative="true"``.
    dependencies : mapping, optional
        Derivative variable -> the knowns (states, inputs) it depends on, written as the
        ``<Derivatives>`` entry's ``dependencies`` (kind ``dependent``); one not listed
        has none written (it depends on every known).
    """
    if provides:
        root.find("CoSimulation").set("providesDirectionalDerivative", "true")
    if not state_derivatives:
        return
    variables = list(root.find("ModelVariables"))
    structure = root.find("ModelStructure")
    listed = Element("Derivatives")  # between <Outputs> and <InitialUnknowns>
    structure.insert(1 if structure.find("Outputs") is not None else 0, listed)
    init_el = structure.find("InitialUnknowns")
    if init_el is None:
        init_el = SubElement(structure, "InitialUnknowns")
    # FMI 2.0 orders InitialUnknowns by index: the derivatives come after the outputs
    last = max((int(u.get("index")) for u in init_el), default=0)
    if min(index[d] for d in state_derivatives) < last:
        raise TypeError("the state derivatives must be declared after the outputs")
    for der, state in state_derivatives.items():
        variables[index[der] - 1].find("Real").set("derivative", str(index[state]))
        attrs = {"index": str(index[der])}
        deps = (dependencies or {}).get(der)
        if deps is not None:
            listed_deps = sorted(index[d] for d in deps if d in index)  # by index
            attrs["dependencies"] = " ".join(map(str, listed_deps))
            if listed_deps:
                attrs["dependenciesKind"] = " ".join("dependent" for _ in listed_deps)
        SubElement(listed, "Unknown", attrs)
        SubElement(init_el, "Unknown", {"index": str(index[der])})


def jacobian_tables(
    names: Mapping[int, str], rows: Mapping[str, int], columns: Sequence[str]
) -> tuple[list[int], list[int], int, int] | None:
    """Per value reference its row and its column of the Jacobian (-1: none), and the
    numbers of rows and columns; None without ``columns`` (no directional derivatives).

    Parameters
    ----------
    names : mapping
        Value reference -> variable name (references 0..n-1).
    rows : mapping
        Unknown -> its row (a state derivative, an output not a state).
    columns : sequence of str
        The knowns (states, inputs), in column order; a name that is no variable's is
        left out (its column is never asked for).
    """
    if not columns:
        return None
    vr_of = {name: vr for vr, name in names.items()}
    row_of, col_of = [-1] * len(names), [-1] * len(names)
    # a subclass may declare fewer variables (no disturbance inputs, say): those rows and
    # columns are then out of reach, the others as they were
    for name, row in rows.items():
        if name in vr_of:
            row_of[vr_of[name]] = row
    for col, name in enumerate(columns):
        if name in vr_of:
            col_of[vr_of[name]] = col
    return row_of, col_of, max(rows.values()) + 1, len(columns)
