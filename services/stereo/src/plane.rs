//! Robust water-plane fit: RANSAC on 3D points (typically from the lower image rows, where the
//! water is), then least-squares refinement on the inliers. Gives camera height above the plane,
//! roll, pitch and the rotation that levels the camera (the stabilized pose).
//!
//! Frame: optical camera frame (x right, y down, z forward). The plane is `n . p + h = 0` with `n`
//! the unit normal pointing up (out of the water, towards the camera), so `h > 0` is the camera
//! height. Angles: `pitch = asin(-n.z)` (positive = looking down), `roll = atan2(n.x, -n.y)`, i.e.
//! `n = (sin roll cos pitch, -cos roll cos pitch, -sin pitch)`.

use nalgebra::{Matrix3, Rotation3, SymmetricEigen, Vector3};
use serde::Deserialize;
use thiserror::Error;

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct PlaneParams {
    pub iterations: usize,
    /// Max point-to-plane distance of an inlier, metres.
    pub inlier_distance: f64,
    /// Fewer inliers than this is a failed fit.
    pub min_inliers: usize,
    /// Planes tilted more than this from the camera's horizontal are not water, degrees.
    pub max_tilt_deg: f64,
    /// Seed of the sample generator (fixed, so the fit is deterministic).
    pub seed: u64,
}

impl Default for PlaneParams {
    fn default() -> Self {
        Self {
            iterations: 200,
            inlier_distance: 0.05,
            min_inliers: 30,
            max_tilt_deg: 30.0,
            seed: 0x5eed,
        }
    }
}

#[derive(Debug, Error, PartialEq)]
pub enum PlaneError {
    #[error("plane fit needs at least {need} points, got {got}")]
    TooFewPoints { need: usize, got: usize },
    #[error("no plane with at least {need} inliers (best had {best})")]
    NoConsensus { need: usize, best: usize },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaterPlane {
    pub normal: Vector3<f64>,
    /// Camera height above the plane, metres.
    pub height: f64,
    pub roll: f64,
    pub pitch: f64,
    pub inliers: usize,
}

impl WaterPlane {
    /// Rotation from the camera frame to a level frame (y along gravity, z forward horizontal,
    /// same heading): `Rx(-pitch) * Rz(-roll)`; it maps `normal` to (0, -1, 0).
    pub fn level_from_camera(&self) -> Rotation3<f64> {
        Rotation3::from_axis_angle(&Vector3::x_axis(), -self.pitch)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), -self.roll)
    }

    fn from_normal(n: Vector3<f64>, h: f64, inliers: usize) -> Self {
        Self {
            normal: n,
            height: h,
            roll: n.x.atan2(-n.y),
            pitch: (-n.z).clamp(-1.0, 1.0).asin(),
            inliers,
        }
    }
}

/// Reusable fitter (keeps its inlier buffer between frames).
pub struct PlaneFitter {
    params: PlaneParams,
    inliers: Vec<usize>,
}

impl PlaneFitter {
    pub fn new(params: PlaneParams) -> Self {
        Self {
            params,
            inliers: Vec::new(),
        }
    }

    pub fn fit(&mut self, points: &[Vector3<f32>]) -> Result<WaterPlane, PlaneError> {
        let p = &self.params;
        let need = p.min_inliers.max(3);
        if points.len() < need {
            return Err(PlaneError::TooFewPoints {
                need,
                got: points.len(),
            });
        }
        let cos_tilt = p.max_tilt_deg.to_radians().cos();
        let pt = |i: usize| points[i].cast::<f64>();
        let mut rng = p.seed | 1;
        let mut best: Option<(Vector3<f64>, f64)> = None;
        let mut best_count = 0;
        for _ in 0..p.iterations {
            let mut idx = [0usize; 3];
            for i in &mut idx {
                *i = (xorshift(&mut rng) % points.len() as u64) as usize;
            }
            let (a, b, c) = (pt(idx[0]), pt(idx[1]), pt(idx[2]));
            let Some((n, h)) = plane_through(a, b, c) else {
                continue;
            };
            // Water is below the camera and roughly level.
            if h <= 0.0 || -n.y < cos_tilt {
                continue;
            }
            let count = points
                .iter()
                .filter(|q| (n.dot(&q.cast()) + h).abs() < p.inlier_distance)
                .count();
            if count > best_count {
                best_count = count;
                best = Some((n, h));
            }
        }
        let Some((mut n, mut h)) = best.filter(|_| best_count >= need) else {
            return Err(PlaneError::NoConsensus {
                need,
                best: best_count,
            });
        };
        // Least-squares refinement, re-selecting inliers each round.
        for _ in 0..3 {
            self.inliers.clear();
            self.inliers.extend(
                (0..points.len()).filter(|&i| (n.dot(&pt(i)) + h).abs() < p.inlier_distance),
            );
            if self.inliers.len() < need {
                break;
            }
            let (nn, hh) = least_squares(self.inliers.iter().map(|&i| pt(i)));
            n = nn;
            h = hh;
        }
        Ok(WaterPlane::from_normal(n, h, self.inliers.len()))
    }
}

