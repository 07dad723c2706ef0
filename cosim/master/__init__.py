"""The co-simulation master: runs FMI 2.0 and 3.0 co-simulation FMUs at a fixed step.

The public API: :class:`CoSimulation` runs a :class:`System` (FMUs, parameters,
connections, driven inputs, disturbances, events), and the typed errors it raises.
"""

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
