"""The co-simulation master: runs FMI 2.0 and 3.0 co-simulation FMUs at a fixed step.

The public API: :class:`CoSimulation` runs a :class:`System` (FMUs, parameters,
connections, driven inputs, disturbances, events), and the typed errors it raises.
Each name is imported on first use: importing :mod:`.errors` or :mod:`.spec` alone
(the command line's parser does) imports neither fmpy nor numpy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..inputs.lazy import lazy_names

if TYPE_CHECKING:
    from .cosimulation import CoSimulation
    from .errors import FMUCallError, FMUStopped, Interrupted, MasterError, SystemSpecError
    from .spec import (
        COUPLINGS,
        DEFAULT_MAX_STEPS,
        Disturbance,
        Event,
        Recorder,
        System,
        VarRef,
        count_steps,
    )

__all__ = [
    "COUPLINGS",
    "DEFAULT_MAX_STEPS",
    "CoSimulation",
    "Disturbance",
    "Event",
    "FMUCallError",
    "FMUStopped",
    "Interrupted",
    "MasterError",
    "Recorder",
    "System",
    "SystemSpecError",
    "VarRef",
    "count_steps",
]
_ERRORS = ("FMUCallError", "FMUStopped", "Interrupted", "MasterError", "SystemSpecError")
__getattr__, __dir__ = lazy_names(
    __name__,
    {"CoSimulation": "cosimulation", **dict.fromkeys(_ERRORS, "errors"),
     **{n: "spec" for n in __all__ if n != "CoSimulation" and n not in _ERRORS}},
)  # fmt: skip
