//! The water a followed target has just crossed, as the polyline of its recent positions
//! ("breadcrumbs"). The world map holds the cells its hull and wash left for seconds; they are no
//! obstacle to a boat that follows it, but a straight lane astern of the target misses them once
//! it turns and sweeps water it never crossed. The trail is where it actually went.

use std::collections::VecDeque;

/// Recent positions of the followed target (ENU, m), newest first, spanning at most a set path
/// length. Owned by the sequencer, fed once per cycle.
#[derive(Debug, Clone, Default)]
pub struct WakeTrail {
    crumbs: VecDeque<[f64; 2]>,
}

/// A new crumb is laid each time the target has gone this far (m) from the previous one; in
/// between, the newest crumb moves with it. Much finer than the 4 m half-width of the exempt
/// band, so a turn is followed closely; at 7 m/s and 10 cycles a second, one crumb a cycle.
const SPACING_M: f64 = 1.0;

impl WakeTrail {
    /// Takes this cycle's target position (`None`: not following) and keeps `length_m` of path
    /// behind it. A position farther than `jump_m` from the newest crumb is another target, or the
    /// same one re-acquired elsewhere: the trail restarts there.
    pub fn update(&mut self, target: Option<[f64; 2]>, length_m: f64, jump_m: f64) {
        let Some(p) = target.filter(|p| p.iter().all(|v| v.is_finite())) else {
            self.crumbs.clear();
            return;
        };
        if self.crumbs.front().is_some_and(|&q| dist(p, q) > jump_m) {
            self.crumbs.clear();
        }
        match self.crumbs.get(1) {
            Some(&second) if dist(p, second) < SPACING_M => self.crumbs[0] = p,
            _ => self.crumbs.push_front(p),
        }
        // Keep the first crumb at or beyond `length_m` of path so the trail spans all of it.
        let mut path = 0.0;
        let mut keep = self.crumbs.len();
        for (k, w) in self
            .crumbs
            .iter()
            .zip(self.crumbs.iter().skip(1))
            .enumerate()
        {
            path += dist(*w.0, *w.1);
            if path >= length_m {
                keep = k + 2;
                break;
            }
        }
        self.crumbs.truncate(keep);
    }

    /// The trail, newest first, contiguous for a [`Band`].
    pub fn points(&mut self) -> &[[f64; 2]] {
        self.crumbs.make_contiguous()
    }
}

/// The water within `half_width_m` of a polyline, with its bounding box so that the many hazards
/// far from the trail cost one comparison each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band<'a> {
    points: &'a [[f64; 2]],
    half_width_m: f64,
    lo: [f64; 2],
    hi: [f64; 2],
}

