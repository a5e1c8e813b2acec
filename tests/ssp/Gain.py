"""A gain with direct feedthrough, exported as an FMI 2.0 co-simulation FMU by pythonfmu.

Used by tutti's SSP tests (tests/cli/ssp.rs). Its outputs are computed from its inputs
whenever they are read (getters), not in doStep: y = k·u + c, n_out = 2·n_in,
b_out = not b_in. Parameters: k, c.
"""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class Gain(Fmi2Slave):
    author = "tutti"
    description = "Gain with direct feedthrough (tutti test model)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.k = 1.0
        self.c = 0.0
        self.n_in = 0
        self.b_in = False
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Integer("n_in", causality=Fmi2Causality.input, variability=Fmi2Variability.discrete))
        self.register_variable(Boolean("b_in", causality=Fmi2Causality.input, variability=Fmi2Variability.discrete))
        self.register_variable(Real("k", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("c", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=lambda: self.k * self.u + self.c))
        self.register_variable(
            Integer("n_out", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete,
                    getter=lambda: 2 * self.n_in)
        )
        self.register_variable(
            Boolean("b_out", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete,
                    getter=lambda: not self.b_in)
        )

    def do_step(self, current_time, step_size):
        return True
