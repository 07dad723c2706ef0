"""Test FMU for the FMI runtime: counts its module's executions, fails on demand.

``mode`` (Integer input) at a step: 0 integrate ``u`` into ``y``; 1 raise
ZeroDivisionError; 2 stop cleanly (fmi2Discard); 3 log a debug message and a warning.
``gain`` must be > 0 (checked at exitInitializationMode). ``executions`` is how often
this module was executed in the process.
"""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

EXECUTIONS = globals().get("EXECUTIONS", 0) + 1


class RuntimeTestProbe(Fmi2Slave):
    log_categories = {**Fmi2Slave.log_categories, "logFmiCalls": "every FMI call"}

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.gain = 1.0
        self.mode = 0
        self.flag = False
        self.label = "probe"
        self.executions = EXECUTIONS
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output))
        self.register_variable(
            Real("gain", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        )
        self.register_variable(
            Integer("mode", causality=Fmi2Causality.input, variability=Fmi2Variability.discrete)
        )
        self.register_variable(
            Boolean("flag", causality=Fmi2Causality.input, variability=Fmi2Variability.discrete)
        )
        self.register_variable(
            String("label", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        )
        self.register_variable(
            Integer(
                "executions", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete
            )
        )

    def exit_initialization_mode(self):
        if not self.gain > 0:
            raise ValueError(f"gain = {self.gain!r} is invalid: expected > 0")

    def do_step(self, current_time, step_size):
        if self.mode == 1:
            return 1 / 0
        if self.mode == 2:
            self.log(f"stopped at t = {current_time}", Fmi2Status.discard)
            return False
        if self.mode == 3:
            self.log("a debug message with 100% of its text", Fmi2Status.ok)
            self.log("a warning", Fmi2Status.warning)
        self.y += self.gain * self.u * step_size
        return True
