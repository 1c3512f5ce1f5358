//! Terrain as a regular heightfield, generated once from the scenario and ray-marched per pixel.
//!
//! Rays walk the grid in blocks and skip blocks whose highest point is below them. Inside a block,
//! marching uses a conservative step: with the block's largest slope `L`, a ray at height `dz`
//! above the ground cannot reach it in less than `dz / (L |d_xy| - d_z)`. Far away the step is floored
//! at a fraction of the pixel footprint, then the crossing is refined by false position.

use crate::math::{smoothstep, v3, V3};
use crate::noise::fbm2;

/// Cells per side of a skip block.
const BLOCK: usize = 8;

/// How the land is shaped.
#[derive(Clone, Debug)]
pub enum TerrainShape {
    /// Land on one side of a straight shoreline through `point`; `inland` is the unit direction
    /// pointing inland.
    Shore {
        point: [f64; 2],
        inland: [f64; 2],
        height: f32,
        slope_width: f32,
    },
    /// A water channel of `width` along a polyline, banks rising on both sides.
    Channel {
        centerline: Vec<[f64; 2]>,
        width: f32,
        bank_height: f32,
        slope_width: f32,
    },
    /// Dry rolling ground with a flattened trail.
    Ground {
        trail: Vec<[f64; 2]>,
        trail_width: f32,
    },
}

#[derive(Clone, Debug)]
pub struct TerrainParams {
    pub shape: TerrainShape,
    /// Amplitude of the random relief, metres.
    pub relief: f32,
    /// [xmin, xmax, ymin, ymax] in world metres.
    pub extent: [f64; 4],
    /// Grid spacing, metres.
    pub cell: f32,
    pub seed: u32,
}

/// Heightfield over an axis-aligned extent.
#[derive(Clone, Debug)]
pub struct Terrain {
    x0: f32,
    y0: f32,
    cell: f32,
    nx: usize,
    ny: usize,
    h: Vec<f32>,
    pub h_min: f32,
    pub h_max: f32,
    /// Highest node of each block of `BLOCK` x `BLOCK` cells (edges shared with neighbours): rays
    /// above a block's maximum skip it without sampling the heightfield.
    block_max: Vec<f32>,
    /// Largest slope inside each block (rise over run, with the diagonal margin): marching takes
    /// long steps over gentle ground even when some other place is steep.
    block_slope: Vec<f32>,
    bnx: usize,
    bny: usize,
    /// Trail polyline and half width (ground worlds), for texturing and labels.
    trail: Option<(Vec<[f32; 2]>, f32)>,
    /// Depth below which banks look like sand/mud rather than grass (maritime worlds).
    pub maritime: bool,
    pub seed: u32,
}

impl Terrain {
    pub fn generate(p: &TerrainParams) -> Terrain {
        let [xmin, xmax, ymin, ymax] = p.extent;
        let nx = ((xmax - xmin) / p.cell as f64).ceil() as usize + 1;
        let ny = ((ymax - ymin) / p.cell as f64).ceil() as usize + 1;
        let mut h = Vec::with_capacity(nx * ny);
        let seed = p.seed;
        let line: Vec<[f32; 2]> = match &p.shape {
            TerrainShape::Channel { centerline: l, .. } | TerrainShape::Ground { trail: l, .. } => {
                l.iter().map(|q| [q[0] as f32, q[1] as f32]).collect()
            }
            TerrainShape::Shore { .. } => Vec::new(),
        };
        for j in 0..ny {
            for i in 0..nx {
                let x = xmin as f32 + i as f32 * p.cell;
                let y = ymin as f32 + j as f32 * p.cell;
                h.push(base_height(&p.shape, &line, p.relief, x, y, seed));
            }
        }
        let trail = match &p.shape {
            TerrainShape::Ground { trail_width, .. } => Some((line, trail_width / 2.0)),
            _ => None,
        };
        let mut t = Terrain {
            x0: xmin as f32,
            y0: ymin as f32,
            cell: p.cell,
            nx,
            ny,
            h,
            h_min: 0.0,
            h_max: 0.0,
            block_max: Vec::new(),
            block_slope: Vec::new(),
            bnx: 0,
            bny: 0,
            trail,
            maritime: !matches!(p.shape, TerrainShape::Ground { .. }),
            seed,
        };
        t.update_bounds();
        t
    }

