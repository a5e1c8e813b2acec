//! Waypoint guidance, formation station keeping and the PID autopilot.
//!
//! Structure (successive loop closure in the spirit of Beard & McLain 2012, chapter 6, with the
//! straight-line path following of chapter 10 and half-plane waypoint switching of chapter 11):
//!
//! * **Guidance** (mode [`Mode::Waypoints`]): the UAV flies the legs of its own (formation-offset)
//!   closed route. On leg `A -> B` the commanded course is the leg's bearing corrected for the
//!   cross-track error `e`: `chi_c = chi_leg - chi_inf * (2/pi) * atan(k_path * e)`. The commanded
//!   altitude is interpolated between the two waypoints' altitudes by the along-leg progress. The
//!   next leg starts when the UAV is within [`AutopilotGains::switch_radius`] of `B` (horizontal
//!   distance), or has crossed the half-plane through `B` normal to the bisector of the two legs
//!   (so a missed radius never makes it circle).
//! * **Station keeping**: every UAV advances the same reference distance `s_ref` along the
//!   *leader's* route at the reference airspeed; the UAV's own progress `s` is its position
//!   projected on the leader's current leg. The airspeed command is the nominal airspeed plus a
//!   saturated PI of `s_ref + along - s`, so UAVs with the same commands keep their along-track
//!   spacing through turns without exchanging positions.
//! * **Lateral**: course -> roll command (PI, ±30°), roll -> aileron (PD on roll and roll rate),
//!   yaw damper: rudder proportional to washed-out yaw rate.
//! * **Longitudinal**: altitude -> pitch command (PI around the trim pitch, ±15°), pitch -> elevator
//!   (PD around the trim elevator, with the pitch rate of a steady turn removed from the damping
//!   term), airspeed -> throttle (PI around the trim throttle, 0..1).
//! * **Anti-windup**: every integrator stops integrating while its output is saturated in the
//!   direction of the error (conditional integration); outputs are clamped.
//!
//! Mode [`Mode::Hold`] holds the course, altitude and airspeed captured when it was entered (the
//! DDF's `Autopilot = 0`); mode [`Mode::Manual`] applies fixed deflections (the trim by default).

use std::f64::consts::PI;

use crate::dynamics::{air_data, Controls, Environment, State};
use crate::formation::{FormationOffset, NedRoute, RouteError, Waypoint};
use crate::geodesy::GeoPoint;
use crate::math::wrap_pi;
use crate::params::AirframeParams;
use crate::trim::Trim;

/// Autopilot gains and limits. Angles in radians, distances in metres, speeds in m/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutopilotGains {
    /// Waypoint switching radius.
    pub switch_radius: f64,
    /// Course offset commanded far from the track.
    pub chi_inf: f64,
    /// Cross-track gain of the path-following law, 1/m.
    pub k_path: f64,
    /// Along-track station keeping: proportional gain, (m/s)/m.
    pub station_kp: f64,
    /// Along-track station keeping: integral gain, (m/s)/(m·s).
    pub station_ki: f64,
    /// Along-track station keeping: largest airspeed correction.
    pub station_max: f64,
    /// Along-track station keeping: the integrator only runs within this distance of the slot, m.
    pub station_band: f64,
    /// Smallest airspeed command.
    pub airspeed_min: f64,
    /// Largest airspeed command.
    pub airspeed_max: f64,
    /// Course -> roll proportional gain.
    pub course_kp: f64,
    /// Course -> roll integral gain.
    pub course_ki: f64,
    /// Roll command limit.
    pub roll_max: f64,
    /// Roll -> aileron proportional gain.
    pub roll_kp: f64,
    /// Roll rate -> aileron damping gain.
    pub roll_kd: f64,
    /// Yaw damper gain (rudder per washed-out yaw rate).
    pub yaw_damper: f64,
    /// Yaw damper washout time constant, s.
    pub washout_tau: f64,
    /// Altitude -> pitch proportional gain, rad/m.
    pub altitude_kp: f64,
    /// Altitude -> pitch integral gain, rad/(m·s).
    pub altitude_ki: f64,
    /// Pitch command limit (absolute).
    pub pitch_max: f64,
    /// Pitch -> elevator proportional gain.
    pub pitch_kp: f64,
    /// Pitch rate -> elevator damping gain.
    pub pitch_kd: f64,
    /// Airspeed -> throttle proportional gain, 1/(m/s).
    pub airspeed_kp: f64,
    /// Airspeed -> throttle integral gain.
    pub airspeed_ki: f64,
    /// Control-surface command limit.
    pub surface_max: f64,
}