/// Unit normal pointing up (negative y) and offset, or None when the points are collinear.
fn plane_through(a: Vector3<f64>, b: Vector3<f64>, c: Vector3<f64>) -> Option<(Vector3<f64>, f64)> {
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    if len < 1e-9 {
        return None;
    }
    let n = if n.y > 0.0 { -n / len } else { n / len };
    Some((n, -n.dot(&a)))
}

/// Total least squares: normal = smallest-eigenvalue eigenvector of the scatter matrix.
fn least_squares(pts: impl Iterator<Item = Vector3<f64>> + Clone) -> (Vector3<f64>, f64) {
    let (mut sum, mut k) = (Vector3::zeros(), 0.0);
    for q in pts.clone() {
        sum += q;
        k += 1.0;
    }
    let c = sum / k;
    let mut m = Matrix3::zeros();
    for q in pts {
        let e = q - c;
        m += e * e.transpose();
    }
    let eig = SymmetricEigen::new(m);
    let i = eig.eigenvalues.imin();
    let mut n: Vector3<f64> = eig.eigenvectors.column(i).into();
    if n.y > 0.0 {
        n = -n;
    }
    (n, -n.dot(&c))
}

fn xorshift(s: &mut u64) -> u64 {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    *s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_height_roll_pitch_with_outliers() {
        let (h, roll, pitch) = (2.5f64, 4f64.to_radians(), 7f64.to_radians());
        let n = Vector3::new(
            roll.sin() * pitch.cos(),
            -roll.cos() * pitch.cos(),
            -pitch.sin(),
        );
        let mut s = 42u64;
        let mut u = || (xorshift(&mut s) % 1_000_000) as f64 / 1e6;
        let mut pts = Vec::new();
        for i in 0..1000 {
            // Point on the plane: pick x, z, solve y; 30% outliers spread in a box.
            let (x, z) = (u() * 20.0 - 10.0, 3.0 + u() * 40.0);
            if i % 10 < 3 {
                pts.push(Vector3::new(x, u() * 6.0 - 4.0, z).cast());
            } else {
                let y = -(h + n.x * x + n.z * z) / n.y + (u() - 0.5) * 0.02;
                pts.push(Vector3::new(x, y, z).cast());
            }
        }
        let fit = PlaneFitter::new(PlaneParams::default()).fit(&pts).unwrap();
        assert!((fit.height - h).abs() < 0.02, "height {}", fit.height);
        assert!(
            (fit.roll - roll).abs() < 0.3f64.to_radians(),
            "roll {}",
            fit.roll
        );
        assert!(
            (fit.pitch - pitch).abs() < 0.3f64.to_radians(),
            "pitch {}",
            fit.pitch
        );
        assert!(
            fit.inliers >= 650 && fit.inliers <= 760,
            "inliers {}",
            fit.inliers
        );
        let level = fit.level_from_camera() * fit.normal;
        assert!((level - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-9);
    }

    #[test]
    fn too_few_points_is_an_error() {
        let pts = vec![Vector3::new(0.0f32, 1.0, 5.0); 3];
        assert!(matches!(
            PlaneFitter::new(PlaneParams::default()).fit(&pts),
            Err(PlaneError::TooFewPoints { .. })
        ));
    }
}
