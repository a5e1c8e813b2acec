//! Waypoint routes and formation offsets.
//!
//! A formation offset is constant in the *path frame* of the leader's route: `along` metres ahead
//! along the track (negative = behind), `cross` metres to the right of the track (negative = left)
//! and `up` metres above it. The follower's route ([`offset_route`]) is the leader's closed circuit
//! moved `cross` metres sideways and `up` metres up: at each waypoint the two adjacent legs are
//! offset and intersected (a mitre joint), so every offset leg is parallel to the leader's leg at
//! exactly `cross` metres. The along-track offset does not change the geometry of a polyline: it is
//! a timing offset, held by the autopilot's along-track station keeping against a reference point
//! that every UAV advances identically along the leader's route (see [`crate::autopilot`]).

use std::fmt;

use crate::geodesy::{geo_to_ned, ned_to_geo, GeoPoint};

/// A route waypoint: position and the airspeed to fly on the leg that ends at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Waypoint {
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Altitude above MSL, m.
    pub alt_m: f64,
    /// Airspeed on the leg toward this waypoint, m/s.
    pub airspeed: f64,
}

impl Waypoint {
    /// The waypoint's position.
    pub fn geo(&self) -> GeoPoint {
        GeoPoint::new(self.lat_deg, self.lon_deg, self.alt_m)
    }
}

/// A formation slot relative to the leader, in the leader's path frame (metres).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FormationOffset {
    /// Along-track, positive ahead of the leader.
    pub along: f64,
    /// Cross-track, positive to the right of the leader's track.
    pub cross: f64,
    /// Vertical, positive above the leader.
    pub up: f64,
}

impl FormationOffset {
    /// An offset from its three components.
    pub const fn new(along: f64, cross: f64, up: f64) -> FormationOffset {
        FormationOffset { along, cross, up }
    }
}

/// Why a route is unusable.
#[derive(Clone, Debug, PartialEq)]
pub enum RouteError {
    /// Fewer than two waypoints.
    TooFewWaypoints,
    /// A coordinate, altitude or airspeed is not finite, or an airspeed is not positive.
    BadValue {
        /// Index of the waypoint.
        index: usize,
    },
    /// Two consecutive waypoints (cyclically) are less than 1 m apart horizontally.
    ZeroLengthLeg {
        /// Index of the leg's first waypoint.
        index: usize,
    },
    /// The route reverses direction (turn of more than about 160°) at a waypoint, where a
    /// sideways offset is not defined.
    Reversal {
        /// Index of the waypoint.
        index: usize,
    },
}

impl fmt::Display for RouteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RouteError::TooFewWaypoints => write!(f, "a route needs at least two waypoints"),
            RouteError::BadValue { index } => write!(f, "waypoint {index}: non-finite value or non-positive airspeed"),
            RouteError::ZeroLengthLeg { index } => write!(f, "leg from waypoint {index} is shorter than 1 m"),
            RouteError::Reversal { index } => write!(f, "the route reverses direction at waypoint {index}"),
        }
    }
}

impl std::error::Error for RouteError {}

/// A closed route in local NED coordinates with precomputed legs; leg `i` goes from waypoint `i`
/// to waypoint `(i + 1) % n`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct NedRoute {
    /// Horizontal positions (north, east), m.
    pub pos: Vec<[f64; 2]>,
    /// Altitudes above MSL, m.
    pub alt: Vec<f64>,
    /// Airspeeds, m/s.
    pub airspeed: Vec<f64>,
    /// Unit direction of each leg.
    pub dir: Vec<[f64; 2]>,
    /// Length of each leg, m.
    pub len: Vec<f64>,
    /// Distance along the circuit at the start of each leg, m.
    pub cum: Vec<f64>,
    /// Length of the whole circuit, m.
    pub perimeter: f64,
}

impl NedRoute {
    pub fn new(home: &GeoPoint, route: &[Waypoint]) -> Result<NedRoute, RouteError> {
        if route.len() < 2 {
            return Err(RouteError::TooFewWaypoints);
        }
        let mut pos = Vec::with_capacity(route.len());
        let mut alt = Vec::with_capacity(route.len());
        let mut airspeed = Vec::with_capacity(route.len());
        for (index, w) in route.iter().enumerate() {
            let ok = [w.lat_deg, w.lon_deg, w.alt_m, w.airspeed].iter().all(|v| v.is_finite()) && w.airspeed > 0.0;
            if !ok {
                return Err(RouteError::BadValue { index });
            }
            let ned = geo_to_ned(home, &w.geo());
            pos.push([ned[0], ned[1]]);
            alt.push(w.alt_m);
            airspeed.push(w.airspeed);
        }
        Self::from_parts(pos, alt, airspeed)
    }

    fn from_parts(pos: Vec<[f64; 2]>, alt: Vec<f64>, airspeed: Vec<f64>) -> Result<NedRoute, RouteError> {
        let n = pos.len();
        let mut dir = Vec::with_capacity(n);
        let mut len = Vec::with_capacity(n);
        let mut cum = Vec::with_capacity(n);
        let mut total = 0.0;
        for i in 0..n {
            let a = pos[i];
            let b = pos[(i + 1) % n];
            let d = [b[0] - a[0], b[1] - a[1]];
            let l = d[0].hypot(d[1]);
            if l.is_nan() || l < 1.0 {
                return Err(RouteError::ZeroLengthLeg { index: i });
            }
            dir.push([d[0] / l, d[1] / l]);
            len.push(l);
            cum.push(total);
            total += l;
        }
        if n > 2 {
            for i in 0..n {
                let din = dir[(i + n - 1) % n];
                let dout = dir[i];
                if din[0] * dout[0] + din[1] * dout[1] < -0.94 {
                    return Err(RouteError::Reversal { index: i });
                }
            }
        }
        Ok(NedRoute { pos, alt, airspeed, dir, len, cum, perimeter: total })
    }

