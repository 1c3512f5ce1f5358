//! Per-frame cache of the sky dome (gradient + clouds) over directions, so the many rays that end in
//! the sky (directly or via water reflections) cost a bilinear lookup instead of fractal noise.
//! Clouds are treated as infinitely far (no parallax between eyes or reflection points), which is
//! what stereo sees of them anyway: zero disparity. The sun stays analytic (it is sharp).

use crate::math::{mix, V3};
use crate::world::Sky;
use rayon::prelude::*;

/// Azimuth texels over 360 degrees and rows over the upper hemisphere (row = sqrt(d.z), so the
/// horizon, where clouds are small, gets the finest rows).
const W: usize = 1024;
const H: usize = 256;

/// Clouds drift a fraction of a texel per second, so the dome is refilled on a fixed time grid
/// (deterministic: the content depends only on the quantised time, not on the call history).
const REFILL_PERIOD: f64 = 0.5;

#[derive(Default)]
pub(crate) struct SkyCache {
    data: Vec<V3>,
    filled_at: Option<f64>,
}

impl SkyCache {
    /// Makes the cache valid for time `t`.
    pub fn update(&mut self, sky: &Sky, t: f64) {
        let tq = (t / REFILL_PERIOD).floor() * REFILL_PERIOD;
        if self.filled_at != Some(tq) {
            self.fill(sky, tq as f32);
            self.filled_at = Some(tq);
        }
    }

    fn fill(&mut self, sky: &Sky, t: f32) {
        self.data.resize(W * H, V3::zeros());
        self.data
            .par_chunks_mut(W)
            .enumerate()
            .for_each(|(j, row)| {
                let v = j as f32 / (H - 1) as f32;
                let z = v * v;
                let r = (1.0 - z * z).max(0.0).sqrt();
                for (i, px) in row.iter_mut().enumerate() {
                    let a = i as f32 / W as f32 * std::f32::consts::TAU;
                    let d = V3::new(r * a.cos(), r * a.sin(), z);
                    *px = sky.dome(V3::zeros(), d, t);
                }
            });
    }

    /// Dome radiance for a unit direction with `d.z >= 0`.
    #[inline]
    pub fn lookup(&self, d: V3) -> V3 {
        let a = fast_atan2(d.y, d.x);
        let fu = (a * (1.0 / std::f32::consts::TAU)).rem_euclid(1.0) * W as f32;
        let fv = d.z.clamp(0.0, 1.0).sqrt() * (H - 1) as f32;
        let (i, j) = ((fu as usize).min(W - 1), (fv as usize).min(H - 2));
        let (tu, tv) = (fu - i as f32, fv - j as f32);
        let i1 = (i + 1) % W;
        let row0 = &self.data[j * W..(j + 1) * W];
        let row1 = &self.data[(j + 1) * W..(j + 2) * W];
        mix(mix(row0[i], row0[i1], tu), mix(row1[i], row1[i1], tu), tv)
    }
}

/// atan2 to ~1e-4 rad (polynomial on the octant), for cache addressing.
#[inline(always)]
fn fast_atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (num, den) = if ax > ay { (ay, ax) } else { (ax, ay) };
    if den == 0.0 {
        return 0.0;
    }
    let q = num / den;
    let q2 = q * q;
    let mut r =
        q * (0.999_866 + q2 * (-0.330_299 + q2 * (0.180_141 + q2 * (-0.085_133 + q2 * 0.020_835))));
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        -r
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atan2_is_close() {
        for i in 0..720 {
            let a = (i as f32 - 360.0).to_radians() * 0.999;
            let (y, x) = (a.sin() * 3.0, a.cos() * 3.0);
            assert!((fast_atan2(y, x) - y.atan2(x)).abs() < 2e-4, "{a}");
        }
    }

    #[test]
    fn cache_matches_direct_evaluation_smoothly() {
        let sky = Sky::new(1.0, 0.5, 0.5, 7);
        let mut c = SkyCache::default();
        c.fill(&sky, 3.0);
        for k in 0..200 {
            let d = V3::new(
                (k as f32 * 0.1).cos(),
                (k as f32 * 0.1).sin(),
                0.05 + k as f32 * 0.004,
            )
            .normalize();
            let err = (c.lookup(d) - sky.dome(V3::zeros(), d, 3.0)).norm();
            assert!(err < 0.08, "{k}: {err}");
        }
    }
}
