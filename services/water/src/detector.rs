//! The per-frame detector: cues, joining, fusion, ground, water elevation and the terrain map.

use crate::config::WaterConfig;
use crate::cues::{self, Integrals, SkyReference};
use crate::geometry::FrameGeometry;
use crate::ground::{Ground, NO_CELL};
use crate::map;
use crate::morph;
use crate::regions::{self, RegionStats, Verdict};
use messages::{water_cue, CameraModel, GridGeometry, MapCell, Pose};
use rayon::prelude::*;

/// The left image of a frame.
#[derive(Clone, Copy, Debug)]
pub enum Image<'a> {
    /// 3 bytes per pixel, rows packed.
    Rgb8(&'a [u8]),
    /// 1 byte per pixel; the colour cue is off.
    Mono8(&'a [u8]),
}

/// One frame's input.
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    pub width: usize,
    pub height: usize,
    pub image: Image<'a>,
    /// Disparity of the left image (px), NaN where invalid; same size as the image.
    pub disparity: &'a [f32],
    pub camera: &'a CameraModel,
    /// Vehicle (body) pose in the world, ENU. With only a camera height and pitch known, pass the
    /// origin here and put height and pitch into `camera.mount`.
    pub vehicle: &'a Pose,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WaterError {
    #[error("image too small: {width}x{height} (need at least 16x16)")]
    TooSmall { width: usize, height: usize },
    #[error("{what} has {got} values, a {width}x{height} frame needs {want}")]
    SizeMismatch {
        what: &'static str,
        width: usize,
        height: usize,
        want: usize,
        got: usize,
    },
    #[error("invalid camera model: {0}")]
    Camera(String),
    #[error("invalid vehicle pose: {0}")]
    Pose(String),
}

/// An accepted water region.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaterRegion {
    /// Region label in this frame (1-based, scan order).
    pub label: u32,
    pub pixels: u32,
    /// Inclusive bounding box in pixels: u0, v0, u1, v1.
    pub bbox: [u32; 4],
    /// Pixels carrying each joined cue: colour, texture, reflection, zero disparity.
    pub cues: [u32; 4],
    /// Water surface elevation (m, ENU z): mean ground elevation around the perimeter (section 3).
    pub elevation_m: f64,
    /// Ground samples on the perimeter; 0 means the nearest ground elevation was used instead.
    pub perimeter_samples: u32,
    /// Mean pixel of the region.
    pub centroid_px: [f32; 2],
    /// Centroid of the region's surface points in the world (ENU, m).
    pub position: [f64; 3],
    /// Horizontal range (m) from the vehicle to `position`, and its bearing (rad) from the vehicle's
    /// heading, positive to the left.
    pub range_m: f64,
    pub bearing_rad: f64,
    /// Map cells marked as water for this region.
    pub map_cells: u32,
}

/// One frame's result, borrowed from the detector.
#[derive(Debug)]
pub struct Detection<'a> {
    /// `width * height` cue bits ([`water_cue`]).
    pub mask: &'a [u8],
    pub regions: &'a [WaterRegion],
    /// Candidate regions the rule base looked at.
    pub candidates: usize,
    /// Rejected candidates by reason: too small, above the horizon, above the ground, invalid cues.
    pub rejected: [u32; 4],
    pub map: &'a [MapCell],
    pub grid: GridGeometry,
    pub sky: SkyReference,
    /// Horizon row at the image centre column.
    pub horizon_row: f32,
}

/// Internal per-pixel flags next to the cue mask.
const RANGE: u8 = 1 << 0;
const ABOVE_GROUND: u8 = 1 << 1;
const ZERO_DISPARITY_KNOWN: u8 = 1 << 2;

/// Reusable water detector: holds every buffer, sized by the first frame.
pub struct WaterDetector {
    config: WaterConfig,
    width: usize,
    height: usize,
    gray: Vec<u8>,
    mask: Vec<u8>,
    joined: Vec<u8>,
    tmp: Vec<u8>,
    aux: Vec<u8>,
    elev: Vec<f32>,
    range: Vec<f32>,
    /// World east/north of each pixel's stereo point.
    xy: Vec<[f32; 2]>,
    cell: Vec<u32>,
    labels: Vec<u32>,
    parent: Vec<u32>,
    stats: Vec<RegionStats>,
    verdicts: Vec<Verdict>,
    /// Per label: index into `regions` (u32::MAX = rejected), perimeter sums, placement sums.
    region_of: Vec<u32>,
    perimeter: Vec<(f64, u32)>,
    placed: Vec<([f64; 2], u32)>,
    horizon: Vec<f32>,
    hist: [u32; 256],
    integrals: Integrals,
    ground: Ground,
    regions: Vec<WaterRegion>,
    map: Vec<MapCell>,
}

