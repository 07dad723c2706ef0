"""Test FMU: y = k * u with direct feedthrough (computed when read); an Integer output."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class MasterTestGain(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.k = 1.0
        self.count = 0
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(
            Real("y", causality=Fmi2Causality.output, getter=lambda: self.k * self.u)
        )
        self.register_variable(
            Real("k", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        )
        self.register_variable(
            Integer("count", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete)
        )

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        outputs = root.find("ModelStructure").find("Outputs")
        for unknown in outputs:
            # y (index 2) depends on u (index 1); count on nothing
            unknown.set("dependencies", "1" if unknown.get("index") == "2" else "")
        return root

    def do_step(self, current_time, step_size):
        self.count += 1
        return True