    fn update_bounds(&mut self) {
        self.h_min = self.h.iter().copied().fold(f32::MAX, f32::min);
        self.h_max = self.h.iter().copied().fold(f32::MIN, f32::max) + 0.01;
        self.bnx = (self.nx - 1).div_ceil(BLOCK).max(1);
        self.bny = (self.ny - 1).div_ceil(BLOCK).max(1);
        self.block_max.clear();
        self.block_slope.clear();
        for bj in 0..self.bny {
            for bi in 0..self.bnx {
                let (mut m, mut l) = (f32::MIN, 0.0f32);
                let (i1, j1) = (
                    ((bi + 1) * BLOCK).min(self.nx - 1),
                    ((bj + 1) * BLOCK).min(self.ny - 1),
                );
                for j in bj * BLOCK..=j1 {
                    for i in bi * BLOCK..=i1 {
                        let a = self.h[j * self.nx + i];
                        m = m.max(a);
                        if i < i1 {
                            l = l.max((self.h[j * self.nx + i + 1] - a).abs());
                        }
                        if j < j1 {
                            l = l.max((self.h[(j + 1) * self.nx + i] - a).abs());
                        }
                    }
                }
                self.block_max.push(m);
                // Bilinear patches can be steeper along a diagonal than along the axes.
                self.block_slope
                    .push(l / self.cell * std::f32::consts::SQRT_2 + 1e-3);
            }
        }
    }

    /// Lowers the ground inside a disc so a flat water surface at the returned elevation covers it:
    /// a bowl `depth` deep in the middle, and the rim kept just above the water.
    pub fn carve_puddle(&mut self, center: [f64; 2], radius: f32, depth: f32) -> f32 {
        let (cx, cy) = (center[0] as f32, center[1] as f32);
        let elevation = self.height(cx, cy);
        let r_out = radius + 1.0;
        let (i0, i1) = self.index_range(cx - r_out, cx + r_out, self.x0, self.nx);
        let (j0, j1) = self.index_range(cy - r_out, cy + r_out, self.y0, self.ny);
        for j in j0..j1 {
            for i in i0..i1 {
                let x = self.x0 + i as f32 * self.cell;
                let y = self.y0 + j as f32 * self.cell;
                let d = (x - cx).hypot(y - cy);
                let v = &mut self.h[j * self.nx + i];
                if d < radius {
                    let bowl = elevation - 0.02 - depth * (1.0 - (d / radius).powi(2));
                    *v = v.min(bowl);
                } else if d < r_out {
                    // Rim: at least 2 cm above the water so the shore line is the disc edge.
                    let w = 1.0 - (d - radius) / (r_out - radius);
                    *v = v.max(elevation + 0.02 * w);
                }
            }
        }
        self.update_bounds();
        elevation
    }

    fn index_range(&self, lo: f32, hi: f32, origin: f32, n: usize) -> (usize, usize) {
        let a = ((lo - origin) / self.cell).floor().max(0.0) as usize;
        let b = (((hi - origin) / self.cell).ceil() as usize + 1).min(n);
        (a.min(n), b)
    }

    pub fn contains(&self, x: f32, y: f32) -> bool {
        let (x1, y1) = self.far_corner();
        x >= self.x0 && x <= x1 && y >= self.y0 && y <= y1
    }

    fn far_corner(&self) -> (f32, f32) {
        (
            self.x0 + (self.nx - 1) as f32 * self.cell,
            self.y0 + (self.ny - 1) as f32 * self.cell,
        )
    }

    /// Bilinear height; clamps to the edge outside the extent.
    #[inline]
    pub fn height(&self, x: f32, y: f32) -> f32 {
        let fx = ((x - self.x0) / self.cell).clamp(0.0, (self.nx - 1) as f32 - 1e-3);
        let fy = ((y - self.y0) / self.cell).clamp(0.0, (self.ny - 1) as f32 - 1e-3);
        let (i, j) = (fx as usize, fy as usize);
        let (tx, ty) = (fx - i as f32, fy - j as f32);
        let k = j * self.nx + i;
        let (a, b) = (self.h[k], self.h[k + 1]);
        let (c, d) = (self.h[k + self.nx], self.h[k + self.nx + 1]);
        let top = a + (b - a) * tx;
        let bot = c + (d - c) * tx;
        top + (bot - top) * ty
    }

    pub fn normal(&self, x: f32, y: f32) -> V3 {
        let e = self.cell;
        let dx = self.height(x + e, y) - self.height(x - e, y);
        let dy = self.height(x, y + e) - self.height(x, y - e);
        v3(-dx, -dy, 2.0 * e).normalize()
    }