impl WaterDetector {
    pub fn new(config: WaterConfig) -> Self {
        let max_range = config.reflection.max_range_m.max(config.ground.max_range_m);
        Self {
            ground: Ground::new(config.ground.clone(), max_range),
            config,
            width: 0,
            height: 0,
            gray: Vec::new(),
            mask: Vec::new(),
            joined: Vec::new(),
            tmp: Vec::new(),
            aux: Vec::new(),
            elev: Vec::new(),
            range: Vec::new(),
            xy: Vec::new(),
            cell: Vec::new(),
            labels: Vec::new(),
            parent: Vec::new(),
            stats: Vec::new(),
            verdicts: Vec::new(),
            region_of: Vec::new(),
            perimeter: Vec::new(),
            placed: Vec::new(),
            horizon: Vec::new(),
            hist: [0; 256],
            integrals: Integrals::new(),
            regions: Vec::new(),
            map: Vec::new(),
        }
    }

    pub fn config(&self) -> &WaterConfig {
        &self.config
    }

    /// Luma of the last frame's image.
    pub fn gray(&self) -> &[u8] {
        &self.gray
    }

    /// Region label of every pixel in the last frame (0 = none); [`WaterRegion::label`] refers to it.
    pub fn region_labels(&self) -> &[u32] {
        &self.labels
    }

    /// Statistics and verdict of every candidate region of the last frame, indexed by label (entry 0
    /// is the background).
    pub fn candidates(&self) -> (&[RegionStats], &[Verdict]) {
        (&self.stats, &self.verdicts)
    }

    /// Ground detection of the last frame.
    pub fn ground(&self) -> &Ground {
        &self.ground
    }

    fn validate(frame: &Frame<'_>) -> Result<(), WaterError> {
        let (w, h) = (frame.width, frame.height);
        if w < 16 || h < 16 {
            return Err(WaterError::TooSmall {
                width: w,
                height: h,
            });
        }
        let n = w * h;
        let (what, want, got) = match frame.image {
            Image::Rgb8(d) => ("Rgb8 image", 3 * n, d.len()),
            Image::Mono8(d) => ("Mono8 image", n, d.len()),
        };
        let mismatch = |what, want, got| WaterError::SizeMismatch {
            what,
            width: w,
            height: h,
            want,
            got,
        };
        if want != got {
            return Err(mismatch(what, want, got));
        }
        if frame.disparity.len() != n {
            return Err(mismatch("disparity", n, frame.disparity.len()));
        }
        let c = frame.camera;
        let finite = [c.fx, c.fy, c.cx, c.cy, c.baseline_m]
            .iter()
            .all(|v| v.is_finite());
        if !finite || c.fx <= 0.0 || c.fy <= 0.0 || c.baseline_m <= 0.0 {
            return Err(WaterError::Camera(format!(
                "fx {} fy {} cx {} cy {} baseline {} (focal lengths and baseline must be positive)",
                c.fx, c.fy, c.cx, c.cy, c.baseline_m
            )));
        }
        let pose_ok = |p: &Pose| {
            p.position.iter().all(|v| v.is_finite())
                && [p.roll, p.pitch, p.yaw].iter().all(|v| v.is_finite())
        };
        if !pose_ok(&c.mount) {
            return Err(WaterError::Camera("non-finite mount pose".into()));
        }
        if !pose_ok(frame.vehicle) {
            return Err(WaterError::Pose(format!("non-finite: {:?}", frame.vehicle)));
        }
        Ok(())
    }

    fn resize(&mut self, w: usize, h: usize) {
        let n = w * h;
        self.width = w;
        self.height = h;
        self.gray.resize(n, 0);
        self.mask.resize(n, 0);
        self.joined.resize(n, 0);
        self.tmp.resize(n, 0);
        self.aux.resize(n, 0);
        self.elev.resize(n, f32::NAN);
        self.range.resize(n, f32::NAN);
        self.xy.resize(n, [f32::NAN; 2]);
        self.cell.resize(n, NO_CELL);
        self.labels.resize(n, 0);
        self.horizon.resize(w, 0.0);
    }