impl Default for AutopilotGains {
    fn default() -> Self {
        AutopilotGains {
            switch_radius: 120.0,
            chi_inf: 60f64.to_radians(),
            k_path: 0.01,
            station_kp: 0.15,
            station_ki: 0.002,
            station_max: 5.0,
            station_band: 10.0,
            airspeed_min: 18.0,
            airspeed_max: 35.0,
            course_kp: 1.5,
            course_ki: 0.02,
            roll_max: 30f64.to_radians(),
            roll_kp: 0.5,
            roll_kd: 0.05,
            yaw_damper: 0.3,
            washout_tau: 1.0,
            altitude_kp: 0.02,
            altitude_ki: 0.002,
            pitch_max: 15f64.to_radians(),
            pitch_kp: 2.0,
            pitch_kd: 0.5,
            airspeed_kp: 0.05,
            airspeed_ki: 0.01,
            surface_max: 0.4363,
        }
    }
}

/// What the autopilot does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// No feedback: fixed deflections ([`Autopilot::set_manual_controls`], the trim by default).
    Manual,
    /// Hold the course, altitude and airspeed captured on entry (airspeed command if set).
    Hold,
    /// Fly the (formation-offset) route with along-track station keeping.
    Waypoints,
}

/// A PI controller with feed-forward, output clamping and conditional-integration anti-windup.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pi {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain.
    pub ki: f64,
    /// Lower output limit.
    pub min: f64,
    /// Upper output limit.
    pub max: f64,
    /// Integrator state (integral of the error).
    pub integral: f64,
}

impl Pi {
    /// A controller with a zero integrator.
    pub fn new(kp: f64, ki: f64, min: f64, max: f64) -> Pi {
        Pi { kp, ki, min, max, integral: 0.0 }
    }

    /// `clamp(ff + kp e + ki ∫e)`; the integrator is frozen while the output is saturated in the
    /// direction `e` pushes.
    pub fn update(&mut self, error: f64, feed_forward: f64, dt: f64) -> f64 {
        let candidate = self.integral + error * dt;
        let out = feed_forward + self.kp * error + self.ki * candidate;
        let winding = (out > self.max && error > 0.0) || (out < self.min && error < 0.0);
        if !winding {
            self.integral = candidate;
        }
        (feed_forward + self.kp * error + self.ki * self.integral).clamp(self.min, self.max)
    }

    /// Zeroes the integrator.
    pub fn reset(&mut self) {
        self.integral = 0.0;
    }
}

/// The measurements the autopilot uses (perfect sensors).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nav {
    /// North of home, m.
    pub pn: f64,
    /// East of home, m.
    pub pe: f64,
    /// Altitude above MSL, m.
    pub alt_msl: f64,
    /// True airspeed, m/s.
    pub va: f64,
    /// Course over ground, rad.
    pub chi: f64,
    /// Roll, rad.
    pub phi: f64,
    /// Pitch, rad.
    pub theta: f64,
    /// Heading, rad.
    pub psi: f64,
    /// Roll rate, rad/s.
    pub p: f64,
    /// Pitch rate, rad/s.
    pub q: f64,
    /// Yaw rate, rad/s.
    pub r: f64,
}

