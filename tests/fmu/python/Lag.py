"""A first-order lag with an integrator, exported as an FMI 2.0 co-simulation FMU by pythonfmu.

Used by tutti's FMU tests (tests/fmu_*.rs). Explicit Euler with the communication step, so
that fmpy and tutti, given the same inputs and step, compute the same numbers bit for bit.
Outputs: y (lag of u), integral (of u), t (the time at the end of the step), count (steps
made, an Integer), positive (y > 0, a Boolean). Parameters: tau (time constant), gain.
Setting `fail_at` > 0 makes doStep refuse (with a log message at status Error) once the time
reaches it; `raise_at` > 0 makes it raise a Python exception instead (status Fatal).

Every value it computes with is a registered variable (inputs, parameters, outputs): it keeps
no state besides them. Built with `pythonfmu build --handle-state --serialize-state`
(`build_lag_with` in crates/tutti-test-support/src/fmu.rs), its FMU state, which PythonFMU
makes of the registered variables (JSON, which keeps every float exactly), is all of it, so a
restored Lag continues bit-identically (crates/tutti-fmu/tests/library.rs).
"""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status


class Lag(Fmi2Slave):
    author = "tutti"
    description = "First-order lag and integrator (tutti test model)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.tau = 0.5
        self.gain = 2.0
        self.fail_at = 0.0
        self.raise_at = 0.0
        self.y = 0.0
        self.integral = 0.0
        self.t = 0.0
        self.count = 0
        self.positive = False
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(
            Real("tau", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        )
        self.register_variable(
            Real("gain", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        )
        self.register_variable(
            Real("fail_at", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        )
        self.register_variable(
            Real("raise_at", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        )
        self.register_variable(Real("y", causality=Fmi2Causality.output))
        self.register_variable(Real("integral", causality=Fmi2Causality.output))
        self.register_variable(Real("t", causality=Fmi2Causality.output))
        self.register_variable(
            Integer("count", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete)
        )
        self.register_variable(
            Boolean("positive", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete)
        )

    def do_step(self, current_time, step_size):
        end = current_time + step_size
        if self.fail_at > 0.0 and end >= self.fail_at:
            self.log(f"Lag: refusing to step past fail_at={self.fail_at} (t={end})", status=Fmi2Status.error)
            return False
        if self.raise_at > 0.0 and end >= self.raise_at:
            raise RuntimeError(f"Lag: raise_at={self.raise_at} reached")
        self.y += step_size * (self.gain * self.u - self.y) / self.tau
        self.integral += step_size * self.u
        self.t = end
        self.count += 1
        self.positive = self.y > 0.0
        return True
