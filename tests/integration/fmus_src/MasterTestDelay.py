"""Test FMU: y(t_k+1) = u(t_k), a one-step delay, no feedthrough."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class MasterTestDelay(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        for unknown in root.find("ModelStructure").find("Outputs"):
            unknown.set("dependencies", "")  # no direct feedthrough
        return root

    def do_step(self, current_time, step_size):
        self.y = self.u
        return True