    /// True on the trail (ground worlds).
    pub fn on_trail(&self, x: f32, y: f32) -> bool {
        match &self.trail {
            Some((pts, half)) => polyline_distance(pts, x, y) < *half,
            None => false,
        }
    }

    /// First crossing of the ray `o + t d` (d unit length) with the ground in `(0, tmax)`.
    /// `pix` is the angular size of a pixel, used to bound the step count far away.
    pub fn intersect(&self, o: V3, d: V3, tmax: f32, pix: f32) -> Option<f32> {
        let (x1, y1) = self.far_corner();
        let (mut t0, mut t1) = (1e-3f32, tmax);
        for (oa, da, lo, hi) in [
            (o.x, d.x, self.x0, x1),
            (o.y, d.y, self.y0, y1),
            (o.z, d.z, self.h_min, self.h_max),
        ] {
            if da.abs() < 1e-9 {
                if oa < lo || oa > hi {
                    return None;
                }
            } else {
                let (a, b) = ((lo - oa) / da, (hi - oa) / da);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        if t0 >= t1 {
            return None;
        }
        // Walk the blocks the ray crosses (2-D DDA); march finely only where it can hit.
        let bs = self.cell * BLOCK as f32;
        let p = o + d * t0;
        let clampi = |v: f32, n: usize| (v.floor().max(0.0) as usize).min(n - 1);
        let (mut bi, mut bj) = (
            clampi((p.x - self.x0) / bs, self.bnx),
            clampi((p.y - self.y0) / bs, self.bny),
        );
        let axis = |o: f32, d: f32, origin: f32, b: usize| -> (f32, f32) {
            if d.abs() < 1e-12 {
                (f32::MAX, f32::MAX)
            } else {
                let edge = origin + (b + usize::from(d > 0.0)) as f32 * bs;
                ((edge - o) / d, bs / d.abs())
            }
        };
        let (mut tx, dtx) = axis(o.x, d.x, self.x0, bi);
        let (mut ty, dty) = axis(o.y, d.y, self.y0, bj);
        let mut ta = t0;
        loop {
            let tb = tx.min(ty).min(t1).max(ta);
            let zmin = o.z + d.z * if d.z < 0.0 { tb } else { ta };
            if zmin <= self.block_max[bj * self.bnx + bi] {
                let slope = self.block_slope[bj * self.bnx + bi];
                if let Some(t) = self.march(o, d, ta, tb, slope, pix) {
                    return Some(t);
                }
            }
            if tb >= t1 {
                return None;
            }
            if tx < ty {
                if d.x > 0.0 {
                    bi += 1
                } else if bi == 0 {
                    return None;
                } else {
                    bi -= 1
                }
                tx += dtx;
            } else {
                if d.y > 0.0 {
                    bj += 1
                } else if bj == 0 {
                    return None;
                } else {
                    bj -= 1
                }
                ty += dty;
            }
            if bi >= self.bnx || bj >= self.bny {
                return None;
            }
            ta = tb;
        }
    }

    /// Conservative march over `[ta, tb]`, then refinement of the first crossing.
    fn march(&self, o: V3, d: V3, ta: f32, tb: f32, slope: f32, pix: f32) -> Option<f32> {
        let closing = slope * (d.x * d.x + d.y * d.y).sqrt() - d.z;
        let above = |t: f32| {
            let p = o + d * t;
            p.z - self.height(p.x, p.y)
        };
        let mut prev = (ta, above(ta));
        if prev.1 < 0.0 {
            return Some(ta); // starts below ground (camera inside a hill): report the entry
        }
        loop {
            let safe = if closing > 1e-6 {
                prev.1 / closing
            } else {
                f32::MAX
            };
            let t = (prev.0 + safe.max(0.02 + 0.5 * pix * prev.0)).min(tb);
            let dz = above(t);
            if dz < 0.0 {
                return Some(refine(prev, (t, dz), above));
            }
            if t >= tb {
                return None;
            }
            prev = (t, dz);
        }
    }
}

/// False-position refinement of a bracketed crossing.
fn refine(mut a: (f32, f32), mut b: (f32, f32), f: impl Fn(f32) -> f32) -> f32 {
    for _ in 0..6 {
        let t = a.0 + (b.0 - a.0) * a.1 / (a.1 - b.1);
        let v = f(t);
        if v < 0.0 {
            b = (t, v);
        } else {
            a = (t, v);
        }
    }
    a.0 + (b.0 - a.0) * a.1 / (a.1 - b.1)
}

/// `line` is the channel centreline or the trail, converted once by the caller.
fn base_height(
    shape: &TerrainShape,
    line: &[[f32; 2]],
    relief: f32,
    x: f32,
    y: f32,
    seed: u32,
) -> f32 {
    let rough = |scale: f32| (fbm2(x, y, scale, 5, 0.0, seed) - 0.5) * 2.0;
    match shape {
        TerrainShape::Shore {
            point,
            inland,
            height,
            slope_width,
        } => {
            let sd =
                (x - point[0] as f32) * inland[0] as f32 + (y - point[1] as f32) * inland[1] as f32;
            // Wobble the shoreline so it is not a ruler-straight line.
            let sd = sd + 8.0 * rough(120.0);
            land_profile(sd, *height, *slope_width, relief * rough(45.0))
        }
        TerrainShape::Channel {
            width,
            bank_height,
            slope_width,
            ..
        } => {
            let d = polyline_distance(line, x, y) - width / 2.0 + 4.0 * rough(90.0);
            land_profile(d, *bank_height, *slope_width, relief * rough(45.0))
        }
        TerrainShape::Ground { trail_width, .. } => {
            let low = relief * rough(90.0);
            // Small bumps, band-limited (footprint 0.4 m drops the finest octaves) so slopes stay
            // moderate and marching takes long steps.
            let bumps = 0.12 * (fbm2(x, y, 3.0, 4, 0.4, seed ^ 0xb) - 0.5) * 2.0;
            let d = polyline_distance(line, x, y);
            // The trail is the low-frequency ground, flattened and slightly worn in.
            let w = 1.0 - smoothstep(trail_width / 2.0, trail_width / 2.0 + 2.5, d);
            let trail_h = low - 0.06;
            (low + bumps) * (1.0 - w) + trail_h * w
        }
    }
}

/// Height across a shoreline: `sd` is the signed distance inland (negative = water side).
fn land_profile(sd: f32, height: f32, slope_width: f32, relief: f32) -> f32 {
    let s = smoothstep(-6.0, slope_width, sd);
    let land = smoothstep(0.0, slope_width, sd);
    -2.5 + (height + 2.5) * s + relief.max(-0.5 * height) * land
}

pub fn polyline_distance(pts: &[[f32; 2]], x: f32, y: f32) -> f32 {
    if pts.len() == 1 {
        return (x - pts[0][0]).hypot(y - pts[0][1]);
    }
    let mut best = f32::MAX;
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let t = if len2 > 0.0 {
            (((x - a[0]) * dx + (y - a[1]) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        best = best.min((x - a[0] - t * dx).hypot(y - a[1] - t * dy));
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ground() -> Terrain {
        Terrain::generate(&TerrainParams {
            shape: TerrainShape::Ground {
                trail: vec![[0.0, 0.0], [100.0, 0.0]],
                trail_width: 3.0,
            },
            relief: 1.5,
            extent: [-50.0, 150.0, -60.0, 60.0],
            cell: 0.5,
            seed: 3,
        })
    }

    #[test]
    fn march_finds_the_heightfield() {
        let t = ground();
        let o = v3(0.0, 0.0, t.height(0.0, 0.0) + 2.0);
        for k in 0..50 {
            let d = v3(1.0, (k as f32 - 25.0) * 0.02, -0.05 - k as f32 * 0.004).normalize();
            let hit = t
                .intersect(o, d, 1000.0, 0.001)
                .expect("looking down hits the ground");
            let p = o + d * hit;
            assert!((p.z - t.height(p.x, p.y)).abs() < 0.02, "ray {k}: {p:?}");
        }
        assert!(t
            .intersect(o, v3(1.0, 0.0, 0.3).normalize(), 1000.0, 0.001)
            .is_none());
    }

    #[test]
    fn puddle_is_below_its_water() {
        let mut t = ground();
        let e = t.carve_puddle([30.0, 0.0], 2.0, 0.2);
        assert!(t.height(30.0, 0.0) < e);
        assert!(t.height(31.5, 0.5) < e);
        assert!(t.height(32.6, 0.0) >= e);
        assert!(t.on_trail(30.0, 1.0) && !t.on_trail(30.0, 5.0));
    }
}
