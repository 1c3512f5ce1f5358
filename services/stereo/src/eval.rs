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
