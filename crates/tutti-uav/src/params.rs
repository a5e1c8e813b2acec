//! Airframe, propulsion and actuator parameters.
//!
//! The default airframe is the Aerosonde UAV exactly as tabulated in R. W. Beard and T. W. McLain,
//! *Small Unmanned Aircraft: Theory and Practice*, Princeton University Press, 2012 (first edition),
//! appendix E ("Airframe Parameters"), table E.2 (Aerosonde UAV): mass 13.5 kg, the inertias, the
//! geometry, the longitudinal and lateral stability and control derivatives, the stall-blending
//! constants `M = 50`, `alpha0 = 0.4712` and the simple propeller model constants
//! (`S_prop = 0.2027`, `k_motor = 80`, `C_prop = 1`, `k_Tp = k_Omega = 0`). The book's later
//! online supplement (an 11 kg Aerosonde with an electric-motor model) is *not* used.

/// How air density is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Atmosphere {
    /// A constant density in kg/m³ (the book uses 1.2682 everywhere).
    Constant(f64),
    /// The International Standard Atmosphere troposphere, as a function of altitude above MSL.
    Isa,
}

impl Atmosphere {
    /// Air density (kg/m³) at `altitude_msl` metres.
    pub fn density(&self, altitude_msl: f64) -> f64 {
        match *self {
            Atmosphere::Constant(rho) => rho,
            Atmosphere::Isa => {
                let h = altitude_msl.clamp(-500.0, 11_000.0);
                let t = 288.15 - 0.0065 * h;
                1.225 * (t / 288.15).powf(4.255_876)
            }
        }
    }
}

/// Aerodynamic, mass and propulsion parameters of a fixed-wing aircraft (Beard & McLain notation).
#[derive(Clone, Debug, PartialEq)]
pub struct AirframeParams {
    /// Mass, kg.
    pub mass: f64,
    /// Roll inertia, kg·m².
    pub jx: f64,
    /// Pitch inertia, kg·m².
    pub jy: f64,
    /// Yaw inertia, kg·m².
    pub jz: f64,
    /// Roll-yaw product of inertia, kg·m².
    pub jxz: f64,
    /// Wing area, m².
    pub s: f64,
    /// Wing span, m.
    pub b: f64,
    /// Mean aerodynamic chord, m.
    pub c: f64,
    /// Gravity, m/s².
    pub g: f64,
    /// Air density model.
    pub atmosphere: Atmosphere,
    /// Oswald efficiency factor.
    pub e: f64,
    /// Stall blending transition rate.
    pub m_blend: f64,
    /// Stall blending cut-off angle of attack, rad.
    pub alpha0: f64,
    /// Lift coefficient at zero angle of attack.
    pub cl0: f64,
    /// Lift-curve slope, 1/rad.
    pub cl_alpha: f64,
    /// Lift due to pitch rate.
    pub cl_q: f64,
    /// Lift due to elevator, 1/rad.
    pub cl_de: f64,
    /// Parasitic drag coefficient (used by the nonlinear drag polar).
    pub cd_p: f64,
    /// Drag due to pitch rate.
    pub cd_q: f64,
    /// Drag due to elevator.
    pub cd_de: f64,
    /// Pitching moment at zero angle of attack.
    pub cm0: f64,
    /// Pitching moment slope.
    pub cm_alpha: f64,
    /// Pitch damping.
    pub cm_q: f64,
    /// Elevator effectiveness (positive elevator = trailing edge down = nose down).
    pub cm_de: f64,
    /// Side force at zero sideslip.
    pub cy0: f64,
    /// Side force due to sideslip.
    pub cy_beta: f64,
    /// Side force due to roll rate.
    pub cy_p: f64,
    /// Side force due to yaw rate.
    pub cy_r: f64,
    /// Side force due to aileron.
    pub cy_da: f64,
    /// Side force due to rudder.
    pub cy_dr: f64,
    /// Rolling moment at zero sideslip.
    pub cl_0: f64,
    /// Dihedral effect.
    pub cl_beta: f64,
    /// Roll damping.
    pub cl_p: f64,
    /// Roll due to yaw rate.
    pub cl_r: f64,
    /// Aileron effectiveness (positive aileron = right wing down).
    pub cl_da: f64,
    /// Roll due to rudder.
    pub cl_dr: f64,
    /// Yawing moment at zero sideslip.
    pub cn0: f64,
    /// Weathercock stability.
    pub cn_beta: f64,
    /// Yaw due to roll rate.
    pub cn_p: f64,
    /// Yaw damping.
    pub cn_r: f64,
    /// Adverse yaw due to aileron.
    pub cn_da: f64,
    /// Rudder effectiveness.
    pub cn_dr: f64,
    /// Propeller disc area, m².
    pub s_prop: f64,
    /// Propeller thrust coefficient.
    pub c_prop: f64,
    /// Motor constant: exit air speed per unit throttle, m/s.
    pub k_motor: f64,
    /// Propeller torque constant.
    pub k_tp: f64,
    /// Propeller speed constant.
    pub k_omega: f64,
}

