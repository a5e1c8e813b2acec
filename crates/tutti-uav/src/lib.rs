//! # tutti-uav: the UAV model of the multi-UAV co-simulation demo
//!
//! A deterministic, allocation-light, I/O-free fixed-wing UAV in the spirit of the Pioneer UAV
//! model (AeroLib) of the RT-LAB Orchestra paper's case study: aerodynamics, a propeller with an
//! engine lag, quaternion 6-DOF equations of motion, first-order actuators, an autopilot with
//! waypoint guidance, a trim solver, flat-earth geodesy and a four-UAV formation scenario.
//!
//! **Coefficient source.** The airframe is the Aerosonde UAV as tabulated in R. W. Beard and
//! T. W. McLain, *Small Unmanned Aircraft: Theory and Practice*, Princeton University Press, 2012
//! (first edition), appendix E, table E.2 — see [`params::AirframeParams::aerosonde`]. The
//! aerodynamic model (stall blending with `M = 50`, `alpha0 = 0.4712`, parabolic drag polar) and
//! the simple propeller model are those of chapter 4 of the same book.
//!
//! **Propulsion.** Thrust is the book's simple propeller model
//! `T = ½ ρ S_prop C_prop ((k_motor δt)² − Va²)`; the piston engine's power lag is modelled by the
//! first-order throttle actuator (0.3 s time constant, rate limited), see
//! [`params::ActuatorParams`].
//!
//! **Integration.** Each [`Uav::step`] runs the autopilot on the current state, moves the
//! actuators (exact first-order response, then rate and position limits), then advances the 13
//! rigid-body states with one classical RK4 step holding the deflections constant, and
//! re-normalises the attitude quaternion. The recommended step is 0.01 s.
//!
//! See `docs/uav-model.md` for the equations, gains and limitations.
//!
//! ```
//! let formation = tutti_uav::scenario::default_formation();
//! let mut uavs = formation.build_all().unwrap();
//! for _ in 0..100 {
//!     for uav in &mut uavs {
//!         uav.step(0.01);
//!     }
//! }
//! let out = uavs[0].outputs();
//! assert!((out.time - 1.0).abs() < 1e-9 && (out.lat_deg - 45.5).abs() < 0.01);
//! ```

pub mod actuators;
pub mod autopilot;
pub mod dynamics;
pub mod formation;
pub mod geodesy;
pub mod math;
pub mod params;
pub mod scenario;
pub mod trim;

pub use autopilot::{Autopilot, AutopilotGains, Mode};
pub use dynamics::{Controls, Environment, State};
pub use formation::{offset_route, FormationOffset, RouteError, Waypoint};
pub use geodesy::GeoPoint;
pub use params::{ActuatorParams, AirframeParams, Atmosphere};
pub use trim::{trim, Trim, TrimError};

use actuators::Actuators;
use autopilot::Nav;
use math::{wrap_360, Vec3};

/// The recommended integration step, s.
pub const DEFAULT_DT: f64 = 0.01;

/// Where and how a [`Uav`] starts: a trimmed flight condition placed in space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InitialCondition {
    /// The trim (airspeed, altitude, alpha, elevator, throttle).
    pub trim: Trim,
    /// North of home, m.
    pub north_m: f64,
    /// East of home, m.
    pub east_m: f64,
    /// Heading, rad from north.
    pub heading_rad: f64,
}

impl InitialCondition {
    /// Straight and level at the trim's altitude, `north_m`/`east_m` from home, heading
    /// `heading_rad`.
    pub fn from_trim(trim: Trim, north_m: f64, east_m: f64, heading_rad: f64) -> InitialCondition {
        InitialCondition { trim, north_m, east_m, heading_rad }
    }
}

/// What a UAV publishes (the SUBSCRIBE items of `ddf/multiuav.ddf`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outputs {
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Elevation above MSL, m.
    pub elevation_m: f64,
    /// True airspeed, m/s.
    pub airspeed: f64,
    /// Heading (yaw), degrees from north in `[0, 360)`.
    pub heading_deg: f64,
    /// Simulated time, s.
    pub time: f64,
}

/// The formation commands a UAV receives (the PUBLISH items of `ddf/multiuav.ddf`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FormationCommand {
    /// `true`: fly the formation route; `false`: hold heading and altitude.
    pub autopilot: bool,
    /// Formation slot in the leader's path frame (DDF `X` = along, `Y` = cross, `Z` = up).
    pub offset: FormationOffset,
    /// Commanded airspeed, m/s; `None` flies the route's airspeeds.
    pub airspeed: Option<f64>,
}

