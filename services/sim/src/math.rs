//! Frames and poses.
//!
//! - World: local ENU (x east, y north, z up), metres. Water surface at z = 0.
//! - Body: x forward, y left, z up. Attitude is roll/pitch/yaw (Z-Y-X): yaw = 0 faces east, positive
//!   yaw turns towards north (counter-clockwise seen from above); positive pitch is nose down and
//!   positive roll is starboard (right) side down, both from the right-hand rule on y-left / x-forward.
//! - Optical camera: x right, y down, z forward (see [`OPTICAL_FROM_BODYLIKE`]).
//!
//! Dynamics use f64; rendering uses f32 (scenes span a few km, f32 keeps sub-millimetre precision).

use nalgebra::{Matrix3, Rotation3, Vector3};

pub type V3 = Vector3<f32>;
pub type M3 = Matrix3<f32>;

/// Rigid pose: `world_from_local` rotation and translation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub position: Vector3<f64>,
    /// Roll, pitch, yaw in radians (Z-Y-X order, see module docs).
    pub rpy: Vector3<f64>,
}

impl Pose {
    pub fn new(position: [f64; 3], rpy: [f64; 3]) -> Self {
        Pose {
            position: Vector3::from(position),
            rpy: Vector3::from(rpy),
        }
    }

    pub fn rotation(&self) -> Rotation3<f64> {
        Rotation3::from_euler_angles(self.rpy.x, self.rpy.y, self.rpy.z)
    }

    /// `self` is `a_from_b`, `other` is `b_from_c`: returns the position and rotation of `a_from_c`.
    pub fn compose(&self, other: &Pose) -> (Vector3<f64>, Rotation3<f64>) {
        let r = self.rotation();
        (self.position + r * other.position, r * other.rotation())
    }
}

/// Rotation taking optical-frame vectors (x right, y down, z forward) into a body-like frame
/// (x forward, y left, z up): columns are the optical axes written in body-like axes.
pub const OPTICAL_FROM_BODYLIKE: [[f64; 3]; 3] =
    [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]];

/// `bodylike_from_optical` as a matrix (the transpose of the rows above).
pub fn bodylike_from_optical() -> Matrix3<f64> {
    let m = OPTICAL_FROM_BODYLIKE;
    Matrix3::new(
        m[0][0], m[1][0], m[2][0], m[0][1], m[1][1], m[2][1], m[0][2], m[1][2], m[2][2],
    )
}

pub fn v3(x: f32, y: f32, z: f32) -> V3 {
    V3::new(x, y, z)
}

#[inline(always)]
pub fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[inline(always)]
pub fn mix(a: V3, b: V3, t: f32) -> V3 {
    a + (b - a) * t
}

/// Cosine to ~3e-5, several times faster than libm's (used per pixel for waves).
#[inline(always)]
pub fn fast_cos(x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI, TAU};
    let k = (x * (1.0 / TAU) + 0.5) as i32 - (x * (1.0 / TAU) + 0.5 < 0.0) as i32;
    let y = (x - k as f32 * TAU).abs(); // [0, pi]
    let (y, sign) = if y > FRAC_PI_2 {
        (PI - y, -1.0)
    } else {
        (y, 1.0)
    };
    let y2 = y * y;
    sign * (1.0 + y2 * (-0.5 + y2 * (1.0 / 24.0 + y2 * (-1.0 / 720.0 + y2 * (1.0 / 40320.0)))))
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_pi(a: f64) -> f64 {
    let r = a.rem_euclid(std::f64::consts::TAU);
    if r > std::f64::consts::PI {
        r - std::f64::consts::TAU
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_cos_matches() {
        for i in -2000..2000 {
            let x = i as f32 * 0.0731;
            assert!((fast_cos(x) - x.cos()).abs() < 5e-5, "{x}");
        }
    }

    #[test]
    fn optical_axes() {
        let r = bodylike_from_optical();
        // Optical z (forward) is body x, optical x (right) is body -y, optical y (down) is body -z.
        assert_eq!(r * Vector3::z(), Vector3::x());
        assert_eq!(r * Vector3::x(), -Vector3::y());
        assert_eq!(r * Vector3::y(), -Vector3::z());
    }

    #[test]
    fn yaw_turns_counter_clockwise() {
        let p = Pose::new([0.0; 3], [0.0, 0.0, std::f64::consts::FRAC_PI_2]);
        let fwd = p.rotation() * Vector3::x();
        assert!(
            (fwd - Vector3::y()).norm() < 1e-12,
            "yaw 90 deg faces north"
        );
        let pitch = Pose::new([0.0; 3], [0.0, 0.1, 0.0]);
        assert!(
            (pitch.rotation() * Vector3::x()).z < 0.0,
            "positive pitch is nose down"
        );
    }
}
