//! Trim for straight, wings-level, constant-altitude flight.
//!
//! Unknowns `x = (alpha, elevator, throttle)`; with `theta = alpha` (zero flight-path angle), zero
//! sideslip, zero rates and zero aileron and rudder, the residual is `(u', w', q')` from the full
//! nonlinear [`derivatives`]. It is driven to zero by Newton's method
//! with a central-difference Jacobian (damped so each step changes alpha by at most 0.1 rad). The
//! lateral equations are identically in equilibrium at that point because the Aerosonde has no
//! asymmetric coefficients (`C_Y0 = C_l0 = C_n0 = 0`, `k_Tp = 0`).

use std::fmt;

use crate::dynamics::{derivatives, Controls, Environment, State};
use crate::math::Quat;
use crate::params::{ActuatorParams, AirframeParams};

/// A trimmed flight condition.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trim {
    /// True airspeed, m/s.
    pub airspeed: f64,
    /// Altitude above MSL, m.
    pub altitude_msl: f64,
    /// Angle of attack = pitch angle, rad.
    pub alpha: f64,
    /// Elevator, rad.
    pub elevator: f64,
    /// Throttle, 0..1.
    pub throttle: f64,
    /// Largest residual acceleration at the solution (m/s² or rad/s²).
    pub residual: f64,
}

/// Why no trim was found.
#[derive(Clone, Debug, PartialEq)]
pub enum TrimError {
    /// Newton's method did not converge.
    NoConvergence {
        /// The residual after the last iteration.
        residual: f64,
    },
    /// The solution needs a control beyond its limits or an angle of attack past stall.
    OutOfLimits {
        /// The (unusable) solution.
        trim: Trim,
    },
    /// Airspeed or altitude not finite and positive.
    BadCondition,
}

impl fmt::Display for TrimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TrimError::NoConvergence { residual } => write!(f, "trim did not converge (residual {residual:.3e})"),
            TrimError::OutOfLimits { trim } => write!(
                f,
                "trim at {:.1} m/s needs alpha {:.3} rad, elevator {:.3} rad, throttle {:.3}: outside the limits",
                trim.airspeed, trim.alpha, trim.elevator, trim.throttle
            ),
            TrimError::BadCondition => write!(f, "trim airspeed and altitude must be finite, airspeed positive"),
        }
    }
}

impl std::error::Error for TrimError {}

impl Trim {
    /// The trimmed rigid-body state at NED position `(pn, pe, pd)` heading `psi` (rad).
    pub fn state(&self, pn: f64, pe: f64, pd: f64, psi: f64) -> State {
        State {
            pn,
            pe,
            pd,
            u: self.airspeed * self.alpha.cos(),
            v: 0.0,
            w: self.airspeed * self.alpha.sin(),
            att: Quat::from_euler(0.0, self.alpha, psi),
            p: 0.0,
            q: 0.0,
            r: 0.0,
        }
    }

    /// The trim deflections.
    pub fn controls(&self) -> Controls {
        Controls { elevator: self.elevator, aileron: 0.0, rudder: 0.0, throttle: self.throttle }
    }
}

fn residual(p: &AirframeParams, va: f64, alt: f64, x: [f64; 3]) -> [f64; 3] {
    let env = Environment { wind_ned: [0.0; 3], home_alt_msl: alt };
    let t = Trim { airspeed: va, altitude_msl: alt, alpha: x[0], elevator: x[1], throttle: x[2], residual: 0.0 };
    let d = derivatives(p, &t.state(0.0, 0.0, 0.0, 0.0), &t.controls(), &env);
    [d.u, d.w, d.q]
}

fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if d.abs() < 1e-14 || !d.is_finite() {
        return None;
    }
    let mut x = [0.0; 3];
    for (col, xi) in x.iter_mut().enumerate() {
        let mut m = a;
        for row in 0..3 {
            m[row][col] = b[row];
        }
        *xi = det(m) / d;
    }
    Some(x)
}

/// Trims `params` for straight and level flight at `airspeed` (m/s) and `altitude_msl` (m), and
/// checks the result against the actuator limits and the stall angle.
pub fn trim(
    params: &AirframeParams,
    actuators: &ActuatorParams,
    airspeed: f64,
    altitude_msl: f64,
) -> Result<Trim, TrimError> {
    if !(airspeed.is_finite() && airspeed > 0.0 && altitude_msl.is_finite()) {
        return Err(TrimError::BadCondition);
    }
    let mut x = [0.05, 0.0, 0.5];
    let mut res = residual(params, airspeed, altitude_msl, x);
    let norm = |r: [f64; 3]| r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for _ in 0..50 {
        if norm(res) < 1e-11 {
            break;
        }
        let h = [1e-6, 1e-6, 1e-6];
        let mut jac = [[0.0; 3]; 3];
        for j in 0..3 {
            let mut xp = x;
            let mut xm = x;
            xp[j] += h[j];
            xm[j] -= h[j];
            let rp = residual(params, airspeed, altitude_msl, xp);
            let rm = residual(params, airspeed, altitude_msl, xm);
            for i in 0..3 {
                jac[i][j] = (rp[i] - rm[i]) / (2.0 * h[j]);
            }
        }
        let Some(dx) = solve3(jac, [-res[0], -res[1], -res[2]]) else {
            return Err(TrimError::NoConvergence { residual: norm(res) });
        };
        let damp = (0.1 / dx[0].abs().max(1e-300)).min(1.0);
        for i in 0..3 {
            x[i] += damp * dx[i];
        }
        res = residual(params, airspeed, altitude_msl, x);
    }
    let r = norm(res);
    if r.is_nan() || r >= 1e-8 {
        return Err(TrimError::NoConvergence { residual: r });
    }
    let t = Trim { airspeed, altitude_msl, alpha: x[0], elevator: x[1], throttle: x[2], residual: r };
    let e = &actuators.elevator;
    let th = &actuators.throttle;
    if x[0].abs() >= params.alpha0 || x[1] < e.min || x[1] > e.max || x[2] < th.min || x[2] > th.max {
        return Err(TrimError::OutOfLimits { trim: t });
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aerosonde_trims_at_25_mps() {
        let p = AirframeParams::aerosonde();
        let t = trim(&p, &ActuatorParams::default(), 25.0, 300.0).unwrap();
        assert!(t.residual < 1e-10, "{t:?}");
        assert!(t.alpha > 0.0 && t.alpha < 0.2, "{t:?}");
        assert!(t.elevator < 0.0 && t.throttle > 0.1 && t.throttle < 0.9, "{t:?}");
    }

    #[test]
    fn too_slow_or_bad_input_is_an_error() {
        let p = AirframeParams::aerosonde();
        assert!(trim(&p, &ActuatorParams::default(), 8.0, 300.0).is_err());
        assert_eq!(trim(&p, &ActuatorParams::default(), f64::NAN, 300.0), Err(TrimError::BadCondition));
    }
}
