"""A pythonfmu FMU that instantiates but cannot run: its step raises."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class BrokenCar(Fmi2Slave):
    description = "a model whose doStep raises"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        raise RuntimeError("the supplier's model failed")
