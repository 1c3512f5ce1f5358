//! A vessel-relative clutter map: how many detections per map no confirmed object explains, by
//! sector around the own vessel (bearing from the bow, range ring), exponentially averaged.
//!
//! Why vessel-relative: the stereo mismatches that make false detections depend on how the heads
//! look at the waves (measured on follow_boat: far water on one head's side gave 8-11 % hazard
//! cells a map, on the other side 0.2-1.4 %, and the pattern moved with the wave direction), so
//! they stay at a bearing from the bow while the vessel moves. A world-anchored map would smear
//! them along the track and never learn them.
//!
//! The tracker asks [`ClutterMap::rate`] where a tentative track is detected and confirms it on
//! the stricter rule where the clutter is dense: the radar tracker's clutter map, which keeps the
//! quick confirmation where the water is clean (the target ahead, a buoy in a quiet sector).

use nalgebra::Vector2;

/// Width of a bearing sector (deg).
pub const SECTOR_DEG: f64 = 10.0;
/// Depth of a range ring (m).
pub const RING_M: f64 = 20.0;
const SECTORS: usize = (360.0 / SECTOR_DEG) as usize;
/// Rings out to 160 m; farther detections share the last one.
const RINGS: usize = 8;

#[derive(Debug, Clone)]
pub struct ClutterMap {
    /// Unexplained detections per map, per (ring, sector).
    rate: Vec<f32>,
    /// Detections counted in the current map, per (ring, sector).
    counts: Vec<u16>,
    tau_s: f64,
}

impl ClutterMap {
    /// `tau_s`: time constant of the average (s).
    pub fn new(tau_s: f64) -> Self {
        Self {
            rate: vec![0.0; SECTORS * RINGS],
            counts: vec![0; SECTORS * RINGS],
            tau_s,
        }
    }

    /// Sector index of `position` seen from `own` with heading `yaw` (ENU, rad).
    fn index(own: Vector2<f64>, yaw: f64, position: [f64; 2]) -> usize {
        let d = Vector2::new(position[0], position[1]) - own;
        let bearing = (d.y.atan2(d.x) - yaw).to_degrees().rem_euclid(360.0);
        let sector = ((bearing / SECTOR_DEG) as usize).min(SECTORS - 1);
        let ring = ((d.norm() / RING_M) as usize).min(RINGS - 1);
        ring * SECTORS + sector
    }

    /// Counts one unexplained detection of the current map.
    pub fn count(&mut self, own: Vector2<f64>, yaw: f64, position: [f64; 2]) {
        let c = &mut self.counts[Self::index(own, yaw, position)];
        *c = c.saturating_add(1);
    }

    /// Folds the current map's counts into the averages (`dt_s`: time since the previous map;
    /// 0 for the first map, which then sets nothing) and clears them.
    pub fn end_map(&mut self, dt_s: f64) {
        // A map's counts are a rate of one map; weigh them by elapsed time, so a set running at
        // another frame rate learns over the same seconds.
        let alpha = (1.0 - (-dt_s / self.tau_s).exp()) as f32;
        for (r, c) in self.rate.iter_mut().zip(&mut self.counts) {
            *r += alpha * (*c as f32 - *r);
            *c = 0;
        }
    }

    /// Unexplained detections per map in the sector of `position`.
    pub fn rate(&self, own: Vector2<f64>, yaw: f64, position: [f64; 2]) -> f32 {
        self.rate[Self::index(own, yaw, position)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.2;

    #[test]
    fn a_sector_with_detections_every_map_learns_its_rate_and_others_stay_clean() {
        let mut m = ClutterMap::new(10.0);
        let own = Vector2::new(100.0, -50.0);
        // Heading north; 45 m out, 45 deg to starboard of the bow (north-east of the vessel).
        let yaw = 90f64.to_radians();
        let hot = [
            own.x + 45.0 * 45f64.to_radians().cos(),
            own.y + 45.0 * 45f64.to_radians().sin(),
        ];
        for _ in 0..500 {
            m.count(own, yaw, hot);
            m.end_map(DT);
        }
        assert!((m.rate(own, yaw, hot) - 1.0).abs() < 0.01);
        // The mirror sector to port and the bow sector learned nothing.
        let port = [own.x - 45.0 * 45f64.to_radians().cos(), hot[1]];
        assert_eq!(m.rate(own, yaw, port), 0.0);
        assert_eq!(m.rate(own, yaw, [own.x, own.y + 45.0]), 0.0);
    }

    #[test]
    fn the_map_turns_with_the_vessel() {
        let mut m = ClutterMap::new(10.0);
        let own = Vector2::new(0.0, 0.0);
        // Heading east, clutter 30 m dead ahead.
        for _ in 0..200 {
            m.count(own, 0.0, [30.0, 0.0]);
            m.end_map(DT);
        }
        // Heading north, dead ahead is now north: the rate follows the bow.
        let north = 90f64.to_radians();
        assert!(m.rate(own, north, [0.0, 30.0]) > 0.9);
        assert_eq!(m.rate(own, north, [30.0, 0.0]), 0.0);
    }

    #[test]
    fn clutter_that_stops_is_forgotten_over_the_time_constant() {
        let mut m = ClutterMap::new(10.0);
        let own = Vector2::new(0.0, 0.0);
        for _ in 0..500 {
            m.count(own, 0.0, [50.0, 5.0]);
            m.end_map(DT);
        }
        // 10 s without detections: one time constant leaves 1/e.
        for _ in 0..50 {
            m.end_map(DT);
        }
        let r = m.rate(own, 0.0, [50.0, 5.0]);
        assert!((r - (-1f32).exp()).abs() < 0.02, "{r}");
        // The first map of a run sets nothing.
        let mut fresh = ClutterMap::new(10.0);
        fresh.count(own, 0.0, [50.0, 5.0]);
        fresh.end_map(0.0);
        assert_eq!(fresh.rate(own, 0.0, [50.0, 5.0]), 0.0);
    }
}
