"""State derivatives and directional derivatives in a slave's model description and runtime.

:class:`StateDerivatives`, a base of ``GliderSlave``: a slave that exposes continuous
states lists them as ``derivative variable -> state`` (``STATE_DERIVATIVES``, with what
each depends on in ``DERIVATIVE_DEPENDENCIES``): :func:`declare` writes the FMI 2.0
``derivative`` attributes, ``<ModelStructure><Derivatives>`` and their initial unknowns
(FMI 3.0's ``<ContinuousStateDerivative>`` is written from these). A slave that provides
directional derivatives names the rows and columns of its Jacobian (``JACOBIAN_ROWS``,
``JACOBIAN_COLUMNS``) and computes it (``jacobian()``): :func:`jacobian_tables` gives the
FMI layer (``fmi_layer.c``) each value reference's row and column, from which it forms
``fmi2GetDirectionalDerivative``'s products.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any
from xml.etree.ElementTree import Element, SubElement

#: the causalities whose variables cannot be set, in the refusal's words
UNSETTABLE = {"output": "an output", "local": "a calculated variable"}


class StateDerivatives:
    """What a slave declares of its states and directional derivatives (none by default)."""

    #: continuous states exposed with their derivatives: derivative variable -> state
    #: variable (FMI 2 ``<Derivatives>``, FMI 3 ``<ContinuousStateDerivative>``)
    STATE_DERIVATIVES: dict[str, str] = {}
    #: state derivative -> the states and inputs it depends on (``<Derivatives>``'s
    #: ``dependencies``; a derivative not listed depends on every known)
    DERIVATIVE_DEPENDENCIES: dict[str, tuple[str, ...]] = {}
    #: directional derivatives (``providesDirectionalDerivative``): the knowns (states and
    #: inputs), the columns of :meth:`jacobian`, and the unknowns with a row of it (variable
    #: -> row; an output that is a state needs none); empty: not provided
    JACOBIAN_COLUMNS: tuple[str, ...] = ()
    JACOBIAN_ROWS: dict[str, int] = {}
    vars: dict[int, Any]  # pythonfmu's value reference -> variable

    def _jacobian_tables(self) -> tuple[list[int], list[int], int, int] | None:
        """The runtime's tables of the directional derivatives (:func:`jacobian_tables`)."""
        names = {vr: v.name for vr, v in self.vars.items()}
        return jacobian_tables(names, self.JACOBIAN_ROWS, self.JACOBIAN_COLUMNS)

    def jacobian(self) -> Sequence[float]:  # pragma: no cover - overridden
        """The Jacobian at the current point, row-major (rows :attr:`JACOBIAN_ROWS`,
        columns :attr:`JACOBIAN_COLUMNS`); the runtime forms the directional derivatives
        from it."""
        raise NotImplementedError


def declare(
    slave: StateDerivatives,
    root: Element,
    index: Mapping[str, int],
    dependencies: Callable[[Sequence[str], Mapping[str, int]], dict[str, str]],
) -> Element:
    """Declare ``slave``'s state derivatives and directional derivatives in its FMI 2.0
    model description ``root`` (returned); a derivative's initial unknown takes its
    dependencies from the slave's ``INITIAL_DEPENDENCIES``.

    Parameters
    ----------
    slave : StateDerivatives
        The slave (its class attributes say what to declare).
    root : Element
        The ``fmiModelDescription`` with its ``ModelStructure`` written.
    index : mapping
        Variable name -> its 1-based index in ``ModelVariables``.
    dependencies : callable
        ``(knowns, index) ->`` the ``dependencies`` and ``dependenciesKind`` attributes
        (the slave base's, as for outputs).
    """
    if slave.JACOBIAN_COLUMNS:
        root.find("CoSimulation").set("providesDirectionalDerivative", "true")
    if not slave.STATE_DERIVATIVES:
        return root
    variables = list(root.find("ModelVariables"))
    structure = root.find("ModelStructure")
    listed = Element("Derivatives")  # between <Outputs> and <InitialUnknowns>
    structure.insert(1 if structure.find("Outputs") is not None else 0, listed)
    init_el = structure.find("InitialUnknowns")
    if init_el is None:
        init_el = SubElement(structure, "InitialUnknowns")
    # FMI 2.0 orders InitialUnknowns by index: the derivatives come after the outputs
    last = max((int(u.get("index")) for u in init_el), default=0)
    if min(index[d] for d in slave.STATE_DERIVATIVES) < last:
        raise TypeError("the state derivatives must be declared after the outputs")
    for der, state in slave.STATE_DERIVATIVES.items():
        variables[index[der] - 1].find("Real").set("derivative", str(index[state]))
        attrs = {"index": str(index[der])}
        knowns = slave.DERIVATIVE_DEPENDENCIES.get(der)
        if knowns is not None:  # a subclass may drop knowns
            attrs |= dependencies([k for k in knowns if k in index], index)
        SubElement(listed, "Unknown", attrs)
        attrs = {"index": str(index[der])}
        knowns = (getattr(slave, "INITIAL_DEPENDENCIES", None) or {}).get(der)
        if knowns is not None:  # in Initialization Mode
            attrs |= dependencies([k for k in knowns if k in index], index)
        SubElement(init_el, "Unknown", attrs)
    return root


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