    /// Detects water in one frame.
    pub fn process(&mut self, frame: &Frame<'_>) -> Result<Detection<'_>, WaterError> {
        Self::validate(frame)?;
        let geo = FrameGeometry::new(frame.camera, frame.vehicle);
        if !geo.upright() {
            return Err(WaterError::Pose(
                "camera is not upright (rolled or pitched past vertical): no horizon".into(),
            ));
        }
        let (w, h) = (frame.width, frame.height);
        if (w, h) != (self.width, self.height) {
            self.resize(w, h);
        }
        for (u, hz) in self.horizon.iter_mut().enumerate() {
            *hz = geo.horizon_row(u as f64) as f32;
        }
        let cfg = &self.config;
        let grid = map::grid_around(geo.vehicle, &cfg.map);

        // Stereo points in the world: elevation, horizontal range from the vehicle, map cell.
        let max_range = cfg.reflection.max_range_m.max(cfg.ground.max_range_m) as f64;
        let ground_range = cfg.ground.max_range_m;
        let dense = cfg.ground.dense_range_m;
        let veh = geo.vehicle;
        self.elev
            .par_chunks_mut(w)
            .zip(self.range.par_chunks_mut(w))
            .zip(self.cell.par_chunks_mut(w))
            .zip(self.xy.par_chunks_mut(w))
            .zip(frame.disparity.par_chunks(w))
            .enumerate()
            .for_each(|(v, ((((el, rg), ce), xy), disp))| {
                for u in 0..w {
                    el[u] = f32::NAN;
                    rg[u] = f32::NAN;
                    ce[u] = NO_CELL;
                    let d = disp[u];
                    if !(d.is_finite() && d > 0.0) {
                        continue;
                    }
                    let z = geo.depth(d);
                    let ray = geo.ray(u as f64, v as f64);
                    let p = [
                        geo.origin[0] + z * ray[0],
                        geo.origin[1] + z * ray[1],
                        geo.origin[2] + z * ray[2],
                    ];
                    let (dx, dy) = (p[0] - veh[0], p[1] - veh[1]);
                    let r = (dx * dx + dy * dy).sqrt();
                    if r > max_range {
                        continue;
                    }
                    el[u] = p[2] as f32;
                    rg[u] = r as f32;
                    xy[u] = [p[0] as f32, p[1] as f32];
                    // Near cells get hundreds of points: every other pixel in both directions is
                    // plenty for their mode and keeps the per-frame sort small.
                    let sparse = (r as f32) < dense && (u | v) & 1 != 0;
                    if r as f32 <= ground_range && !sparse {
                        ce[u] = grid.cell_of(p[0], p[1]);
                    }
                }
            });

        // Ground (section 2): mode + variance per cell, radial minimum elevation swaths.
        let fallback = (geo.vehicle[2]) as f32;
        self.ground
            .update(grid, [veh[0], veh[1]], &self.cell, &self.elev, fallback);

        // Image cues: colour and texture.
        self.mask.fill(0);
        let sky = match frame.image {
            Image::Rgb8(rgb) => {
                let sky = cues::sky_reference(rgb, w, h, &self.horizon, &cfg.color, &mut self.hist);
                cues::color_cue(rgb, w, &sky, &cfg.color, &mut self.gray, &mut self.mask);
                sky
            }
            Image::Mono8(gray) => {
                self.gray.copy_from_slice(gray);
                SkyReference::from_rgb(cfg.color.default_sky_rgb.map(|c| c as f32), 0)
            }
        };
        self.integrals.build(&self.gray, w, h);
        cues::texture_cue(&self.integrals, w, h, &cfg.texture, &mut self.mask);

        // Stereo cues: zero disparity low in the image, range points below the ground (reflections).
        let zd = &cfg.zero_disparity;
        let rf = &cfg.reflection;
        let above_m = cfg.rules.above_ground_m;
        let ground = &self.ground;
        let horizon = &self.horizon;
        let elev = &self.elev;
        let range = &self.range;
        let xy = &self.xy;
        let near_ground = self.ground.nearest_ground().unwrap_or(fallback) as f64;
        let fb = geo.fx * geo.baseline;
        let edge = rf.edge_margin_px as f64;
        self.mask
            .par_chunks_mut(w)
            .zip(self.aux.par_chunks_mut(w))
            .zip(frame.disparity.par_chunks(w))
            .enumerate()
            .for_each(|(v, ((m, aux), disp))| {
                let row = v * w;
                for u in 0..w {
                    aux[u] = 0;
                    let d = disp[u];
                    let valid = d.is_finite() && d > 0.0;
                    let ray = geo.ray(u as f64, v as f64);
                    // Zero disparity is evidence only where the ground itself could have been
                    // matched (its disparity keeps the match inside the right image).
                    // The ground at depth t has disparity fB / t; with t = (g - z0) / ray_z > 0 the
                    // test u - margin >= fB / t, multiplied by g - z0 < 0, needs no division.
                    let known = u >= zd.left_margin_px
                        && (ray[2] >= 0.0
                            || near_ground >= geo.origin[2]
                            || (u as f64 - edge) * (near_ground - geo.origin[2]) <= fb * ray[2]);
                    if known {
                        aux[u] |= ZERO_DISPARITY_KNOWN;
                    }
                    if known
                        && v as f32 >= horizon[u] + zd.horizon_margin_px as f32
                        && (if valid {
                            d < zd.max_disparity
                        } else {
                            zd.count_invalid
                        })
                    {
                        m[u] |= water_cue::ZERO_DISPARITY;
                    }
                    let e = elev[row + u];
                    if e.is_nan() {
                        continue;
                    }
                    let [x, y] = xy[row + u];
                    let (x, y) = (x as f64, y as f64);
                    let g = ground.ground_at(x, y);
                    let r = range[row + u];
                    // Where the ground's own disparity would put the match outside the right
                    // image, the matcher can only return a wrong, smaller disparity, which looks
                    // like a point below the ground: no evidence there.
                    let dz = g as f64 - geo.origin[2];
                    let matchable =
                        ray[2] >= 0.0 || dz >= 0.0 || (u as f64 - edge) * dz <= fb * ray[2];
                    if matchable
                        && e < g - (rf.margin_m + rf.margin_per_m * r)
                        && r <= rf.max_range_m
                    {
                        m[u] |= water_cue::REFLECTION;
                    } else {
                        aux[u] |= RANGE;
                        if e > g + above_m {
                            aux[u] |= ABOVE_GROUND;
                        }
                    }
                }
            });

        // Join close regions of each cue, then label the union (section 2, figure 4).
        let bits = water_cue::COLOR
            | water_cue::TEXTURE
            | water_cue::REFLECTION
            | water_cue::ZERO_DISPARITY;
        morph::close(
            &self.mask,
            &mut self.joined,
            &mut self.tmp,
            w,
            h,
            cfg.join_radius_px,
            bits,
        );
        let seeds = if cfg.weak_cues_form_regions {
            bits
        } else {
            water_cue::COLOR | water_cue::REFLECTION
        };
        // Region membership in the tmp buffer: the joined seed cues.
        self.tmp
            .par_iter_mut()
            .zip(&self.joined)
            .for_each(|(t, &j)| *t = j & seeds);
        let n = regions::label(&self.tmp, w, h, &mut self.labels, &mut self.parent);

        // Region statistics for the rule base.
        self.stats.clear();
        self.stats.resize(n + 1, RegionStats::default());
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let l = self.labels[i] as usize;
                if l != 0 {
                    self.stats[l].add(
                        u,
                        v,
                        self.joined[i],
                        (v as f32) < self.horizon[u],
                        self.aux[i] & ZERO_DISPARITY_KNOWN != 0,
                    );
                }
            }
        }
        // Around each region's perimeter: range points above the ground (a region sitting on an
        // elevated object is not water), and ground samples for the water elevation (section 3).
        // Points inside a region are not used: stereo on water is unreliable.
        self.perimeter.clear();
        self.perimeter.resize(n + 1, (0.0, 0));
        let off = cfg.ground.perimeter_offset_px.max(1) as isize;
        let tol = cfg.ground.perimeter_tolerance_m;
        for v in 0..h as isize {
            for u in 0..w as isize {
                let i = (v * w as isize + u) as usize;
                let l = self.labels[i] as usize;
                if l == 0 {
                    continue;
                }
                for (du, dv) in [(-off, 0), (off, 0), (0, -off), (0, off)] {
                    let (uu, vv) = (u + du, v + dv);
                    if uu < 0 || vv < 0 || uu >= w as isize || vv >= h as isize {
                        continue;
                    }
                    let j = (vv * w as isize + uu) as usize;
                    if self.labels[j] as usize == l || self.aux[j] & RANGE == 0 {
                        continue;
                    }
                    let s = &mut self.stats[l];
                    s.range_points += 1;
                    s.above_ground += (self.aux[j] & ABOVE_GROUND != 0) as u32;
                    let [x, y] = self.xy[j];
                    let c = grid.cell_of(x as f64, y as f64);
                    if c == NO_CELL {
                        continue;
                    }
                    let c = c as usize;
                    if self.ground.cells[c].ground
                        && (self.elev[j] - self.ground.elevation[c]).abs() <= tol
                    {
                        self.perimeter[l].0 += self.ground.elevation[c] as f64;
                        self.perimeter[l].1 += 1;
                    }
                }
            }
        }
        // Rule-base fusion.
        self.verdicts.clear();
        self.verdicts
            .extend(self.stats.iter().map(|s| regions::judge(s, &cfg.rules)));
        self.verdicts[0] = Verdict::TooSmall;
        let nearest = self.ground.nearest_ground().unwrap_or(fallback) as f64;

