//! Ground detection (section 2): range points binned into the map's cells; a cell is ground when its
//! mode elevation has low variance (criterion 1) and lies near the minimum elevation of its radial
//! swath around the vehicle (criterion 2). Swaths are 2 m wide rings, split into bearing sectors,
//! spike-filtered and gap-filled along range.

use crate::config::GroundParams;
use rayon::prelude::*;

/// A point that does not fall into a map cell.
pub const NO_CELL: u32 = u32::MAX;

/// Cell grid shared by the ground detector and the terrain map: ENU-aligned, row 0 to the south.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub width: usize,
    pub height: usize,
    pub resolution: f64,
    /// ENU of the grid centre.
    pub center: [f64; 2],
}

impl Grid {
    pub fn cells(&self) -> usize {
        self.width * self.height
    }

    #[inline]
    pub fn cell_of(&self, x: f64, y: f64) -> u32 {
        let c = ((x - self.center[0]) / self.resolution + self.width as f64 / 2.0).floor();
        let r = ((y - self.center[1]) / self.resolution + self.height as f64 / 2.0).floor();
        if c >= 0.0 && r >= 0.0 && c < self.width as f64 && r < self.height as f64 {
            r as u32 * self.width as u32 + c as u32
        } else {
            NO_CELL
        }
    }

    #[inline]
    pub fn cell_center(&self, cell: usize) -> [f64; 2] {
        let (c, r) = (cell % self.width, cell / self.width);
        [
            self.center[0] + (c as f64 + 0.5 - self.width as f64 / 2.0) * self.resolution,
            self.center[1] + (r as f64 + 0.5 - self.height as f64 / 2.0) * self.resolution,
        ]
    }
}

/// `atan2` to about 0.1 degree, several times faster than libm's: sectors are tens of degrees wide
/// and this runs for every far range point.
#[inline]
pub fn fast_atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (ax, ay) = (x.abs(), y.abs());
    if ax == 0.0 && ay == 0.0 {
        return 0.0;
    }
    let (z, swap) = if ay > ax {
        (ax / ay, true)
    } else {
        (ay / ax, false)
    };
    let mut a = FRAC_PI_4 * z - z * (z - 1.0) * (0.2447 + 0.0663 * z);
    if swap {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 {
        -a
    } else {
        a
    }
}

/// Float to an unsigned key with the same order.
#[inline]
fn ordered(z: f32) -> u32 {
    let b = z.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b ^ 0x8000_0000
    }
}

#[inline]
fn unordered(k: u32) -> f32 {
    f32::from_bits(if k & 0x8000_0000 != 0 {
        k ^ 0x8000_0000
    } else {
        !k
    })
}

/// Per-cell statistics of one frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct CellStats {
    pub count: u32,
    /// Mode elevation (m), NaN without points.
    pub mode: f32,
    /// Standard deviation of the points close to the mode (m).
    pub std: f32,
    pub min: f32,
    pub max: f32,
    /// Criterion 1: enough points, low variance around the mode.
    pub flat: bool,
    /// Both criteria: the cell's mode is the ground.
    pub ground: bool,
}

pub struct Ground {
    params: GroundParams,
    pub grid: Grid,
    /// Vehicle position the swaths are centred on.
    vehicle: [f64; 2],
    keys: Vec<u64>,
    pub cells: Vec<CellStats>,
    /// Ground elevation of every cell: its mode where it is ground, else its swath's ground.
    pub elevation: Vec<f32>,
    rings: usize,
    sectors: usize,
    swath_min: Vec<f32>,
    swath_sum: Vec<f64>,
    swath_n: Vec<u32>,
    /// Ground elevation of each swath (ring-major: `ring * sectors + sector`), gap-filled.
    pub swath_ground: Vec<f32>,
    scratch: Vec<f32>,
    /// Elevation used when no ground was found anywhere.
    fallback: f32,
}

impl Ground {
    /// `max_range_m` bounds the swath map (points beyond use the last ring).
    pub fn new(params: GroundParams, max_range_m: f32) -> Self {
        let rings = ((max_range_m / params.swath_m.max(0.1)).ceil() as usize).max(1);
        let sectors = params.sectors.max(1);
        Self {
            params,
            grid: Grid {
                width: 0,
                height: 0,
                resolution: 1.0,
                center: [0.0; 2],
            },
            vehicle: [0.0; 2],
            keys: Vec::new(),
            cells: Vec::new(),
            elevation: Vec::new(),
            rings,
            sectors,
            swath_min: vec![f32::NAN; rings * sectors],
            swath_sum: vec![0.0; rings * sectors],
            swath_n: vec![0; rings * sectors],
            swath_ground: vec![f32::NAN; rings * sectors],
            scratch: Vec::with_capacity(rings),
            fallback: 0.0,
        }
    }

