//! Small fixed-size vector and quaternion helpers (no linear-algebra dependency).

use std::f64::consts::PI;

/// A 3-vector; for positions and velocities the order is north, east, down (NED) or x, y, z (body).
pub type Vec3 = [f64; 3];

/// Dot product.
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Euclidean norm.
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// Wraps an angle to `(-pi, pi]`.
pub fn wrap_pi(a: f64) -> f64 {
    let mut x = (a + PI).rem_euclid(2.0 * PI) - PI;
    if x <= -PI {
        x += 2.0 * PI;
    }
    x
}

/// Wraps an angle in degrees to `[0, 360)`.
pub fn wrap_360(deg: f64) -> f64 {
    let x = deg.rem_euclid(360.0);
    if x >= 360.0 {
        0.0
    } else {
        x
    }
}

/// Attitude quaternion `e0 + e1 i + e2 j + e3 k` (scalar first) rotating body-frame vectors into NED,
/// with the conventions of Beard & McLain (2012), appendix B.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quat {
    /// Scalar part.
    pub e0: f64,
    /// First vector part.
    pub e1: f64,
    /// Second vector part.
    pub e2: f64,
    /// Third vector part.
    pub e3: f64,
}

impl Quat {
    /// The identity attitude (wings level, pointing north).
    pub const IDENTITY: Quat = Quat { e0: 1.0, e1: 0.0, e2: 0.0, e3: 0.0 };

    /// From 3-2-1 Euler angles: roll `phi`, pitch `theta`, yaw `psi` (radians).
    pub fn from_euler(phi: f64, theta: f64, psi: f64) -> Quat {
        let (sf, cf) = (phi / 2.0).sin_cos();
        let (st, ct) = (theta / 2.0).sin_cos();
        let (sp, cp) = (psi / 2.0).sin_cos();
        Quat {
            e0: cp * ct * cf + sp * st * sf,
            e1: cp * ct * sf - sp * st * cf,
            e2: cp * st * cf + sp * ct * sf,
            e3: sp * ct * cf - cp * st * sf,
        }
    }

    /// 3-2-1 Euler angles `(phi, theta, psi)` in radians; `psi` in `(-pi, pi]`.
    pub fn to_euler(&self) -> (f64, f64, f64) {
        let Quat { e0, e1, e2, e3 } = *self;
        let phi = (2.0 * (e0 * e1 + e2 * e3)).atan2(e0 * e0 + e3 * e3 - e1 * e1 - e2 * e2);
        let theta = (2.0 * (e0 * e2 - e1 * e3)).clamp(-1.0, 1.0).asin();
        let psi = (2.0 * (e0 * e3 + e1 * e2)).atan2(e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3);
        (phi, theta, psi)
    }

    /// Euclidean norm (1 for a valid attitude).
    pub fn norm(&self) -> f64 {
        (self.e0 * self.e0 + self.e1 * self.e1 + self.e2 * self.e2 + self.e3 * self.e3).sqrt()
    }

    /// This quaternion scaled to unit norm.
    pub fn normalised(&self) -> Quat {
        let n = self.norm();
        Quat { e0: self.e0 / n, e1: self.e1 / n, e2: self.e2 / n, e3: self.e3 / n }
    }

    /// Rotation matrix from body to NED (rows are NED axes).
    pub fn body_to_ned(&self) -> [[f64; 3]; 3] {
        let Quat { e0, e1, e2, e3 } = *self;
        [
            [e1 * e1 + e0 * e0 - e2 * e2 - e3 * e3, 2.0 * (e1 * e2 - e3 * e0), 2.0 * (e1 * e3 + e2 * e0)],
            [2.0 * (e1 * e2 + e3 * e0), e2 * e2 + e0 * e0 - e1 * e1 - e3 * e3, 2.0 * (e2 * e3 - e1 * e0)],
            [2.0 * (e1 * e3 - e2 * e0), 2.0 * (e2 * e3 + e1 * e0), e3 * e3 + e0 * e0 - e1 * e1 - e2 * e2],
        ]
    }

    /// Rotates a body-frame vector into NED.
    pub fn rotate_to_ned(&self, v: Vec3) -> Vec3 {
        let r = self.body_to_ned();
        [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
    }

    /// Rotates a NED vector into the body frame.
    pub fn rotate_to_body(&self, v: Vec3) -> Vec3 {
        let r = self.body_to_ned();
        [
            r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
            r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
            r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_round_trip() {
        for &(phi, theta, psi) in &[(0.1, -0.2, 2.5), (-0.5, 0.3, -1.0), (0.0, 0.0, 3.0)] {
            let q = Quat::from_euler(phi, theta, psi);
            assert!((q.norm() - 1.0).abs() < 1e-12);
            let (a, b, c) = q.to_euler();
            assert!((a - phi).abs() < 1e-12 && (b - theta).abs() < 1e-12 && wrap_pi(c - psi).abs() < 1e-12);
        }
    }

    #[test]
    fn rotation_is_consistent() {
        let q = Quat::from_euler(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        // Nose pointing east: body x is NED east.
        let v = q.rotate_to_ned([1.0, 0.0, 0.0]);
        assert!(v[0].abs() < 1e-12 && (v[1] - 1.0).abs() < 1e-12);
        let back = q.rotate_to_body(v);
        assert!((back[0] - 1.0).abs() < 1e-12 && back[1].abs() < 1e-12);
        assert!((wrap_pi(3.0 * PI) - PI).abs() < 1e-12);
        assert_eq!(wrap_360(-90.0), 270.0);
    }
}
