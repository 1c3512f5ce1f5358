//! Scoring detections against ground truth: per water body in view, detected or not and its range;
//! per accepted region, whether it is false (little overlap with true water).

use crate::geometry::FrameGeometry;
use messages::{truth_class, water_cue, CameraModel, Pose};

/// A true water body (a puddle disc or ellipse) with its surface elevation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthBody {
    pub id: u32,
    pub center: [f64; 2],
    /// Semi-axes along east and north (m).
    pub radii: [f64; 2],
    pub elevation_m: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalParams {
    /// A body is in view when at least this many of its pixels are.
    pub min_truth_pixels: u32,
    /// A body is detected when accepted water covers at least this share of its pixels.
    pub detect_share: f32,
    /// An accepted region is false when less than this share of it is true water.
    pub false_share: f32,
}

impl Default for EvalParams {
    fn default() -> Self {
        Self {
            min_truth_pixels: 40,
            detect_share: 0.2,
            false_share: 0.2,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyScore {
    pub id: u32,
    pub truth_pixels: u32,
    pub water_pixels: u32,
    pub detected: bool,
    /// Horizontal range (m) from the vehicle to the body's nearest visible point.
    pub range_m: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionScore {
    pub label: u32,
    pub pixels: u32,
    /// Share of the region on true water.
    pub truth_share: f32,
    pub is_false: bool,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameScore {
    pub bodies: Vec<BodyScore>,
    pub regions: Vec<RegionScore>,
}

impl FrameScore {
    pub fn has_false_region(&self) -> bool {
        self.regions.iter().any(|r| r.is_false)
    }
}

/// Which body each true water pixel belongs to: `out[i]` is the body's index + 1, 0 for none.
/// Pixels labelled puddle or water are back-projected with the true disparity and given to the body
/// whose (slightly enlarged) outline contains them. Returns each body's nearest range through
/// `ranges` (infinite when not in view).
#[allow(clippy::too_many_arguments)]
pub fn assign_bodies(
    width: usize,
    labels: &[u8],
    truth_disparity: &[f32],
    camera: &CameraModel,
    vehicle: &Pose,
    bodies: &[TruthBody],
    out: &mut Vec<u16>,
    ranges: &mut Vec<f64>,
) {
    let geo = FrameGeometry::new(camera, vehicle);
    out.clear();
    out.resize(labels.len(), 0);
    ranges.clear();
    ranges.resize(bodies.len(), f64::INFINITY);
    for (i, (&l, &d)) in labels.iter().zip(truth_disparity).enumerate() {
        if (l != truth_class::PUDDLE && l != truth_class::WATER) || !(d.is_finite() && d > 0.0) {
            continue;
        }
        let (u, v) = ((i % width) as f64, (i / width) as f64);
        let z = geo.depth(d);
        let ray = geo.ray(u, v);
        let (x, y) = (geo.origin[0] + z * ray[0], geo.origin[1] + z * ray[1]);
        let mut best = (f64::INFINITY, 0usize);
        for (k, b) in bodies.iter().enumerate() {
            let q =
                ((x - b.center[0]) / b.radii[0]).powi(2) + ((y - b.center[1]) / b.radii[1]).powi(2);
            if q < best.0 {
                best = (q, k);
            }
        }
        if best.0 <= 1.3 * 1.3 {
            out[i] = best.1 as u16 + 1;
            let r = ((x - geo.vehicle[0]).powi(2) + (y - geo.vehicle[1]).powi(2)).sqrt();
            ranges[best.1] = ranges[best.1].min(r);
        }
    }
}

/// Scores one frame. `body_of` comes from [`assign_bodies`]; `mask` and `region_labels` from the
/// detector, `accepted` lists the accepted regions' labels and pixel counts.
pub fn score_frame(
    body_of: &[u16],
    ranges: &[f64],
    bodies: &[TruthBody],
    mask: &[u8],
    region_labels: &[u32],
    accepted: &[(u32, u32)],
    p: &EvalParams,
) -> FrameScore {
    let mut truth = vec![0u32; bodies.len()];
    let mut hit = vec![0u32; bodies.len()];
    let mut on_truth = vec![0u32; accepted.len()];
    for i in 0..body_of.len() {
        let b = body_of[i] as usize;
        if b > 0 {
            truth[b - 1] += 1;
            hit[b - 1] += (mask[i] & water_cue::WATER != 0) as u32;
        }
        let l = region_labels[i];
        if l != 0 && b > 0 {
            if let Some(k) = accepted.iter().position(|a| a.0 == l) {
                on_truth[k] += 1;
            }
        }
    }
    let bodies = bodies
        .iter()
        .enumerate()
        .filter(|(k, _)| truth[*k] >= p.min_truth_pixels)
        .map(|(k, b)| BodyScore {
            id: b.id,
            truth_pixels: truth[k],
            water_pixels: hit[k],
            detected: hit[k] as f32 >= p.detect_share * truth[k] as f32,
            range_m: ranges[k],
        })
        .collect();
    let regions = accepted
        .iter()
        .zip(&on_truth)
        .map(|(&(label, pixels), &t)| {
            let share = t as f32 / pixels.max(1) as f32;
            RegionScore {
                label,
                pixels,
                truth_share: share,
                is_false: share < p.false_share,
            }
        })
        .collect();
    FrameScore { bodies, regions }
}

/// Detection counts per range bin over many frames.
#[derive(Clone, Debug, PartialEq)]
pub struct RangeTable {
    /// Upper edges of the bins (m); the last bin is open.
    pub edges: Vec<f64>,
    pub seen: Vec<u32>,
    pub detected: Vec<u32>,
}

impl RangeTable {
    pub fn new(edges: &[f64]) -> Self {
        Self {
            edges: edges.to_vec(),
            seen: vec![0; edges.len() + 1],
            detected: vec![0; edges.len() + 1],
        }
    }

    pub fn bin(&self, range: f64) -> usize {
        self.edges
            .iter()
            .position(|&e| range < e)
            .unwrap_or(self.edges.len())
    }

    pub fn add(&mut self, b: &BodyScore) {
        let k = self.bin(b.range_m);
        self.seen[k] += 1;
        self.detected[k] += b.detected as u32;
    }

    /// Detection rate over bodies nearer than `range` (m).
    pub fn rate_within(&self, range: f64) -> Option<f64> {
        let k = self.bin(range - 1e-9);
        let (s, d) = (0..=k)
            .filter(|&i| i == 0 || self.edges[i - 1] < range)
            .fold((0, 0), |(s, d), i| (s + self.seen[i], d + self.detected[i]));
        (s > 0).then(|| d as f64 / s as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> (CameraModel, Pose) {
        let cam = CameraModel {
            fx: 100.0,
            fy: 100.0,
            cx: 9.5,
            cy: 4.5,
            baseline_m: 0.5,
            mount: Pose {
                position: [0.0, 0.0, 2.0],
                pitch: 0.3,
                ..Pose::default()
            },
        };
        (cam, Pose::default())
    }

    #[test]
    fn pixels_go_to_the_body_they_see_and_range_is_the_nearest() {
        let (cam, pose) = (camera().0, camera().1);
        let geo = FrameGeometry::new(&cam, &pose);
        let (w, h) = (20, 10);
        let bodies = [
            TruthBody {
                id: 7,
                center: [8.0, 0.0],
                radii: [3.0, 3.0],
                elevation_m: 0.0,
            },
            TruthBody {
                id: 9,
                center: [30.0, 0.0],
                radii: [1.0, 1.0],
                elevation_m: 0.0,
            },
        ];
        let mut labels = vec![truth_class::TRAIL; w * h];
        let mut disp = vec![f32::NAN; w * h];
        for v in 0..h {
            for u in 0..w {
                if let Some(p) = geo.intersect_plane(u as f64, v as f64, 0.0) {
                    let i = v * w + u;
                    let ray = geo.ray(u as f64, v as f64);
                    let z = (p[0] - geo.origin[0]) / ray[0];
                    disp[i] = (cam.fx * cam.baseline_m / z) as f32;
                    if (p[0] - 8.0).hypot(p[1]) < 3.0 {
                        labels[i] = truth_class::PUDDLE;
                    }
                }
            }
        }
        let (mut of, mut ranges) = (Vec::new(), Vec::new());
        assign_bodies(
            w,
            &labels,
            &disp,
            &cam,
            &pose,
            &bodies,
            &mut of,
            &mut ranges,
        );
        let n = of.iter().filter(|&&b| b == 1).count();
        assert!(n > 10, "{n}");
        assert!(of.iter().all(|&b| b != 2));
        assert!(ranges[0] > 4.5 && ranges[0] < 6.5, "{}", ranges[0]);
        assert!(ranges[1].is_infinite());
    }

    #[test]
    fn detection_and_false_regions_are_scored() {
        // 10 pixels: 0..4 body 1, 4..6 nothing, 6..10 body 2.
        let body_of = [1, 1, 1, 1, 0, 0, 2, 2, 2, 2u16];
        let w = water_cue::WATER;
        // Region 1 covers body 1 (and one dry pixel); region 2 is all dry; body 2 has one water pixel.
        let mask = [w, w, w, 0, w, 0, 0, 0, 0, w];
        let labels = [1, 1, 1, 0, 1, 0, 0, 0, 0, 2u32];
        let bodies = [
            TruthBody {
                id: 1,
                center: [0.0; 2],
                radii: [1.0; 2],
                elevation_m: 0.0,
            },
            TruthBody {
                id: 2,
                center: [5.0; 2],
                radii: [1.0; 2],
                elevation_m: 0.0,
            },
        ];
        let p = EvalParams {
            min_truth_pixels: 2,
            detect_share: 0.5,
            false_share: 0.5,
        };
        let s = score_frame(
            &body_of,
            &[7.0, 12.0],
            &bodies,
            &mask,
            &labels,
            &[(1, 4), (2, 1)],
            &p,
        );
        assert_eq!(s.bodies.len(), 2);
        assert!(s.bodies[0].detected && s.bodies[0].water_pixels == 3);
        assert!(!s.bodies[1].detected, "1 of 4 pixels is below the share");
        assert!(!s.regions[0].is_false);
        assert!((s.regions[0].truth_share - 0.75).abs() < 1e-6);
        // Region 2's single pixel lies on body 2: it is true water.
        assert!(!s.regions[1].is_false);
        let s = score_frame(
            &body_of,
            &[7.0, 12.0],
            &bodies,
            &mask,
            &labels,
            &[(1, 4), (2, 1)],
            &EvalParams {
                false_share: 0.8,
                ..p
            },
        );
        assert!(
            s.has_false_region(),
            "75% on truth is false at an 80% threshold"
        );

        let mut t = RangeTable::new(&[7.0, 10.0, 15.0]);
        for b in &s.bodies {
            t.add(b);
        }
        assert_eq!(t.seen, vec![0, 1, 1, 0]);
        assert_eq!(t.detected, vec![0, 1, 0, 0]);
        assert_eq!(t.rate_within(10.0), Some(1.0));
        assert_eq!(t.rate_within(15.0), Some(0.5));
        assert_eq!(t.rate_within(7.0), None);
    }
}