    pub fn params(&self) -> &GroundParams {
        &self.params
    }

    /// Swath index of a world position.
    #[inline]
    pub fn swath_of(&self, x: f64, y: f64) -> usize {
        let (dx, dy) = (x - self.vehicle[0], y - self.vehicle[1]);
        let range = (dx * dx + dy * dy).sqrt();
        let ring = ((range / self.params.swath_m as f64) as usize).min(self.rings - 1);
        let turn = (fast_atan2(dy, dx) / std::f64::consts::TAU).rem_euclid(1.0);
        let sector = ((turn * self.sectors as f64) as usize).min(self.sectors - 1);
        ring * self.sectors + sector
    }

    /// Ground elevation at a world position: the cell's when inside the grid, else the swath's.
    #[inline]
    pub fn ground_at(&self, x: f64, y: f64) -> f32 {
        match self.grid.cell_of(x, y) {
            NO_CELL => self.swath_ground[self.swath_of(x, y)],
            c => self.elevation[c as usize],
        }
    }

    /// Ground elevation of the nearest swath ahead that holds ground cells, if any (the paper's
    /// "closest ground elevation" for water seen beyond the range data).
    pub fn nearest_ground(&self) -> Option<f32> {
        (0..self.rings).find_map(|ring| {
            let s = ring * self.sectors;
            let (sum, n) = (s..s + self.sectors).fold((0.0, 0u32), |(a, k), i| {
                (a + self.swath_sum[i], k + self.swath_n[i])
            });
            (n > 0).then(|| (sum / n as f64) as f32)
        })
    }

    /// Runs ground detection on one frame's points: `cell[i]` is the cell of point `i` (or
    /// [`NO_CELL`]) and `elev[i]` its elevation. `fallback` is the elevation used when the frame has
    /// no ground at all (the vehicle's).
    pub fn update(
        &mut self,
        grid: Grid,
        vehicle: [f64; 2],
        cell: &[u32],
        elev: &[f32],
        fallback: f32,
    ) {
        self.grid = grid;
        self.vehicle = vehicle;
        self.fallback = fallback;
        let n = grid.cells();
        self.cells.clear();
        self.cells.resize(n, CellStats::default());
        self.elevation.clear();
        self.elevation.resize(n, f32::NAN);
        // Sort points by (cell, elevation) in one pass: the key order is both (section 2 binning).
        self.keys.clear();
        self.keys.extend(
            cell.iter()
                .zip(elev)
                .filter(|(&c, _)| c != NO_CELL)
                .map(|(&c, &z)| ((c as u64) << 32) | ordered(z) as u64),
        );
        self.keys.par_sort_unstable();
        for k in &self.keys {
            self.cells[(k >> 32) as usize].count += 1;
        }
        // Cell statistics in parallel; each cell finds its points from the running counts.
        let mut start = 0u32;
        for c in self.cells.iter_mut() {
            // Temporarily keep the start offset in `min`'s bits until the parallel pass below.
            c.min = f32::from_bits(start);
            start += c.count;
        }
        let p = &self.params;
        let keys = &self.keys;
        self.cells.par_iter_mut().for_each(|c| {
            let s = c.min.to_bits() as usize;
            let z = &keys[s..s + c.count as usize];
            *c = cell_stats(z, p);
        });
        self.swaths();
    }