impl FormationCommand {
    /// From the DDF items as doubles: `autopilot >= 0.5` is on; `X`, `Y`, `Z` are the along-track,
    /// cross-track (right positive) and up offsets in metres; an airspeed that is not finite and
    /// positive means "use the route's airspeeds".
    pub fn from_ddf(autopilot: f64, x: f64, y: f64, z: f64, airspeed: f64) -> FormationCommand {
        let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
        FormationCommand {
            autopilot: autopilot >= 0.5,
            offset: FormationOffset::new(finite(x), finite(y), finite(z)),
            airspeed: (airspeed.is_finite() && airspeed > 0.0).then_some(airspeed),
        }
    }
}

/// One UAV: airframe, actuators, autopilot and state.
#[derive(Clone, Debug)]
pub struct Uav {
    params: AirframeParams,
    home: GeoPoint,
    env: Environment,
    state: State,
    actuators: Actuators,
    autopilot: Autopilot,
    time: f64,
}

impl Uav {
    /// A UAV at `init` (trimmed, straight and level) with default actuators and autopilot gains;
    /// the autopilot starts in [`Mode::Hold`] with no route.
    pub fn new(params: AirframeParams, home: GeoPoint, init: InitialCondition) -> Uav {
        Self::with_parts(params, ActuatorParams::default(), AutopilotGains::default(), home, init)
    }

    /// [`Uav::new`] with explicit actuator parameters and autopilot gains.
    pub fn with_parts(
        params: AirframeParams,
        actuator_params: ActuatorParams,
        gains: AutopilotGains,
        home: GeoPoint,
        init: InitialCondition,
    ) -> Uav {
        let t = init.trim;
        let state = t.state(init.north_m, init.east_m, home.alt_m - t.altitude_msl, init.heading_rad);
        let env = Environment { wind_ned: [0.0; 3], home_alt_msl: home.alt_m };
        Uav {
            autopilot: Autopilot::new(gains, t, &params),
            actuators: Actuators::new(actuator_params, t.controls()),
            params,
            home,
            env,
            state,
            time: 0.0,
        }
    }

    /// Advances the UAV by `dt` seconds: autopilot, actuators, then one RK4 step.
    pub fn step(&mut self, dt: f64) {
        let nav = Nav::measure(&self.state, &self.env);
        let command = self.autopilot.update(&nav, dt);
        self.actuators.step(&command, dt);
        self.state = dynamics::rk4_step(&self.params, &self.state, &self.actuators.position, &self.env, dt);
        self.time += dt;
    }

    /// The published outputs.
    pub fn outputs(&self) -> Outputs {
        let geo = geodesy::ned_to_geo(&self.home, [self.state.pn, self.state.pe, self.state.pd]);
        let (_, _, psi) = self.state.att.to_euler();
        Outputs {
            lat_deg: geo.lat_deg,
            lon_deg: geo.lon_deg,
            elevation_m: geo.alt_m,
            airspeed: dynamics::air_data(&self.state, &self.env).va,
            heading_deg: wrap_360(psi.to_degrees()),
            time: self.time,
        }
    }

    /// Applies the formation commands (cheap when nothing changed: call it every step).
    pub fn apply_command(&mut self, cmd: &FormationCommand) {
        self.autopilot.set_formation_offset(cmd.offset);
        self.autopilot.set_airspeed_command(cmd.airspeed);
        self.autopilot.set_enabled(cmd.autopilot);
    }

    /// Sets the leader's closed route (the UAV flies it moved by its formation offset).
    pub fn set_route(&mut self, route: &[Waypoint]) -> Result<(), RouteError> {
        self.autopilot.set_route(&self.home, route)
    }

    /// The autopilot.
    pub fn autopilot(&self) -> &Autopilot {
        &self.autopilot
    }

    /// The autopilot, mutably (mode, offsets, airspeed command).
    pub fn autopilot_mut(&mut self) -> &mut Autopilot {
        &mut self.autopilot
    }

    /// Sets a steady wind, NED m/s (zero by default).
    pub fn set_wind(&mut self, wind_ned: Vec3) {
        self.env.wind_ned = wind_ned;
    }

    /// The rigid-body state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The actuator positions.
    pub fn controls(&self) -> Controls {
        self.actuators.position
    }

    /// The home point (NED origin).
    pub fn home(&self) -> GeoPoint {
        self.home
    }

    /// The airframe parameters.
    pub fn params(&self) -> &AirframeParams {
        &self.params
    }

