//! Forces, moments and the quaternion 6-DOF equations of motion, integrated with RK4.
//!
//! Notation and equations follow Beard & McLain (2012): gravity, aerodynamics and the simple
//! propeller model of chapter 4 (sections 4.1–4.3, including the sigmoid stall blending of the lift
//! coefficient and the parabolic drag polar of the nonlinear model), and the rigid-body equations of
//! chapter 3 (section 3.3, with the `Gamma` inertia terms) written with the attitude quaternion of
//! appendix B.

use crate::math::{Quat, Vec3};
use crate::params::AirframeParams;

/// The 13 rigid-body states.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    /// North position relative to home, m.
    pub pn: f64,
    /// East position relative to home, m.
    pub pe: f64,
    /// Down position relative to home, m (altitude above home is `-pd`).
    pub pd: f64,
    /// Body-x velocity (inertial, expressed in body axes), m/s.
    pub u: f64,
    /// Body-y velocity, m/s.
    pub v: f64,
    /// Body-z velocity, m/s.
    pub w: f64,
    /// Attitude (body to NED).
    pub att: Quat,
    /// Roll rate, rad/s.
    pub p: f64,
    /// Pitch rate, rad/s.
    pub q: f64,
    /// Yaw rate, rad/s.
    pub r: f64,
}

impl State {
    fn to_array(self) -> [f64; 13] {
        let a = self.att;
        [self.pn, self.pe, self.pd, self.u, self.v, self.w, a.e0, a.e1, a.e2, a.e3, self.p, self.q, self.r]
    }

    fn from_array(x: [f64; 13]) -> State {
        State {
            pn: x[0],
            pe: x[1],
            pd: x[2],
            u: x[3],
            v: x[4],
            w: x[5],
            att: Quat { e0: x[6], e1: x[7], e2: x[8], e3: x[9] },
            p: x[10],
            q: x[11],
            r: x[12],
        }
    }

    /// Ground velocity in NED, m/s.
    pub fn velocity_ned(&self) -> Vec3 {
        self.att.rotate_to_ned([self.u, self.v, self.w])
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.to_array().iter().all(|x| x.is_finite())
    }
}

/// Control-surface deflections (rad) and throttle (0..1) as seen by the airframe.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Controls {
    /// Elevator, rad; positive is trailing edge down (nose-down moment).
    pub elevator: f64,
    /// Aileron, rad; positive rolls right.
    pub aileron: f64,
    /// Rudder, rad; positive yaws left.
    pub rudder: f64,
    /// Throttle, 0..1.
    pub throttle: f64,
}

/// The environment the airframe flies in.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Environment {
    /// Steady wind in NED, m/s (the direction the air moves *to*).
    pub wind_ned: Vec3,
    /// Altitude of the NED origin (home) above MSL, m; used for the air density.
    pub home_alt_msl: f64,
}

/// Airspeed, angle of attack and sideslip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AirData {
    /// True airspeed, m/s.
    pub va: f64,
    /// Angle of attack, rad.
    pub alpha: f64,
    /// Sideslip, rad.
    pub beta: f64,
}

/// Body-frame force (N) and moment (N·m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForcesMoments {
    /// `(fx, fy, fz)`, N.
    pub force: Vec3,
    /// `(l, m, n)`, N·m.
    pub moment: Vec3,
}

/// Air-relative quantities for `state` in `env`.
pub fn air_data(state: &State, env: &Environment) -> AirData {
    let wind_body = state.att.rotate_to_body(env.wind_ned);
    let ur = state.u - wind_body[0];
    let vr = state.v - wind_body[1];
    let wr = state.w - wind_body[2];
    let va = (ur * ur + vr * vr + wr * wr).sqrt();
    if va < 1e-6 {
        return AirData { va, alpha: 0.0, beta: 0.0 };
    }
    AirData { va, alpha: wr.atan2(ur), beta: (vr / va).clamp(-1.0, 1.0).asin() }
}