impl Nav {
    /// Measurements of `state` flying in `env`.
    pub fn measure(state: &State, env: &Environment) -> Nav {
        let (phi, theta, psi) = state.att.to_euler();
        let vel = state.velocity_ned();
        let chi = if vel[0].hypot(vel[1]) > 0.1 { vel[1].atan2(vel[0]) } else { psi };
        Nav {
            pn: state.pn,
            pe: state.pe,
            alt_msl: env.home_alt_msl - state.pd,
            va: air_data(state, env).va,
            chi,
            phi,
            theta,
            psi,
            p: state.p,
            q: state.q,
            r: state.r,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
struct Guidance {
    leader: NedRoute,
    own: NedRoute,
    /// Legs begun since the route was set (each one a waypoint reached).
    leg: u64,
    s_ref: f64,
}

/// The autopilot: guidance plus the PID loops.
#[derive(Clone, Debug, PartialEq)]
pub struct Autopilot {
    mode: Mode,
    gains: AutopilotGains,
    trim: Trim,
    g: f64,
    /// Extra angle of attack per unit of extra load factor at trim: `C_L,trim / C_L_alpha`.
    alpha_per_load: f64,
    /// Elevator per unit angle of attack holding the pitching moment: `-C_m_alpha / C_m_delta_e`.
    elevator_per_alpha: f64,
    manual: Controls,
    course: Pi,
    altitude: Pi,
    airspeed: Pi,
    station: Pi,
    washout: f64,
    hold: Option<(f64, f64, f64)>,
    guidance: Option<Guidance>,
    airspeed_cmd: Option<f64>,
    offset: FormationOffset,
}

impl Autopilot {
    /// An autopilot for `params` built around `trim` (its feed-forward terms), in [`Mode::Hold`],
    /// with no route.
    pub fn new(gains: AutopilotGains, trim: Trim, params: &AirframeParams) -> Autopilot {
        let gn = &gains;
        let cl_trim = params.cl0 + params.cl_alpha * trim.alpha + params.cl_de * trim.elevator;
        Autopilot {
            mode: Mode::Hold,
            trim,
            g: params.g,
            alpha_per_load: cl_trim / params.cl_alpha,
            elevator_per_alpha: -params.cm_alpha / params.cm_de,
            manual: trim.controls(),
            course: Pi::new(gn.course_kp, gn.course_ki, -gn.roll_max, gn.roll_max),
            altitude: Pi::new(gn.altitude_kp, gn.altitude_ki, -gn.pitch_max, gn.pitch_max),
            airspeed: Pi::new(gn.airspeed_kp, gn.airspeed_ki, 0.0, 1.0),
            station: Pi::new(gn.station_kp, gn.station_ki, -gn.station_max, gn.station_max),
            washout: 0.0,
            hold: None,
            guidance: None,
            airspeed_cmd: None,
            offset: FormationOffset::default(),
            gains,
        }
    }

    /// The current mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Changes mode. Entering [`Mode::Hold`] captures course, altitude and airspeed at the next
    /// update; [`Mode::Waypoints`] without a route falls back to [`Mode::Hold`].
    pub fn set_mode(&mut self, mode: Mode) {
        let mode = if mode == Mode::Waypoints && self.guidance.is_none() { Mode::Hold } else { mode };
        if mode == self.mode {
            return;
        }
        if mode == Mode::Hold {
            self.hold = None;
        }
        if self.mode == Mode::Manual {
            self.course.reset();
            self.altitude.reset();
            self.airspeed.reset();
        }
        self.mode = mode;
    }

    /// The DDF's `Autopilot` item: `true` follows the formation waypoints, `false` holds heading
    /// (course) and altitude.
    pub fn set_enabled(&mut self, enabled: bool) {
        self.set_mode(if enabled { Mode::Waypoints } else { Mode::Hold });
    }

    /// True in [`Mode::Waypoints`].
    pub fn is_enabled(&self) -> bool {
        self.mode == Mode::Waypoints
    }

    /// The fixed deflections of [`Mode::Manual`].
    pub fn set_manual_controls(&mut self, controls: Controls) {
        self.manual = controls;
    }

    /// Sets the leader's closed route (its offsets are applied with the current formation
    /// offset), restarts at leg 0 (waypoint 0 to waypoint 1) with the formation reference at
    /// waypoint 0.
    pub fn set_route(&mut self, home: &GeoPoint, route: &[Waypoint]) -> Result<(), RouteError> {
        let leader = NedRoute::new(home, route)?;
        let own = leader.offset(self.offset.cross, self.offset.up);
        self.guidance = Some(Guidance { leader, own, leg: 0, s_ref: 0.0 });
        self.station.reset();
        Ok(())
    }

    /// Sets the formation offset (takes effect at once; the leg and the reference are kept).
    pub fn set_formation_offset(&mut self, offset: FormationOffset) {
        if offset == self.offset {
            return;
        }
        self.offset = offset;
        if let Some(g) = &mut self.guidance {
            g.own = g.leader.offset(offset.cross, offset.up);
        }
    }

    /// The formation offset.
    pub fn formation_offset(&self) -> FormationOffset {
        self.offset
    }

    /// Overrides the route's airspeeds (`None`: fly the waypoints' airspeeds). The value is
    /// clamped to the gains' airspeed range.
    pub fn set_airspeed_command(&mut self, airspeed: Option<f64>) {
        self.airspeed_cmd = airspeed.filter(|v| v.is_finite() && *v > 0.0);
    }

    /// The airspeed override, if any.
    pub fn airspeed_command(&self) -> Option<f64> {
        self.airspeed_cmd
    }

    /// The gains.
    pub fn gains(&self) -> &AutopilotGains {
        &self.gains
    }

    /// Index of the waypoint the UAV is flying toward, if it has a route.
    pub fn target_waypoint(&self) -> Option<usize> {
        self.guidance.as_ref().map(|g| ((g.leg + 1) % g.own.n() as u64) as usize)
    }

    /// How many waypoints have been reached (leg switches) since the route was set.
    pub fn waypoints_reached(&self) -> u64 {
        self.guidance.as_ref().map_or(0, |g| g.leg)
    }

    /// The formation reference: distance flown along the leader's circuit, m.
    pub fn reference_distance(&self) -> f64 {
        self.guidance.as_ref().map_or(0.0, |g| g.s_ref)
    }

    fn airspeed_limit(&self, v: f64) -> f64 {
        v.clamp(self.gains.airspeed_min, self.gains.airspeed_max)
    }

    /// Waypoint guidance: (course, altitude, airspeed) commands.
    fn guide(&mut self, nav: &Nav, dt: f64) -> (f64, f64, f64) {
        let gains = self.gains;
        let airspeed_cmd = self.airspeed_cmd;
        let offset = self.offset;
        let g = self.guidance.as_mut().expect("waypoint mode has a route");
        let n = g.own.n();
        let pos = [nav.pn, nav.pe];
        for _ in 0..n {
            let i = (g.leg % n as u64) as usize;
            let j = (i + 1) % n;
            let b = g.own.pos[j];
            let rel = [pos[0] - b[0], pos[1] - b[1]];
            let (di, dj) = (g.own.dir[i], g.own.dir[j]);
            let mut bis = [di[0] + dj[0], di[1] + dj[1]];
            let bl = bis[0].hypot(bis[1]);
            bis = if bl > 1e-6 { [bis[0] / bl, bis[1] / bl] } else { di };
            let passed = rel[0] * bis[0] + rel[1] * bis[1] >= 0.0;
            if rel[0].hypot(rel[1]) < gains.switch_radius || passed {
                g.leg += 1;
            } else {
                break;
            }
        }
        let i = (g.leg % n as u64) as usize;
        let j = (i + 1) % n;
        let a = g.own.pos[i];
        let d = g.own.dir[i];
        let rel = [pos[0] - a[0], pos[1] - a[1]];
        let right = g.own.right(i);
        let e_cross = rel[0] * right[0] + rel[1] * right[1];
        let chi_leg = d[1].atan2(d[0]);
        let course = chi_leg - gains.chi_inf * (2.0 / PI) * (gains.k_path * e_cross).atan();
        let frac = ((rel[0] * d[0] + rel[1] * d[1]) / g.own.len[i]).clamp(0.0, 1.0);
        let altitude = g.own.alt[i] + frac * (g.own.alt[j] - g.own.alt[i]);
        let nominal = airspeed_cmd.unwrap_or(g.own.airspeed[j]);

        // Progress along the leader's circuit: the projection on the leader's current leg.
        let (la, ld) = (g.leader.pos[i], g.leader.dir[i]);
        let s_own = g.leader.leg_start(g.leg) + (pos[0] - la[0]) * ld[0] + (pos[1] - la[1]) * ld[1];
        let along_error = g.s_ref + offset.along - s_own;
        // Conditional integration: only near the slot, so turns do not charge the integrator.
        let frozen = self.station.integral;
        let correction = self.station.update(along_error, 0.0, dt);
        if along_error.abs() > gains.station_band {
            self.station.integral = frozen;
        }
        (course, altitude, nominal + correction)
    }

    fn advance_reference(&mut self, dt: f64) {
        let cmd = self.airspeed_cmd.map(|v| self.airspeed_limit(v));
        if let Some(g) = &mut self.guidance {
            let leg = g.leader.leg_at(g.s_ref);
            let v = cmd.unwrap_or(g.leader.airspeed[(leg + 1) % g.leader.n()]);
            g.s_ref += v * dt;
        }
    }

    /// One autopilot update: the actuator commands for the measurements `nav`.
    pub fn update(&mut self, nav: &Nav, dt: f64) -> Controls {
        let (course, altitude, airspeed) = match self.mode {
            Mode::Manual => {
                self.advance_reference(dt);
                return self.manual;
            }
            Mode::Hold => {
                let (c, h, v) = *self.hold.get_or_insert((nav.chi, nav.alt_msl, nav.va));
                (c, h, self.airspeed_cmd.unwrap_or(v))
            }
            Mode::Waypoints => self.guide(nav, dt),
        };
        self.advance_reference(dt);
        let airspeed = self.airspeed_limit(airspeed);
        let gn = self.gains;
        let t = self.trim;

        // Lateral: course -> roll -> aileron, yaw damper -> rudder.
        let roll = self.course.update(wrap_pi(course - nav.chi), 0.0, dt);
        let aileron = (gn.roll_kp * (roll - nav.phi) - gn.roll_kd * nav.p).clamp(-gn.surface_max, gn.surface_max);
        self.washout += dt / gn.washout_tau * (nav.r - self.washout);
        let rudder = (gn.yaw_damper * (nav.r - self.washout)).clamp(-gn.surface_max, gn.surface_max);

        // Longitudinal: altitude -> pitch -> elevator, airspeed -> throttle.
        // In a banked turn the wing must carry 1/cos(phi) g: feed the extra angle of attack forward
        // into the pitch command and the elevator, and do not damp the turn's steady pitch rate.
        let phi = nav.phi.clamp(-1.2, 1.2);
        let extra_alpha = self.alpha_per_load * (1.0 / phi.cos() - 1.0);
        let pitch = self.altitude.update(altitude - nav.alt_msl, t.alpha + extra_alpha, dt);
        let q_turn = self.g / nav.va.max(1.0) * phi.tan() * phi.sin() * nav.theta.cos();
        let elevator = (t.elevator + self.elevator_per_alpha * extra_alpha - gn.pitch_kp * (pitch - nav.theta)
            + gn.pitch_kd * (nav.q - q_turn))
            .clamp(-gn.surface_max, gn.surface_max);
        let throttle = self.airspeed.update(airspeed - nav.va, t.throttle, dt);

        Controls { elevator, aileron, rudder, throttle }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pi_anti_windup() {
        let mut pi = Pi::new(1.0, 1.0, -1.0, 1.0);
        for _ in 0..1000 {
            assert_eq!(pi.update(10.0, 0.0, 0.01), 1.0);
        }
        // Saturated the whole time: the integrator did not wind up.
        assert!(pi.integral < 0.01, "{}", pi.integral);
        // Reversing the error desaturates immediately.
        assert!(pi.update(-0.5, 0.0, 0.01) < 0.0);
    }
}