    pub fn n(&self) -> usize {
        self.pos.len()
    }

    /// Right-hand normal of leg `i`.
    pub fn right(&self, i: usize) -> [f64; 2] {
        let d = self.dir[i % self.n()];
        [-d[1], d[0]]
    }

    /// The route moved `cross` metres right and `up` metres up (mitre joints at the waypoints).
    pub fn offset(&self, cross: f64, up: f64) -> NedRoute {
        let n = self.n();
        let mut pos = Vec::with_capacity(n);
        for i in 0..n {
            let rin = self.right(i + n - 1);
            let rout = self.right(i);
            let denom = 1.0 + rin[0] * rout[0] + rin[1] * rout[1];
            let m = if n == 2 { rout } else { [(rin[0] + rout[0]) / denom, (rin[1] + rout[1]) / denom] };
            pos.push([self.pos[i][0] + cross * m[0], self.pos[i][1] + cross * m[1]]);
        }
        let alt = self.alt.iter().map(|a| a + up).collect();
        NedRoute::from_parts(pos, alt, self.airspeed.clone()).unwrap_or_else(|_| {
            // A cross offset larger than a leg can collapse that leg; fall back to the pure
            // vertical offset rather than producing a degenerate route.
            NedRoute { alt: self.alt.iter().map(|a| a + up).collect(), ..self.clone() }
        })
    }

    /// Distance along the circuit at the start of unbounded leg counter `k` (laps accumulate).
    pub fn leg_start(&self, k: u64) -> f64 {
        let n = self.n() as u64;
        (k / n) as f64 * self.perimeter + self.cum[(k % n) as usize]
    }

    /// Index of the leg containing circuit distance `s` (taken modulo the perimeter).
    pub fn leg_at(&self, s: f64) -> usize {
        let s = s.rem_euclid(self.perimeter);
        self.cum.iter().rposition(|&c| c <= s).unwrap_or(0)
    }
}

/// The follower route for `offset` behind/beside/above the leader's closed `route` (see the module
/// documentation: only `cross` and `up` change the geometry).
pub fn offset_route(home: &GeoPoint, route: &[Waypoint], offset: FormationOffset) -> Result<Vec<Waypoint>, RouteError> {
    let ned = NedRoute::new(home, route)?.offset(offset.cross, offset.up);
    Ok((0..ned.n())
        .map(|i| {
            let g = ned_to_geo(home, [ned.pos[i][0], ned.pos[i][1], home.alt_m - ned.alt[i]]);
            Waypoint { lat_deg: g.lat_deg, lon_deg: g.lon_deg, alt_m: g.alt_m, airspeed: ned.airspeed[i] }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(home: &GeoPoint) -> Vec<Waypoint> {
        [[0.0, 0.0], [1000.0, 0.0], [1000.0, 1000.0], [0.0, 1000.0]]
            .iter()
            .map(|p| {
                let g = ned_to_geo(home, [p[0], p[1], -100.0]);
                Waypoint { lat_deg: g.lat_deg, lon_deg: g.lon_deg, alt_m: g.alt_m, airspeed: 25.0 }
            })
            .collect()
    }

    #[test]
    fn offset_legs_are_parallel_at_the_cross_distance() {
        let home = GeoPoint::new(45.5, -73.6, 0.0);
        let route = square(&home);
        let off = offset_route(&home, &route, FormationOffset::new(-50.0, 60.0, 20.0)).unwrap();
        let leader = NedRoute::new(&home, &route).unwrap();
        let follower = NedRoute::new(&home, &off).unwrap();
        // Clockwise square: right of track is inside; the inside square is 880 m wide.
        let expect = [[60.0, 60.0], [940.0, 60.0], [940.0, 940.0], [60.0, 940.0]];
        for (p, e) in follower.pos.iter().zip(expect) {
            assert!((p[0] - e[0]).abs() < 1e-6 && (p[1] - e[1]).abs() < 1e-6, "{p:?} vs {e:?}");
        }
        for i in 0..4 {
            let r = leader.right(i);
            let d = [follower.pos[i][0] - leader.pos[i][0], follower.pos[i][1] - leader.pos[i][1]];
            assert!((d[0] * r[0] + d[1] * r[1] - 60.0).abs() < 1e-6);
            assert!((follower.alt[i] - leader.alt[i] - 20.0).abs() < 1e-9);
        }
        assert_eq!(leader.leg_at(1500.0), 1);
        assert_eq!(leader.leg_at(4000.0 + 10.0), 0);
        assert!((leader.leg_start(5) - 5000.0).abs() < 1e-6);
    }

    #[test]
    fn bad_routes_are_rejected() {
        let home = GeoPoint::new(45.5, -73.6, 0.0);
        let r = square(&home);
        assert_eq!(NedRoute::new(&home, &r[..1]).unwrap_err(), RouteError::TooFewWaypoints);
        let mut dup = r.clone();
        dup[1] = dup[0];
        assert_eq!(NedRoute::new(&home, &dup).unwrap_err(), RouteError::ZeroLengthLeg { index: 0 });
        let mut bad = r.clone();
        bad[2].airspeed = 0.0;
        assert_eq!(NedRoute::new(&home, &bad).unwrap_err(), RouteError::BadValue { index: 2 });
        let back = vec![r[0], r[1], r[0]];
        assert!(matches!(
            NedRoute::new(&home, &back),
            Err(RouteError::ZeroLengthLeg { .. } | RouteError::Reversal { .. })
        ));
    }
}