    /// Altitude above MSL, m.
    pub fn altitude_msl(&self) -> f64 {
        self.home.alt_m - self.state.pd
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.time
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trimmed_uav(mode: Mode) -> Uav {
        let params = AirframeParams::aerosonde();
        let home = GeoPoint::new(45.5, -73.6, 36.0);
        let t = trim(&params, &ActuatorParams::default(), 25.0, 300.0).unwrap();
        let mut uav = Uav::new(params, home, InitialCondition::from_trim(t, 0.0, 0.0, 30f64.to_radians()));
        uav.autopilot_mut().set_mode(mode);
        uav
    }

    fn run(uav: &mut Uav, seconds: f64, mut each: impl FnMut(&Uav)) {
        let steps = (seconds / DEFAULT_DT).round() as usize;
        for _ in 0..steps {
            uav.step(DEFAULT_DT);
            each(uav);
        }
    }

    /// The issue's criterion, tested in its strictest form: open loop (autopilot in manual mode,
    /// deflections frozen at trim), the trim must hold level flight within 1 m for 60 s.
    #[test]
    fn open_loop_trim_holds_level_flight_for_60_s() {
        let mut uav = trimmed_uav(Mode::Manual);
        let h0 = uav.altitude_msl();
        let mut worst = 0.0f64;
        run(&mut uav, 60.0, |u| worst = worst.max((u.altitude_msl() - h0).abs()));
        let out = uav.outputs();
        assert!(worst < 1.0, "altitude drift {worst} m");
        assert!((out.airspeed - 25.0).abs() < 0.01, "{out:?}");
        assert!((out.heading_deg - 30.0).abs() < 0.01, "{out:?}");
        assert!((out.time - 60.0).abs() < 1e-9);
        // 60 s at 25 m/s heading 030: 1299 m north, 750 m east.
        assert!((uav.state().pn - 1299.04).abs() < 1.0 && (uav.state().pe - 750.0).abs() < 1.0, "{:?}", uav.state());
    }

    /// Open loop, a 2 m/s airspeed disturbance excites the phugoid: the Aerosonde model is
    /// dynamically stable (the oscillation decays) but lightly damped, so it does not hold altitude.
    #[test]
    fn open_loop_phugoid_is_stable() {
        let mut uav = trimmed_uav(Mode::Manual);
        uav.state.u += 2.0;
        let mut first = 0.0f64;
        let mut last = 0.0f64;
        let h0 = uav.altitude_msl();
        let mut t = 0.0;
        run(&mut uav, 240.0, |u| {
            t += DEFAULT_DT;
            let dh = (u.altitude_msl() - h0).abs();
            if t < 60.0 {
                first = first.max(dh);
            } else if t > 180.0 {
                last = last.max((u.outputs().airspeed - 25.0).abs());
            }
        });
        assert!(first > 1.0, "the disturbance should move the aircraft ({first} m)");
        assert!(last < 1.0, "phugoid not decaying: airspeed error {last} m/s after 180 s");
    }

    /// With the autopilot's hold loops engaged (no waypoints) a disturbed aircraft returns to
    /// the captured altitude and heading.
    #[test]
    fn hold_mode_recovers_altitude_and_heading() {
        let mut uav = trimmed_uav(Mode::Hold);
        let h0 = uav.altitude_msl();
        uav.step(DEFAULT_DT);
        uav.state.u += 2.0;
        uav.state.p += 0.3;
        let mut late = 0.0f64;
        let mut t = 0.0;
        run(&mut uav, 60.0, |u| {
            t += DEFAULT_DT;
            if t > 40.0 {
                late = late.max((u.altitude_msl() - h0).abs());
            }
        });
        assert!(late < 1.0, "altitude error {late} m after 40 s");
        assert!((uav.outputs().heading_deg - 30.0).abs() < 1.0, "{:?}", uav.outputs());
        assert!((uav.outputs().airspeed - 25.0).abs() < 0.2, "{:?}", uav.outputs());
    }

    #[test]
    fn ddf_commands_map_to_the_autopilot() {
        let mut uav = scenario::default_formation().build_uav(1).unwrap();
        let cmd = FormationCommand::from_ddf(1.0, -60.0, -60.0, 20.0, 0.0);
        assert_eq!(cmd.airspeed, None);
        uav.apply_command(&cmd);
        assert!(uav.autopilot().is_enabled());
        assert_eq!(uav.autopilot().formation_offset(), FormationOffset::new(-60.0, -60.0, 20.0));
        uav.apply_command(&FormationCommand::from_ddf(0.0, -30.0, 10.0, f64::NAN, 27.0));
        assert_eq!(uav.autopilot().mode(), Mode::Hold);
        assert_eq!(uav.autopilot().airspeed_command(), Some(27.0));
        assert_eq!(uav.autopilot().formation_offset(), FormationOffset::new(-30.0, 10.0, 0.0));
        // Holding: after 20 s the UAV flies the commanded airspeed at its captured altitude.
        let h0 = uav.altitude_msl();
        run(&mut uav, 30.0, |_| {});
        assert!((uav.outputs().airspeed - 27.0).abs() < 0.3, "{:?}", uav.outputs());
        assert!((uav.altitude_msl() - h0).abs() < 3.0, "{} vs {h0}", uav.altitude_msl());
        assert!(uav.outputs().heading_deg < 1.0 || uav.outputs().heading_deg > 359.0, "{:?}", uav.outputs());
    }
}
