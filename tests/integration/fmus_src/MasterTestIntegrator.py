"""Test FMU: y = y0 + integral of u dt (exact for a held input), no feedthrough."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class MasterTestIntegrator(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.y0 = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output))
        self.register_variable(
            Real("y0", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        )

    def exit_initialization_mode(self):
        self.y = self.y0

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        for unknown in root.find("ModelStructure").find("Outputs"):
            unknown.set("dependencies", "")  # no direct feedthrough
        return root

    def do_step(self, current_time, step_size):
        self.y += self.u * step_size
        return True
