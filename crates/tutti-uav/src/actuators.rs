//! First-order actuator dynamics with rate and position limits ("simple controls" subsystem).

use crate::dynamics::Controls;
use crate::params::{ActuatorLimits, ActuatorParams};

/// Advances one actuator by `dt`: exact first-order response to the (position-limited) command
/// over the step, then the rate limit, then the position limit.
pub fn actuator_step(lim: &ActuatorLimits, position: f64, command: f64, dt: f64) -> f64 {
    let target = if command.is_finite() { command.clamp(lim.min, lim.max) } else { position };
    let alpha = if lim.tau > 0.0 { 1.0 - (-dt / lim.tau).exp() } else { 1.0 };
    let max_step = lim.rate_max * dt;
    let step = ((target - position) * alpha).clamp(-max_step, max_step);
    (position + step).clamp(lim.min, lim.max)
}

/// The actuator states (the deflections the airframe actually sees).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Actuators {
    /// Limits and time constants.
    pub params: ActuatorParams,
    /// Current positions.
    pub position: Controls,
}

impl Actuators {
    /// Actuators at rest at `position` (e.g. the trim deflections).
    pub fn new(params: ActuatorParams, position: Controls) -> Actuators {
        Actuators { params, position }
    }

    /// Moves every actuator toward `command` for `dt` seconds.
    pub fn step(&mut self, command: &Controls, dt: f64) {
        let p = &self.params;
        let x = &mut self.position;
        x.elevator = actuator_step(&p.elevator, x.elevator, command.elevator, dt);
        x.aileron = actuator_step(&p.aileron, x.aileron, command.aileron, dt);
        x.rudder = actuator_step(&p.rudder, x.rudder, command.rudder, dt);
        x.throttle = actuator_step(&p.throttle, x.throttle, command.throttle, dt);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_order_rate_and_position_limits() {
        let lim = ActuatorLimits { tau: 0.1, rate_max: 1.0, min: -0.5, max: 0.5 };
        // Small step: first-order response, 63 % after one time constant.
        let mut x = 0.0;
        for _ in 0..10 {
            x = actuator_step(&lim, x, 0.05, 0.01);
        }
        assert!((x - 0.05 * (1.0 - (-1.0f64).exp())).abs() < 1e-12);
        // Large step: rate limited to 1 rad/s, then position limited.
        let x1 = actuator_step(&lim, 0.0, 10.0, 0.01);
        assert!((x1 - 0.01).abs() < 1e-12);
        let mut y = 0.0;
        for _ in 0..200 {
            y = actuator_step(&lim, y, 10.0, 0.01);
        }
        assert!(y <= 0.5 && y > 0.5 - 1e-6, "{y}");
        assert_eq!(actuator_step(&lim, 0.5, 10.0, 0.01), 0.5);
        assert_eq!(actuator_step(&lim, 0.2, f64::NAN, 0.01), 0.2);
    }
}