impl<'a> Band<'a> {
    pub fn new(points: &'a [[f64; 2]], half_width_m: f64) -> Self {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in points {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k] - half_width_m);
                hi[k] = hi[k].max(p[k] + half_width_m);
            }
        }
        Self {
            points,
            half_width_m,
            lo,
            hi,
        }
    }

    /// No water at all.
    pub fn empty() -> Self {
        Self::new(&[], 0.0)
    }

    pub fn contains(&self, p: [f64; 2]) -> bool {
        (0..2).all(|k| (self.lo[k]..=self.hi[k]).contains(&p[k]))
            && distance_to_polyline(p, self.points) <= self.half_width_m
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Distance (m) from `p` to the polyline through `points` (a single point: distance to it; none:
/// infinite).
fn distance_to_polyline(p: [f64; 2], points: &[[f64; 2]]) -> f64 {
    match points {
        [] => f64::INFINITY,
        [only] => dist(p, *only),
        _ => points
            .windows(2)
            .map(|w| distance_to_segment(p, w[0], w[1]))
            .fold(f64::INFINITY, f64::min),
    }
}

fn distance_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (ux, uy) = (b[0] - a[0], b[1] - a[1]);
    let (vx, vy) = (p[0] - a[0], p[1] - a[1]);
    let len2 = ux * ux + uy * uy;
    let t = if len2 > 0.0 {
        ((vx * ux + vy * uy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (vx - t * ux).hypot(vy - t * uy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds positions along `path` (a function of time) at 10 Hz for `seconds`; returns the last.
    fn run(trail: &mut WakeTrail, seconds: f64, path: impl Fn(f64) -> [f64; 2]) -> [f64; 2] {
        let mut last = [f64::NAN; 2];
        for k in 0..=(seconds * 10.0) as usize {
            last = path(k as f64 * 0.1);
            trail.update(Some(last), 20.0, 8.0);
        }
        last
    }

    #[test]
    fn the_trail_follows_a_turn_and_spans_the_set_path_length() {
        // 7 m/s north for 3 s, then a 90 deg turn to the east at 15 m radius (2.2 s), then east.
        let r = 15.0;
        let quarter = 0.5 * std::f64::consts::PI * r / 7.0;
        let path = |t: f64| {
            if t <= 3.0 {
                [0.0, 7.0 * t]
            } else if t <= 3.0 + quarter {
                let a = 7.0 * (t - 3.0) / r;
                [r - r * a.cos(), 21.0 + r * a.sin()]
            } else {
                [r + 7.0 * (t - 3.0 - quarter), 21.0 + r]
            }
        };
        let mut trail = WakeTrail::default();
        let last = run(&mut trail, 3.0 + quarter + 1.0, path);
        let pts = trail.points().to_vec();
        assert_eq!(pts[0], last, "newest first");
        // About 20 m of path: 7 m along the east leg, the 23.6 m arc's last 13 m.
        let length: f64 = pts.windows(2).map(|w| dist(w[0], w[1])).sum();
        assert!((20.0..22.0).contains(&length), "path length {length}");
        // On the arc the trail stays within a few centimetres of the true path ...
        let on_arc = path(3.0 + 0.5 * quarter);
        assert!(distance_to_polyline(on_arc, &pts) < 0.1);
        // ... while the straight line astern of the target along its present course (west)
        // passes 4 m or more from the water it went over there.
        assert!(distance_to_polyline(on_arc, &[pts[0], [-100.0, 21.0 + r]]) > 4.0);
        // Water crossed more than 20 m of path ago is no longer in the trail.
        assert!(distance_to_polyline(path(2.0), &pts) > 4.0);
    }

    #[test]
    fn a_jump_or_the_end_of_following_restarts_the_trail() {
        let mut trail = WakeTrail::default();
        run(&mut trail, 2.0, |t| [0.0, 5.0 * t]);
        assert!(trail.points().len() > 5);
        // Another target 30 m away: the old water is not its wake.
        trail.update(Some([30.0, 10.0]), 20.0, 8.0);
        assert_eq!(trail.points(), &[[30.0, 10.0]]);
        trail.update(None, 20.0, 8.0);
        assert!(trail.points().is_empty());
        // A non-finite position is no position.
        trail.update(Some([f64::NAN, 0.0]), 20.0, 8.0);
        assert!(trail.points().is_empty());
    }

    #[test]
    fn distance_to_a_polyline_is_to_its_nearest_segment() {
        let line = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]];
        assert_eq!(distance_to_polyline([5.0, 3.0], &line), 3.0);
        assert_eq!(distance_to_polyline([13.0, 5.0], &line), 3.0);
        assert_eq!(distance_to_polyline([-4.0, -3.0], &line), 5.0);
        assert_eq!(distance_to_polyline([1.0, 1.0], &line[..1]), 2f64.sqrt());
        assert_eq!(distance_to_polyline([1.0, 1.0], &[]), f64::INFINITY);
        let band = Band::new(&line, 3.0);
        assert!(band.contains([5.0, 3.0]) && band.contains([13.0, 5.0]));
        assert!(!band.contains([5.0, 3.1]) && !band.contains([5.0, 8.0]));
        assert!(!Band::empty().contains([0.0, 0.0]));
    }
}