/// Lift coefficient with the book's sigmoid blending to flat-plate lift past stall.
pub fn lift_coefficient(p: &AirframeParams, alpha: f64) -> f64 {
    let a = (-p.m_blend * (alpha - p.alpha0)).exp();
    let b = (p.m_blend * (alpha + p.alpha0)).exp();
    let sigma = if b.is_finite() && a.is_finite() { (1.0 + a + b) / ((1.0 + a) * (1.0 + b)) } else { 1.0 };
    let linear = p.cl0 + p.cl_alpha * alpha;
    let flat_plate = 2.0 * alpha.signum() * alpha.sin() * alpha.sin() * alpha.cos();
    (1.0 - sigma) * linear + sigma * flat_plate
}

/// Drag coefficient: parasitic drag plus induced drag of the linear lift.
pub fn drag_coefficient(p: &AirframeParams, alpha: f64) -> f64 {
    let cl = p.cl0 + p.cl_alpha * alpha;
    p.cd_p + cl * cl / (std::f64::consts::PI * p.e * p.aspect_ratio())
}

/// Gravity, aerodynamic and propulsion forces and moments in body axes.
pub fn forces_moments(p: &AirframeParams, state: &State, controls: &Controls, env: &Environment) -> ForcesMoments {
    let ad = air_data(state, env);
    let Quat { e0, e1, e2, e3 } = state.att;
    let mg = p.mass * p.g;
    let gravity =
        [mg * 2.0 * (e1 * e3 - e2 * e0), mg * 2.0 * (e2 * e3 + e1 * e0), mg * (e3 * e3 + e0 * e0 - e1 * e1 - e2 * e2)];

    let rho = p.atmosphere.density(env.home_alt_msl - state.pd);
    let qbar_s = 0.5 * rho * ad.va * ad.va * p.s;
    // Rate terms are divided by 2 Va; guard against a stopped aircraft.
    let inv_2va = 1.0 / (2.0 * ad.va.max(1.0));
    let (sa, ca) = ad.alpha.sin_cos();
    let cl = lift_coefficient(p, ad.alpha);
    let cd = drag_coefficient(p, ad.alpha);
    let cx = -cd * ca + cl * sa;
    let cx_q = -p.cd_q * ca + p.cl_q * sa;
    let cx_de = -p.cd_de * ca + p.cl_de * sa;
    let cz = -cd * sa - cl * ca;
    let cz_q = -p.cd_q * sa - p.cl_q * ca;
    let cz_de = -p.cd_de * sa - p.cl_de * ca;
    let (de, da, dr, dt) = (controls.elevator, controls.aileron, controls.rudder, controls.throttle);
    let (beta, pr, qr, rr) = (ad.beta, state.p, state.q, state.r);

    let thrust = 0.5 * rho * p.s_prop * p.c_prop * ((p.k_motor * dt).powi(2) - ad.va * ad.va);
    let fx = gravity[0] + qbar_s * (cx + cx_q * p.c * qr * inv_2va + cx_de * de) + thrust;
    let fy = gravity[1]
        + qbar_s
            * (p.cy0
                + p.cy_beta * beta
                + p.cy_p * p.b * pr * inv_2va
                + p.cy_r * p.b * rr * inv_2va
                + p.cy_da * da
                + p.cy_dr * dr);
    let fz = gravity[2] + qbar_s * (cz + cz_q * p.c * qr * inv_2va + cz_de * de);

    let l = qbar_s
        * p.b
        * (p.cl_0
            + p.cl_beta * beta
            + p.cl_p * p.b * pr * inv_2va
            + p.cl_r * p.b * rr * inv_2va
            + p.cl_da * da
            + p.cl_dr * dr)
        - p.k_tp * (p.k_omega * dt).powi(2);
    let m = qbar_s * p.c * (p.cm0 + p.cm_alpha * ad.alpha + p.cm_q * p.c * qr * inv_2va + p.cm_de * de);
    let n = qbar_s
        * p.b
        * (p.cn0
            + p.cn_beta * beta
            + p.cn_p * p.b * pr * inv_2va
            + p.cn_r * p.b * rr * inv_2va
            + p.cn_da * da
            + p.cn_dr * dr);
    ForcesMoments { force: [fx, fy, fz], moment: [l, m, n] }
}

