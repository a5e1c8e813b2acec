//! Local flat-earth conversion between NED offsets and WGS-84 latitude/longitude/altitude.
//!
//! Around the home point, north and east offsets are converted with the WGS-84 meridian radius
//! `R_M` and prime-vertical radius `R_N` at the home latitude (plus the home altitude):
//! `lat = lat0 + pn / (R_M + h0)`, `lon = lon0 + pe / ((R_N + h0) cos lat0)`, `alt = h0 - pd`.
//! Over the few kilometres of the demo the error against an exact geodetic conversion is well under
//! a metre horizontally; the earth's curvature is ignored vertically (about 0.8 m at 3.2 km).

use crate::math::Vec3;

const WGS84_A: f64 = 6_378_137.0;
const WGS84_E2: f64 = 6.694_379_990_14e-3;

/// A geodetic position: latitude and longitude in degrees, altitude in metres above MSL.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeoPoint {
    /// Latitude, degrees (north positive).
    pub lat_deg: f64,
    /// Longitude, degrees (east positive).
    pub lon_deg: f64,
    /// Altitude above mean sea level, m.
    pub alt_m: f64,
}

impl GeoPoint {
    /// A point from its three coordinates.
    pub const fn new(lat_deg: f64, lon_deg: f64, alt_m: f64) -> GeoPoint {
        GeoPoint { lat_deg, lon_deg, alt_m }
    }
}

fn radii(home: &GeoPoint) -> (f64, f64) {
    let s = home.lat_deg.to_radians().sin();
    let w = 1.0 - WGS84_E2 * s * s;
    let rn = WGS84_A / w.sqrt();
    let rm = WGS84_A * (1.0 - WGS84_E2) / (w * w.sqrt());
    (rm + home.alt_m, (rn + home.alt_m) * home.lat_deg.to_radians().cos())
}

/// The geodetic position of NED offset `ned` (m) from `home`.
pub fn ned_to_geo(home: &GeoPoint, ned: Vec3) -> GeoPoint {
    let (rm, rn_cos) = radii(home);
    GeoPoint {
        lat_deg: home.lat_deg + (ned[0] / rm).to_degrees(),
        lon_deg: home.lon_deg + (ned[1] / rn_cos).to_degrees(),
        alt_m: home.alt_m - ned[2],
    }
}

/// The NED offset (m) of `point` from `home`.
pub fn geo_to_ned(home: &GeoPoint, point: &GeoPoint) -> Vec3 {
    let (rm, rn_cos) = radii(home);
    [
        (point.lat_deg - home.lat_deg).to_radians() * rm,
        (point.lon_deg - home.lon_deg).to_radians() * rn_cos,
        home.alt_m - point.alt_m,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_scale() {
        let home = GeoPoint::new(45.5, -73.6, 36.0);
        let p = ned_to_geo(&home, [1000.0, -2000.0, -264.0]);
        assert!((p.alt_m - 300.0).abs() < 1e-12);
        // One degree of latitude is about 111.1 km at 45 N; one of longitude about 78.0 km.
        assert!(((p.lat_deg - 45.5) * 111_132.0 - 1000.0).abs() < 2.0, "{p:?}");
        assert!(((p.lon_deg + 73.6) * 78_000.0 + 2000.0).abs() < 10.0, "{p:?}");
        let back = geo_to_ned(&home, &p);
        assert!((back[0] - 1000.0).abs() < 1e-6 && (back[1] + 2000.0).abs() < 1e-6 && (back[2] + 264.0).abs() < 1e-9);
    }
}
