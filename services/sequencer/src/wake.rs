//! The water a followed target has just crossed, as the polyline of its recent positions
//! ("breadcrumbs"). The world map holds the cells its hull and wash left for seconds; they are no
//! obstacle to a boat that follows it, but a straight lane astern of the target misses them once
//! it turns and sweeps water it never crossed. The trail is where it actually went.

use std::collections::VecDeque;

use crate::arcs::FollowedTarget;

/// Recent positions of the followed target (ENU, m), newest first, spanning at most a set path
/// length, and astern of the oldest one the water it crossed before it was followed. Owned by the
/// sequencer, fed once per cycle.
#[derive(Debug, Clone, Default)]
pub struct WakeTrail {
    crumbs: VecDeque<[f64; 2]>,
    /// The target's course (rad, ENU) when the trail (re)started.
    start_course: f64,
    /// The crumbs and the tail astern of the oldest, as [`WakeTrail::points`] hands them out.
    line: Vec<[f64; 2]>,
}

/// A new crumb is laid each time the target has gone this far (m) from the previous one; in
/// between, the newest crumb moves with it. Much finer than the 4 m half-width of the exempt
/// band, so a turn is followed closely; at 7 m/s and 10 cycles a second, one crumb a cycle.
const SPACING_M: f64 = 1.0;

/// How long (s) the map holds what a moving boat leaves behind: its 3-observation average, the
/// hazard decay and the wash itself (in follow_boat's log a wake cell stayed lethal for 4 s). A
/// target that was already under way when it was first followed left that much water astern of
/// where it was, along its course: as far back as it went in this time, and no farther than the
/// trail's length, that water is in the trail too. Without it, a trail just started covers only
/// the metres the target has gone since: in follow_boat (seeds 38 and 40) the smear astern of a
/// 7 m/s target 55 m ahead blocked the arcs towards it from about 2 s after it was first
/// followed; the boat turned away and never closed in.
const WAKE_HELD_S: f64 = 3.0;

impl WakeTrail {
    /// Takes this cycle's target (`None`: not following) and keeps `length_m` of path behind it.
    /// A position farther than `jump_m` from the newest crumb is another target, or the same one
    /// re-acquired elsewhere: the trail restarts there.
    pub fn update(&mut self, target: Option<&FollowedTarget>, length_m: f64, jump_m: f64) {
        self.line.clear();
        let Some(t) = target.filter(|t| {
            t.position
                .iter()
                .chain(&t.velocity)
                .chain([&t.course])
                .all(|v| v.is_finite())
        }) else {
            self.crumbs.clear();
            return;
        };
        let p = t.position;
        if self.crumbs.front().is_some_and(|&q| dist(p, q) > jump_m) {
            self.crumbs.clear();
        }
        if self.crumbs.is_empty() {
            self.start_course = t.course;
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
        self.line.extend(self.crumbs.iter());
        let speed = t.velocity[0].hypot(t.velocity[1]);
        let tail = (length_m - path).min(speed * WAKE_HELD_S);
        if let Some(&oldest) = self.crumbs.back().filter(|_| tail > 0.0) {
            let (s, c) = self.start_course.sin_cos();
            self.line.push([oldest[0] - tail * c, oldest[1] - tail * s]);
        }
    }

    /// The trail, newest first, for a [`Band`].
    pub fn points(&self) -> &[[f64; 2]] {
        &self.line
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

    /// The target at `position` moving at `velocity` (its course along it).
    fn target(position: [f64; 2], velocity: [f64; 2]) -> FollowedTarget {
        FollowedTarget {
            position,
            velocity,
            course: velocity[1].atan2(velocity[0]),
        }
    }

    /// Feeds positions along `path` (a function of time) at 10 Hz for `seconds`; returns the last.
    fn run(trail: &mut WakeTrail, seconds: f64, path: impl Fn(f64) -> [f64; 2]) -> [f64; 2] {
        let mut last = [f64::NAN; 2];
        for k in 0..=(seconds * 10.0) as usize {
            let t = k as f64 * 0.1;
            let (p, ahead) = (path(t), path(t + 0.01));
            let velocity = [(ahead[0] - p[0]) / 0.01, (ahead[1] - p[1]) / 0.01];
            trail.update(Some(&target(p, velocity)), 20.0, 8.0);
            last = p;
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
        // Another target 30 m away, lying still: the old water is not its wake.
        trail.update(Some(&target([30.0, 10.0], [0.0, 0.0])), 20.0, 8.0);
        assert_eq!(trail.points(), &[[30.0, 10.0]]);
        trail.update(None, 20.0, 8.0);
        assert!(trail.points().is_empty());
        // A non-finite position or velocity is no target.
        trail.update(Some(&target([f64::NAN, 0.0], [1.0, 0.0])), 20.0, 8.0);
        assert!(trail.points().is_empty());
        trail.update(Some(&target([0.0, 0.0], [f64::NAN, 0.0])), 20.0, 8.0);
        assert!(trail.points().is_empty());
    }

    #[test]
    fn a_target_under_way_when_first_followed_has_its_wake_astern_in_the_trail() {
        // First followed at (0, 50) going north at 5 m/s: the 15 m it went in the last 3 s, along
        // its course, are its wake.
        let mut trail = WakeTrail::default();
        trail.update(Some(&target([0.0, 50.0], [0.0, 5.0])), 20.0, 8.0);
        let close = |a: [f64; 2], b: [f64; 2]| dist(a, b) < 1e-9;
        let pts = trail.points().to_vec();
        assert!(pts.len() == 2 && close(pts[0], [0.0, 50.0]) && close(pts[1], [0.0, 35.0]));
        let band = Band::new(trail.points(), 4.0);
        assert!(band.contains([1.0, 40.0]) && band.contains([-3.5, 36.0]));
        assert!(!band.contains([0.0, 30.0]) && !band.contains([5.0, 45.0]));
        // As it goes on, its own path takes over and the whole trail stays 20 m long.
        let last = run(&mut trail, 2.0, |t| [0.0, 50.0 + 5.0 * t]);
        let pts = trail.points().to_vec();
        assert_eq!(pts[0], last);
        assert!(close(pts[pts.len() - 1], [0.0, 40.0]), "{pts:?}");
        // A boat lying still leaves no wake: only the water it lies on.
        let mut still = WakeTrail::default();
        still.update(Some(&target([0.0, 50.0], [0.0, 0.0])), 20.0, 8.0);
        assert_eq!(still.points(), &[[0.0, 50.0]]);
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