    fn swaths(&mut self) {
        let p = self.params.clone();
        let (rings, sectors) = (self.rings, self.sectors);
        // The swath "minimum" is a low quantile of its flat cells' modes: mirror images of the
        // ground in water are flat too and lie below it, and must not become the minimum.
        self.swath_min.fill(f32::NAN);
        self.keys.clear();
        for i in 0..self.cells.len() {
            let c = self.cells[i];
            if c.flat {
                let [x, y] = self.grid.cell_center(i);
                let s = self.swath_of(x, y);
                self.keys.push(((s as u64) << 32) | ordered(c.mode) as u64);
            }
        }
        self.keys.sort_unstable();
        let mut a = 0;
        while a < self.keys.len() {
            let s = (self.keys[a] >> 32) as usize;
            let mut b = a;
            while b < self.keys.len() && (self.keys[b] >> 32) as usize == s {
                b += 1;
            }
            let k = a + ((b - a - 1) as f32 * p.min_quantile.clamp(0.0, 1.0)).round() as usize;
            self.swath_min[s] = unordered(self.keys[k] as u32);
            a = b;
        }
        // Spike filter along range, then gap filling by interpolation (section 2).
        for sector in 0..sectors {
            spike_filter(
                &mut self.swath_min,
                sector,
                sectors,
                rings,
                p.spike_m,
                &mut self.scratch,
            );
            fill_gaps(&mut self.swath_min, sector, sectors, rings);
        }
        // Criterion 2 and the swaths' ground elevation.
        self.swath_sum.fill(0.0);
        self.swath_n.fill(0);
        for i in 0..self.cells.len() {
            let c = self.cells[i];
            if !c.flat {
                continue;
            }
            let [x, y] = self.grid.cell_center(i);
            let s = self.swath_of(x, y);
            let above = c.mode - self.swath_min[s];
            if above <= p.max_above_min_m && above >= -p.spike_m {
                self.cells[i].ground = true;
                self.swath_sum[s] += c.mode as f64;
                self.swath_n[s] += 1;
            }
        }
        for s in 0..rings * sectors {
            self.swath_ground[s] = if self.swath_n[s] > 0 {
                (self.swath_sum[s] / self.swath_n[s] as f64) as f32
            } else {
                f32::NAN
            };
        }
        for sector in 0..sectors {
            fill_gaps(&mut self.swath_ground, sector, sectors, rings);
        }
        // Sectors without any ground borrow the nearest sector that has some.
        for sector in 0..sectors {
            if !self.swath_ground[sector].is_nan() {
                continue;
            }
            let donor = (1..=sectors / 2).find_map(|k| {
                [(sector + k) % sectors, (sector + sectors - k) % sectors]
                    .into_iter()
                    .find(|&o| !self.swath_ground[o].is_nan())
            });
            for ring in 0..rings {
                self.swath_ground[ring * sectors + sector] = match donor {
                    Some(o) => self.swath_ground[ring * sectors + o],
                    None => self.fallback,
                };
            }
        }
        for i in 0..self.cells.len() {
            let c = self.cells[i];
            self.elevation[i] = if c.ground {
                c.mode
            } else {
                let [x, y] = self.grid.cell_center(i);
                self.swath_ground[self.swath_of(x, y)]
            };
        }
    }
}

/// Mode (fullest elevation window), spread around it, extremes. `keys` are sorted.
fn cell_stats(keys: &[u64], p: &GroundParams) -> CellStats {
    let n = keys.len();
    if n == 0 {
        return CellStats {
            mode: f32::NAN,
            std: f32::NAN,
            min: f32::NAN,
            max: f32::NAN,
            ..CellStats::default()
        };
    }
    let z = |i: usize| unordered(keys[i] as u32);
    let (mut best, mut best_i, mut j) = (0usize, 0usize, 0usize);
    for i in 0..n {
        while j < n && z(j) - z(i) <= p.mode_window_m {
            j += 1;
        }
        if j - i > best {
            best = j - i;
            best_i = i;
        }
    }
    let mode = (best_i..best_i + best).map(|i| z(i) as f64).sum::<f64>() / best as f64;
    let (mut s, mut q, mut m) = (0f64, 0f64, 0u32);
    for i in 0..n {
        let d = z(i) as f64 - mode;
        if d.abs() <= p.close_band_m as f64 {
            s += d;
            q += d * d;
            m += 1;
        }
    }
    let mean = s / m as f64;
    let std = (q / m as f64 - mean * mean).max(0.0).sqrt() as f32;
    CellStats {
        count: n as u32,
        mode: mode as f32,
        std,
        min: z(0),
        max: z(n - 1),
        flat: n >= p.min_points && std <= p.max_std_m,
        ground: false,
    }
}

/// A swath value far from the median of its window (two rings either side) is removed.
fn spike_filter(
    v: &mut [f32],
    sector: usize,
    sectors: usize,
    rings: usize,
    spike: f32,
    tmp: &mut Vec<f32>,
) {
    let at = |r: usize| r * sectors + sector;
    tmp.clear();
    tmp.extend((0..rings).map(|r| v[at(r)]));
    for r in 0..rings {
        if tmp[r].is_nan() {
            continue;
        }
        // Median of the five-ring window around it (itself included, so one spike among two
        // neighbours cannot drag the median).
        let mut nb = [0f32; 5];
        let mut k = 0;
        for o in [r.wrapping_sub(2), r.wrapping_sub(1), r, r + 1, r + 2] {
            if o < rings && !tmp[o].is_nan() {
                nb[k] = tmp[o];
                k += 1;
            }
        }
        if k < 3 {
            continue;
        }
        let nb = &mut nb[..k];
        nb.sort_unstable_by(f32::total_cmp);
        let med = if k % 2 == 1 {
            nb[k / 2]
        } else {
            0.5 * (nb[k / 2 - 1] + nb[k / 2])
        };
        if (tmp[r] - med).abs() > spike {
            v[at(r)] = f32::NAN;
        }
    }
}