impl AirframeParams {
    /// The Aerosonde UAV of Beard & McLain (2012), appendix E, table E.2, with an ISA atmosphere
    /// (the book's constant `rho = 1.2682` is available as [`Atmosphere::Constant`]).
    pub fn aerosonde() -> AirframeParams {
        AirframeParams {
            mass: 13.5,
            jx: 0.8244,
            jy: 1.135,
            jz: 1.759,
            jxz: 0.1204,
            s: 0.55,
            b: 2.8956,
            c: 0.18994,
            g: 9.81,
            atmosphere: Atmosphere::Isa,
            e: 0.9,
            m_blend: 50.0,
            alpha0: 0.4712,
            cl0: 0.28,
            cl_alpha: 3.45,
            cl_q: 0.0,
            cl_de: -0.36,
            cd_p: 0.0437,
            cd_q: 0.0,
            cd_de: 0.0,
            cm0: -0.02338,
            cm_alpha: -0.38,
            cm_q: -3.6,
            cm_de: -0.5,
            cy0: 0.0,
            cy_beta: -0.98,
            cy_p: 0.0,
            cy_r: 0.0,
            cy_da: 0.0,
            cy_dr: -0.17,
            cl_0: 0.0,
            cl_beta: -0.12,
            cl_p: -0.26,
            cl_r: 0.14,
            cl_da: 0.08,
            cl_dr: 0.105,
            cn0: 0.0,
            cn_beta: 0.25,
            cn_p: 0.022,
            cn_r: -0.35,
            cn_da: 0.06,
            cn_dr: -0.032,
            s_prop: 0.2027,
            c_prop: 1.0,
            k_motor: 80.0,
            k_tp: 0.0,
            k_omega: 0.0,
        }
    }

    /// Wing aspect ratio `b² / S`.
    pub fn aspect_ratio(&self) -> f64 {
        self.b * self.b / self.s
    }
}

impl Default for AirframeParams {
    fn default() -> Self {
        AirframeParams::aerosonde()
    }
}

/// One first-order actuator: `x' = (cmd - x) / tau`, with a rate limit and position limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActuatorLimits {
    /// Time constant, s.
    pub tau: f64,
    /// Maximum rate, units per second.
    pub rate_max: f64,
    /// Lower position limit.
    pub min: f64,
    /// Upper position limit.
    pub max: f64,
}

/// The four actuators of the "simple controls" subsystem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActuatorParams {
    /// Elevator, rad.
    pub elevator: ActuatorLimits,
    /// Aileron, rad.
    pub aileron: ActuatorLimits,
    /// Rudder, rad.
    pub rudder: ActuatorLimits,
    /// Throttle, 0..1; its time constant stands for the engine's power lag.
    pub throttle: ActuatorLimits,
}

impl Default for ActuatorParams {
    /// Servos: 50 ms, 120 °/s, ±25°. Engine/throttle: 0.3 s lag, full range in 0.5 s, 0..1.
    fn default() -> Self {
        let surface = ActuatorLimits { tau: 0.05, rate_max: 120f64.to_radians(), min: -0.4363, max: 0.4363 };
        ActuatorParams {
            elevator: surface,
            aileron: surface,
            rudder: surface,
            throttle: ActuatorLimits { tau: 0.3, rate_max: 2.0, min: 0.0, max: 1.0 },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isa_density() {
        assert!((Atmosphere::Isa.density(0.0) - 1.225).abs() < 1e-9);
        let rho300 = Atmosphere::Isa.density(300.0);
        assert!((rho300 - 1.1901).abs() < 1e-3, "{rho300}");
        assert_eq!(Atmosphere::Constant(1.2682).density(1234.0), 1.2682);
    }
}