/// Time derivative of the state (returned in a [`State`] used as a plain 13-vector).
pub fn derivatives(p: &AirframeParams, state: &State, controls: &Controls, env: &Environment) -> State {
    let fm = forces_moments(p, state, controls, env);
    let [fx, fy, fz] = fm.force;
    let [l, m, n] = fm.moment;
    let (u, v, w) = (state.u, state.v, state.w);
    let (pr, qr, rr) = (state.p, state.q, state.r);
    let vel = state.att.rotate_to_ned([u, v, w]);

    let Quat { e0, e1, e2, e3 } = state.att;
    let att = Quat {
        e0: 0.5 * (-pr * e1 - qr * e2 - rr * e3),
        e1: 0.5 * (pr * e0 + rr * e2 - qr * e3),
        e2: 0.5 * (qr * e0 - rr * e1 + pr * e3),
        e3: 0.5 * (rr * e0 + qr * e1 - pr * e2),
    };

    let gamma = p.jx * p.jz - p.jxz * p.jxz;
    let g1 = p.jxz * (p.jx - p.jy + p.jz) / gamma;
    let g2 = (p.jz * (p.jz - p.jy) + p.jxz * p.jxz) / gamma;
    let g3 = p.jz / gamma;
    let g4 = p.jxz / gamma;
    let g5 = (p.jz - p.jx) / p.jy;
    let g6 = p.jxz / p.jy;
    let g7 = ((p.jx - p.jy) * p.jx + p.jxz * p.jxz) / gamma;
    let g8 = p.jx / gamma;

    State {
        pn: vel[0],
        pe: vel[1],
        pd: vel[2],
        u: rr * v - qr * w + fx / p.mass,
        v: pr * w - rr * u + fy / p.mass,
        w: qr * u - pr * v + fz / p.mass,
        att,
        p: g1 * pr * qr - g2 * qr * rr + g3 * l + g4 * n,
        q: g5 * pr * rr - g6 * (pr * pr - rr * rr) + m / p.jy,
        r: g7 * pr * qr - g1 * qr * rr + g4 * l + g8 * n,
    }
}

fn axpy(x: [f64; 13], k: f64, d: [f64; 13]) -> [f64; 13] {
    std::array::from_fn(|i| x[i] + k * d[i])
}

/// One classical fourth-order Runge–Kutta step of `dt` seconds with the controls held constant
/// (zero-order hold); the quaternion is re-normalised at the end of the step.
pub fn rk4_step(p: &AirframeParams, state: &State, controls: &Controls, env: &Environment, dt: f64) -> State {
    let f = |x: [f64; 13]| derivatives(p, &State::from_array(x), controls, env).to_array();
    let x0 = state.to_array();
    let k1 = f(x0);
    let k2 = f(axpy(x0, dt / 2.0, k1));
    let k3 = f(axpy(x0, dt / 2.0, k2));
    let k4 = f(axpy(x0, dt, k3));
    let x1: [f64; 13] = std::array::from_fn(|i| x0[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
    let mut next = State::from_array(x1);
    next.att = next.att.normalised();
    next
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lift_blends_to_flat_plate() {
        let p = AirframeParams::aerosonde();
        assert!((lift_coefficient(&p, 0.0) - p.cl0).abs() < 1e-6);
        assert!((lift_coefficient(&p, 0.1) - (p.cl0 + p.cl_alpha * 0.1)).abs() < 1e-6);
        let a: f64 = 1.0;
        let fp = 2.0 * a.sin() * a.sin() * a.cos();
        assert!((lift_coefficient(&p, a) - fp).abs() < 1e-6);
        assert!(lift_coefficient(&p, 40.0).is_finite() && lift_coefficient(&p, -40.0).is_finite());
    }

    #[test]
    fn free_fall_without_air() {
        let mut p = AirframeParams::aerosonde();
        p.atmosphere = crate::params::Atmosphere::Constant(0.0);
        let s =
            State { pn: 0.0, pe: 0.0, pd: 0.0, u: 0.0, v: 0.0, w: 0.0, att: Quat::IDENTITY, p: 0.0, q: 0.0, r: 0.0 };
        let env = Environment::default();
        let mut x = s;
        for _ in 0..100 {
            x = rk4_step(&p, &x, &Controls::default(), &env, 0.01);
        }
        // One second of free fall: 4.905 m, 9.81 m/s.
        assert!((x.pd - 4.905).abs() < 1e-9, "{}", x.pd);
        assert!((x.w - 9.81).abs() < 1e-9);
    }
}