/// Linear interpolation across NaN gaps along range; nearest value beyond the ends.
fn fill_gaps(v: &mut [f32], sector: usize, sectors: usize, rings: usize) {
    let at = |r: usize| r * sectors + sector;
    let mut prev: Option<usize> = None;
    for r in 0..rings {
        if v[at(r)].is_nan() {
            continue;
        }
        match prev {
            None => (0..r).for_each(|g| v[at(g)] = v[at(r)]),
            Some(p) if r > p + 1 => {
                let (a, b) = (v[at(p)], v[at(r)]);
                for g in p + 1..r {
                    v[at(g)] = a + (b - a) * (g - p) as f32 / (r - p) as f32;
                }
            }
            _ => {}
        }
        prev = Some(r);
    }
    if let Some(p) = prev {
        for g in p + 1..rings {
            v[at(g)] = v[at(p)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_atan2_is_close_to_libm() {
        for i in 0..3600 {
            let t = (i as f64 / 10.0 - 180.0).to_radians() + 1e-3;
            let (y, x) = (3.0 * t.sin(), 3.0 * t.cos());
            let e = (fast_atan2(y, x) - y.atan2(x)).abs();
            assert!(e < 2e-3, "angle {t}: error {e}");
        }
    }

    #[test]
    fn ordered_keys_sort_like_floats() {
        let mut z = [3.5f32, -2.0, 0.0, -0.25, 10.0, -7.5];
        let mut k: Vec<u32> = z.iter().map(|&v| ordered(v)).collect();
        k.sort_unstable();
        z.sort_by(f32::total_cmp);
        assert_eq!(k.iter().map(|&k| unordered(k)).collect::<Vec<_>>(), z);
    }

    #[test]
    fn spike_is_removed_and_gap_filled() {
        let (rings, sectors) = (7, 1);
        let mut v = vec![0.0, 0.1, f32::NAN, -3.0, 0.3, 0.4, f32::NAN];
        let mut tmp = Vec::new();
        spike_filter(&mut v, 0, sectors, rings, 0.5, &mut tmp);
        assert!(v[3].is_nan());
        fill_gaps(&mut v, 0, sectors, rings);
        assert!(
            (v[2] - 0.1 - 0.2 / 3.0).abs() < 1e-5 && (v[3] - 0.1 - 0.4 / 3.0).abs() < 1e-5,
            "{v:?}"
        );
        assert_eq!(v[6], 0.4);
    }

    #[test]
    fn tree_cell_is_not_ground_and_flat_cell_is() {
        let p = GroundParams {
            swath_m: 10.0,
            ..GroundParams::default()
        };
        let grid = Grid {
            width: 4,
            height: 1,
            resolution: 1.0,
            center: [2.0, 0.5],
        };
        let mut g = Ground::new(p, 20.0);
        let (mut cells, mut elev) = (Vec::new(), Vec::new());
        // Cells 0 and 1: flat ground at 1.0 m; cell 2: a trunk (points from 1 m to 4 m); cell 3: a
        // flat box top 1.5 m above the ground around it.
        for i in 0..40 {
            cells.extend([0u32, 1, 2, 3]);
            let jitter = (i % 5) as f32 * 0.01;
            elev.extend([
                1.0 + jitter,
                1.02 + jitter,
                1.0 + i as f32 * 0.075,
                2.5 + jitter,
            ]);
        }
        g.update(grid, [0.0, 0.0], &cells, &elev, 0.0);
        assert!(g.cells[0].ground && g.cells[1].ground);
        assert!(
            !g.cells[2].flat,
            "trunk has high variance: {:?}",
            g.cells[2]
        );
        assert!(
            g.cells[3].flat && !g.cells[3].ground,
            "box top is above the swath minimum"
        );
        assert!(
            (g.elevation[3] - 1.03).abs() < 0.05,
            "non-ground cell takes its swath's ground"
        );
    }

    #[test]
    fn mirror_images_below_the_ground_do_not_become_the_ground() {
        // One swath of 20 flat cells at 0.3 m; 3 of them hold instead the flat mirror image of the
        // ground seen in a puddle, 1.2 m lower. A true minimum would make the mirror the ground.
        let p = GroundParams {
            swath_m: 50.0,
            sectors: 1,
            ..GroundParams::default()
        };
        let grid = Grid {
            width: 20,
            height: 1,
            resolution: 1.0,
            center: [10.0, 0.5],
        };
        let mut g = Ground::new(p, 40.0);
        let (mut cells, mut elev) = (Vec::new(), Vec::new());
        for c in 0..20u32 {
            let z = if [4, 9, 15].contains(&c) { -0.9 } else { 0.3 };
            for i in 0..10 {
                cells.push(c);
                elev.push(z + (i % 3) as f32 * 0.01);
            }
        }
        g.update(grid, [0.0, 0.0], &cells, &elev, 0.0);
        for c in 0..20 {
            let mirror = [4, 9, 15].contains(&c);
            assert_eq!(g.cells[c].ground, !mirror, "cell {c}: {:?}", g.cells[c]);
            assert!(
                (g.elevation[c] - 0.31).abs() < 0.02,
                "cell {c}: {}",
                g.elevation[c]
            );
        }
    }
}
