//! Accuracy metrics against a ground-truth disparity (non-finite = unknown), Middlebury style.

use crate::disparity::DisparityMap;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Metrics {
    /// Produced pixels / ground-truth pixels (only pixels with known ground truth count).
    pub density: f64,
    /// Share of ground-truth pixels that are missing or off by more than 1 px (2 px).
    pub bad1_all: f64,
    pub bad2_all: f64,
    /// Share of produced pixels (with ground truth) off by more than 1 px (2 px).
    pub bad1_valid: f64,
    pub bad2_valid: f64,
    /// Mean absolute error over produced pixels, px.
    pub mae_valid: f64,
}

pub fn evaluate(disp: &DisparityMap, gt: &[f32]) -> Metrics {
    assert_eq!(disp.data.len(), gt.len(), "ground truth size");
    let (mut n_gt, mut n_valid, mut b1, mut b2, mut sum) = (0u64, 0u64, 0u64, 0u64, 0f64);
    for (&d, &g) in disp.data.iter().zip(gt) {
        if !g.is_finite() {
            continue;
        }
        n_gt += 1;
        if d < 0 {
            continue;
        }
        n_valid += 1;
        let e = (d as f64 / crate::disparity::DISP_SCALE as f64 - g as f64).abs();
        sum += e;
        b1 += (e > 1.0) as u64;
        b2 += (e > 2.0) as u64;
    }
    let (ng, nv) = (n_gt.max(1) as f64, n_valid.max(1) as f64);
    let missing = (n_gt - n_valid) as f64;
    Metrics {
        density: n_valid as f64 / ng,
        bad1_all: (b1 as f64 + missing) / ng,
        bad2_all: (b2 as f64 + missing) / ng,
        bad1_valid: b1 as f64 / nv,
        bad2_valid: b2 as f64 / nv,
        mae_valid: sum / nv,
    }
}

/// How far a fitted water plane is from the true water surface of the same frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneError {
    /// Angle between the fitted and the true plane normal (roll and pitch error together), degrees.
    pub tilt_deg: f64,
    /// Fitted minus true camera height above the plane, m.
    pub height_error_m: f64,
}

/// Compares a fitted plane (`normal . p + offset = 0` in the optical frame, unit normal up) with
/// the least-squares plane through `truth_points`, true 3D points of water pixels in the same
/// frame (waves average out). `None` with fewer than 50 points or points along a line.
pub fn plane_error(normal: [f64; 3], offset: f64, truth_points: &[[f64; 3]]) -> Option<PlaneError> {
    use nalgebra::{Matrix3, Vector3};
    if truth_points.len() < 50 {
        return None;
    }
    let n = truth_points.len() as f64;
    let centroid = truth_points
        .iter()
        .fold(Vector3::zeros(), |acc, p| acc + Vector3::from(*p))
        / n;
    let scatter = truth_points.iter().fold(Matrix3::zeros(), |acc, p| {
        let d = Vector3::from(*p) - centroid;
        acc + d * d.transpose()
    });
    let eigen = scatter.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
    // A plane needs spread in two directions.
    if eigen.eigenvalues[order[1]] <= 1e-9 * eigen.eigenvalues[order[2]].max(1e-12) {
        return None;
    }
    let mut true_normal: Vector3<f64> = eigen.eigenvectors.column(order[0]).into();
    // Up is the side the camera (the origin) is on.
    if true_normal.dot(&centroid) > 0.0 {
        true_normal = -true_normal;
    }
    let true_height = -true_normal.dot(&centroid);
    let fitted = Vector3::from(normal).normalize();
    Some(PlaneError {
        tilt_deg: fitted
            .dot(&true_normal)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees(),
        height_error_m: offset - true_height,
    })
}

#[cfg(test)]
mod plane_tests {
    use super::*;

    #[test]
    fn plane_error_measures_tilt_and_height_against_the_true_points() {
        // Water 3 m below a camera pitched down: in the optical frame (y down) the surface is
        // y cos(p) + z sin(p) = 3 ... with the normal pointing up (towards -y).
        let p = 4f64.to_radians();
        let up = [0.0, -p.cos(), -p.sin()];
        let points: Vec<[f64; 3]> = (0..20)
            .flat_map(|i| (0..20).map(move |j| (i, j)))
            .map(|(i, j)| {
                let (x, z) = (-10.0 + i as f64, 5.0 + 2.0 * j as f64);
                // Solve up . (x, y, z) + 3 = 0 for y, with a little wave.
                let wave = 0.05 * ((i * 7 + j * 3) % 5) as f64 - 0.1;
                let y = (3.0 + up[2] * z) / p.cos() + wave;
                [x, y, z]
            })
            .collect();
        let exact = plane_error(up, 3.0, &points).unwrap();
        assert!(exact.tilt_deg < 0.2, "{exact:?}");
        assert!(exact.height_error_m.abs() < 0.05, "{exact:?}");
        // A fit 1 deg off in roll and 0.5 m too high is reported as such.
        let r = 1f64.to_radians();
        let rolled = [up[1] * -r.sin(), up[1] * r.cos(), up[2]];
        let off = plane_error(rolled, 3.5, &points).unwrap();
        assert!((off.tilt_deg - 1.0).abs() < 0.2, "{off:?}");
        assert!((off.height_error_m - 0.5).abs() < 0.05, "{off:?}");
        assert!(plane_error(up, 3.0, &points[..10]).is_none());
    }
}
