//! The overview picture of a run (PNG, north up): every hazard the world map held during the run
//! (red, brighter = more likely), the true obstacles (white rings: buoys, markers, pylons; orange:
//! boats), the own track (green), confirmed contacts over time (dots: yellow boat, cyan marker,
//! magenta extended, grey other) and every few seconds the arc the sequencer chose (yellow curve
//! from the boat's position at the time).

use crate::observe::Observation;
use image::{Rgb, RgbImage};
use messages::{contact_class, truth_class};
use std::path::Path;

/// Longest side of the picture (px).
const MAX_SIDE_PX: f64 = 1400.0;
const MARGIN_M: f64 = 25.0;

struct Canvas {
    img: RgbImage,
    west: f64,
    north: f64,
    px_per_m: f64,
}

impl Canvas {
    fn px(&self, e: f64, n: f64) -> (i64, i64) {
        (
            ((e - self.west) * self.px_per_m).round() as i64,
            ((self.north - n) * self.px_per_m).round() as i64,
        )
    }

    fn put(&mut self, x: i64, y: i64, c: Rgb<u8>) {
        if x >= 0 && y >= 0 && (x as u32) < self.img.width() && (y as u32) < self.img.height() {
            self.img.put_pixel(x as u32, y as u32, c);
        }
    }

    fn dot(&mut self, e: f64, n: f64, radius_px: i64, c: Rgb<u8>) {
        let (x, y) = self.px(e, n);
        for dy in -radius_px..=radius_px {
            for dx in -radius_px..=radius_px {
                if dx * dx + dy * dy <= radius_px * radius_px {
                    self.put(x + dx, y + dy, c);
                }
            }
        }
    }

    fn ring(&mut self, e: f64, n: f64, radius_m: f64, c: Rgb<u8>) {
        let r = (radius_m * self.px_per_m).max(3.0);
        let steps = (r * 8.0).ceil() as usize;
        let (x, y) = self.px(e, n);
        for k in 0..steps {
            let a = k as f64 / steps as f64 * std::f64::consts::TAU;
            self.put(
                x + (r * a.cos()).round() as i64,
                y + (r * a.sin()).round() as i64,
                c,
            );
        }
    }

    /// Line between two world points (Bresenham).
    fn line(&mut self, a: [f64; 2], b: [f64; 2], c: Rgb<u8>) {
        let (mut x0, mut y0) = self.px(a[0], a[1]);
        let (x1, y1) = self.px(b[0], b[1]);
        let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
        let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
        let mut err = dx + dy;
        for _ in 0..=(dx.max(-dy) + 1) {
            self.put(x0, y0, c);
            if x0 == x1 && y0 == y1 {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x0 += sx;
            }
            if e2 <= dx {
                err += dx;
                y0 += sy;
            }
        }
    }
}

/// Writes the overview of `o` to `path`; `arcs` gives the curvature and length of each arc.
pub fn write(o: &Observation, arcs: &[(f64, f64)], path: &Path) -> anyhow::Result<()> {
    anyhow::ensure!(!o.track.is_empty(), "no ground truth track to draw");
    let (mut w, mut e, mut s, mut n) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let mut include = |x: f64, y: f64| {
        w = w.min(x);
        e = e.max(x);
        s = s.min(y);
        n = n.max(y);
    };
    for &(_, x, y, _) in &o.track {
        include(x, y);
    }
    // The picture is about the run: hazards and objects far from the track would only shrink it.
    let near_track = |x: f64, y: f64| {
        o.track
            .iter()
            .step_by(10)
            .any(|&(_, tx, ty, _)| (tx - x).hypot(ty - y) < 120.0)
    };
    for &(_, p, _) in o.truth_objects.values() {
        if near_track(p[0], p[1]) {
            include(p[0], p[1]);
        }
    }
    let (w, e, s, n) = (w - MARGIN_M, e + MARGIN_M, s - MARGIN_M, n + MARGIN_M);
    let px_per_m = (MAX_SIDE_PX / (e - w).max(n - s)).min(4.0);
    let size = |m: f64| ((m * px_per_m).ceil() as u32).max(1);
    let mut c = Canvas {
        img: RgbImage::from_pixel(size(e - w), size(n - s), Rgb([12, 28, 48])),
        west: w,
        north: n,
        px_per_m,
    };
    // Grid lines every 50 m for scale.
    let grid = Rgb([30, 50, 72]);
    let mut x = (w / 50.0).ceil() * 50.0;
    while x < e {
        c.line([x, s], [x, n], grid);
        x += 50.0;
    }
    let mut y = (s / 50.0).ceil() * 50.0;
    while y < n {
        c.line([w, y], [e, y], grid);
        y += 50.0;
    }
    let res = o.hazard_resolution_m;
    let cell_px = ((res * px_per_m).ceil() as i64).max(1);
    for (&(ce, cn), &hazard) in &o.hazard_cells {
        let (x0, y0) = c.px(ce as f64 * res, (cn + 1) as f64 * res);
        let shade = Rgb([hazard.max(120), 30, 30]);
        for dy in 0..cell_px {
            for dx in 0..cell_px {
                c.put(x0 + dx, y0 + dy, shade);
            }
        }
    }
    for &(class, p, radius) in o.truth_objects.values() {
        let colour = if class == truth_class::BOAT {
            Rgb([255, 150, 40])
        } else {
            Rgb([235, 235, 235])
        };
        c.ring(p[0], p[1], radius as f64, colour);
    }
    for pair in o.track.windows(2) {
        c.line(
            [pair[0].1, pair[0].2],
            [pair[1].1, pair[1].2],
            Rgb([60, 220, 90]),
        );
    }
    for &(pose, chosen, _) in &o.arcs {
        let Some(&(curvature, length)) = arcs.get(chosen as usize) else {
            continue;
        };
        let (cy, sy) = (pose.yaw.cos(), pose.yaw.sin());
        let to_world = |b: [f64; 2]| {
            [
                pose.position[0] + cy * b[0] - sy * b[1],
                pose.position[1] + sy * b[0] + cy * b[1],
            ]
        };
        let steps = 20;
        let mut prev = to_world([0.0, 0.0]);
        for k in 1..=steps {
            let p = to_world(sequencer::arcs::Arc::point(
                curvature,
                length * k as f64 / steps as f64,
            ));
            c.line(prev, p, Rgb([250, 220, 60]));
            prev = p;
        }
    }
    for &(_, class, p) in &o.contact_trail {
        let colour = match class {
            contact_class::BOAT => Rgb([255, 230, 0]),
            contact_class::CHANNEL_MARKER => Rgb([0, 220, 255]),
            contact_class::EXTENDED => Rgb([230, 60, 230]),
            _ => Rgb([160, 160, 160]),
        };
        c.dot(p[0], p[1], 2, colour);
    }
    if let Some(&(_, x, y, _)) = o.track.last() {
        c.dot(x, y, 4, Rgb([60, 220, 90]));
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    c.img.save(path)?;
    Ok(())
}

/// Curvature and swept length of every arc of the sequencer configuration in `config` (TOML), or of
/// the default configuration.
pub fn arc_geometry(config: Option<&Path>) -> anyhow::Result<Vec<(f64, f64)>> {
    let cfg: sequencer::Config = runtime::config::load_or_default(config)?;
    let set = sequencer::arcs::ArcSet::new(&cfg.arcs, cfg.map_resolution_m)?;
    Ok(set
        .arcs()
        .iter()
        .map(|a| (a.curvature, a.extent_m))
        .collect())
}