        // Terrain map, then water placed on it at each region's elevation.
        map::terrain(&self.ground, &cfg.map, &mut self.map);
        self.placed.clear();
        self.placed.resize(n + 1, ([0.0; 2], 0));
        self.region_of.clear();
        self.region_of.resize(n + 1, u32::MAX);
        self.regions.clear();
        for l in 1..=n {
            if self.verdicts[l] != Verdict::Water {
                continue;
            }
            let s = &self.stats[l];
            let (sum, k) = self.perimeter[l];
            self.region_of[l] = self.regions.len() as u32;
            self.regions.push(WaterRegion {
                label: l as u32,
                pixels: s.pixels,
                bbox: s.bbox,
                cues: s.cues,
                elevation_m: if k > 0 { sum / k as f64 } else { nearest },
                perimeter_samples: k,
                centroid_px: [
                    (s.sum_u as f64 / s.pixels as f64) as f32,
                    (s.sum_v as f64 / s.pixels as f64) as f32,
                ],
                position: [f64::NAN; 3],
                range_m: f64::NAN,
                bearing_rad: f64::NAN,
                map_cells: 0,
            });
        }
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let l = self.labels[i] as usize;
                let k = if l == 0 { u32::MAX } else { self.region_of[l] };
                if k == u32::MAX {
                    continue;
                }
                self.mask[i] |= water_cue::WATER;
                let e = self.regions[k as usize].elevation_m;
                if let Some(p) = geo.intersect_plane(u as f64, v as f64, e) {
                    let pl = &mut self.placed[l];
                    pl.0[0] += p[0];
                    pl.0[1] += p[1];
                    pl.1 += 1;
                    let c = grid.cell_of(p[0], p[1]);
                    if c != NO_CELL {
                        let cell = &mut self.map[c as usize];
                        if cell.water == 0 {
                            self.regions[k as usize].map_cells += 1;
                        }
                        map::mark_water(cell, e as f32, &cfg.map);
                    }
                }
            }
        }
        let yaw = frame.vehicle.yaw;
        for r in self.regions.iter_mut() {
            let (sum, k) = self.placed[r.label as usize];
            if k == 0 {
                continue;
            }
            let (x, y) = (sum[0] / k as f64, sum[1] / k as f64);
            let (dx, dy) = (x - veh[0], y - veh[1]);
            r.position = [x, y, r.elevation_m];
            r.range_m = (dx * dx + dy * dy).sqrt();
            r.bearing_rad = (dy.atan2(dx) - yaw + std::f64::consts::PI)
                .rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
        }
        let mut rejected = [0u32; 4];
        for v in &self.verdicts[1..] {
            match v {
                Verdict::Water => {}
                Verdict::TooSmall => rejected[0] += 1,
                Verdict::AboveHorizon => rejected[1] += 1,
                Verdict::AboveGround => rejected[2] += 1,
                Verdict::InvalidCues => rejected[3] += 1,
            }
        }
        let cu = (w / 2).min(w - 1);
        Ok(Detection {
            mask: &self.mask,
            regions: &self.regions,
            candidates: n,
            rejected,
            map: &self.map,
            grid: map::geometry(&grid),
            sky,
            horizon_row: self.horizon[cu],
        })
    }
}
