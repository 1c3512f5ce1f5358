//! Hammerhead hazard map (paper section 4, "Mapping"): project one disparity image into a
//! vessel-centred ENU grid, gather per-cell statistics, filter spatially (isolated points against
//! the point density expected at that range) and temporally (a short per-cell evidence memory of the
//! same head, kept in world-anchored cells so the vessel's motion is compensated), then give each
//! observed cell a hazard probability from the offline-trained classifier and a traversal cost.
//!
//! Cell features (heights relative to the water plane, z = 0): highest, mean and lowest point and
//! their spread; `elevated_extent_m`, the elevated points (above the model's `elevated_height_m`)
//! divided by the points one metre of vertical surface would give in that cell at that range
//! (sampling step, focal length and the range smear of disparity noise included), i.e. roughly how
//! many metres of solid surface stand there; the elevated fraction; `history`, the decayed share
//! of this head's recent frames with elevated points at this world cell (0 for a first sighting);
//! the share of elevated 8-neighbours; `water_margin_px`, the disparity error that would lift water
//! on the ray of the highest point to its height (capped by the model); `lifted_height_m`, how far
//! the lowest point stands above [`crate::model::LIFT_HINGE_M`]. Cost: lethal (254) from
//! `cost.lethal_probability`, below it linear in the probability; unobserved cells 255.
//!
//! Buffers are sized at the first frame of a head (warm-up) and reused; a frame allocates nothing.
//! Heights are taken relative to the frame's own water level: a residual plane fitted to the
//! cells' mean heights corrects the tilt the stereo service's near-range water plane leaves at far
//! range ([`LevelConfig`]).
//!
//! Projection runs in parallel over image rows into a per-pixel buffer; accumulation into cells is
//! sequential in pixel order, so the output does not depend on thread timing.

use crate::geometry::{AttitudeSource, CameraToWorld, GeometryError};
use crate::model::{Features, HazardModel, LIFT_HINGE_M};
use messages::{DisparityHeader, GridGeometry, MapCell, Name, Pose};
use rayon::prelude::*;
use serde::Deserialize;

/// Most heads one mapper keeps a memory for.
pub const MAX_HEADS: usize = 8;

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct GridConfig {
    pub width: u32,
    pub height: u32,
    pub resolution_m: f64,
}

impl Default for GridConfig {
    fn default() -> Self {
        Self {
            width: 200,
            height: 200,
            resolution_m: 0.5,
        }
    }
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ProjectionConfig {
    /// Use every `row_step`-th row and `col_step`-th column of the disparity image.
    pub row_step: usize,
    pub col_step: usize,
    /// Optical depth limits of used points (m).
    pub min_range_m: f64,
    pub max_range_m: f64,
    /// Points below this height (m, relative to the water plane) are gross mismatches
    /// (reflections go below the water, so the bound is generous).
    pub min_height_m: f64,
    /// Clearance: points higher than this are above the vessel's air draft (bridge decks,
    /// overhanging branches) and no obstacle to it; most points up there are sky mismatches.
    pub max_height_m: f64,
}

impl Default for ProjectionConfig {
    fn default() -> Self {
        Self {
            row_step: 2,
            col_step: 2,
            min_range_m: 2.0,
            max_range_m: 70.0,
            min_height_m: -5.0,
            max_height_m: 6.0,
        }
    }
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SpatialConfig {
    /// A cell with at most this many elevated points and no elevated neighbour is isolated ...
    pub isolated_max_points: u32,
    /// ... when an obstacle of `min_obstacle_height_m` there would give at least this many points.
    pub min_expected_points: f32,
    pub min_obstacle_height_m: f32,
    /// Disparity noise (px): points of one surface smear over `2 z^2 sigma / (f B)` metres of range.
    pub disparity_sigma_px: f32,
    /// A cell is also isolated when its 3x3 block holds fewer elevated points than this share of
    /// what `min_obstacle_height_m` of surface would give in one cell at that range (0: off). Close
    /// in, a real surface gives hundreds of points a cell; canopy mismatches a bank's trees throw
    /// 8-10 m ahead, one point a cell at 5-6 m, support each other as neighbours and rated 0.6-0.8:
    /// on cluttered_river they boxed the boat in beside the bank until the run ended. The share
    /// matters only within about 20 m (at 0.1, for the simulated heads' 494 px focal length and every
    /// second pixel: 21 points at 8.5 m, 6 at 15 m, 2 at 20 m).
    pub sparse_max_fraction: f32,
}

impl Default for SpatialConfig {
    fn default() -> Self {
        Self {
            isolated_max_points: 1,
            min_expected_points: 3.0,
            min_obstacle_height_m: 0.5,
            disparity_sigma_px: 0.3,
            sparse_max_fraction: 0.1,
        }
    }
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct TemporalConfig {
    /// Time constant of the per-cell evidence memory (s); 0 disables it.
    pub tau_s: f64,
    /// A longer gap between two frames of a head (or time going backwards) clears its memory (s).
    pub max_gap_s: f64,
}

impl Default for TemporalConfig {
    fn default() -> Self {
        Self {
            tau_s: 0.6,
            max_gap_s: 2.0,
        }
    }
}

/// The residual water level: the water plane is fitted by the stereo service on near rows, and a
/// fraction of a degree of tilt left in it lifts or sinks far water by a metre (0.5 deg at 60 m is
/// 0.5 m), which the classifier then takes for objects. Each frame, a plane `h = a + b x + c y`
/// (x, y: metres from the camera) is fitted to the cells' mean heights with shrinking trims (so
/// objects and shore drop out) and subtracted from every point before the cells are scored.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct LevelConfig {
    pub enabled: bool,
    /// Fewer cells inside the last trim leave the frame uncorrected.
    pub min_cells: u32,
    /// A steeper residual plane is not water (shore, a bad frame) and leaves the frame uncorrected.
    pub max_slope_deg: f64,
    /// Largest offset at the camera (m) accepted, for the same reason.
    pub max_offset_m: f64,
    /// Only cells within this distance of the camera (m) are fitted (default: every mapped cell).
    /// Mapping farther than about 65 m with the 640x480 heads needs it: far water's heights are
    /// noisier (range error grows with the square of range) and far cells outnumber near ones, so
    /// they would move the level near the boat (ARCHITECTURE.md, mapping range).
    pub max_range_m: f64,
}

impl Default for LevelConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            min_cells: 200,
            max_slope_deg: 3.0,
            max_offset_m: 1.0,
            max_range_m: f64::INFINITY,
        }
    }
}

/// Trims (m) of the residual level fit's passes: cells farther from the previous pass's plane are
/// left out, so the first pass sees everything but tall objects and the last only water.
const LEVEL_TRIMS_M: [f64; 4] = [2.0, 1.0, 0.5, 0.3];

/// Far objects ranged as one: stereo range noise grows with the square of range (about 5 m, one
/// sigma, at 100 m on the 640x480 heads), so the pixels of one far boat land over 10-20 m of range
/// and map as a long blob. Beyond `min_range_m`, elevated sampled pixels are grouped into image
/// segments (4-connected, neighbours within `join_px` of disparity); a segment of at least
/// `min_points` whose disparities agree (median absolute deviation at most `max_mad_px`: a
/// vertical surface, not water or a bank receding in range) is projected again at its median
/// disparity. Pixels beyond the projection's range limit join segments too, so an object across
/// the limit is placed by all of its pixels. Off by default (`min_range_m` infinite).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SegmentConfig {
    pub min_range_m: f64,
    pub join_px: f32,
    pub min_points: u32,
    pub max_mad_px: f32,
}

impl Default for SegmentConfig {
    fn default() -> Self {
        Self {
            min_range_m: f64::INFINITY,
            join_px: 1.0,
            min_points: 4,
            max_mad_px: 0.5,
        }
    }
}

impl SegmentConfig {
    fn enabled(&self) -> bool {
        self.min_range_m.is_finite()
    }
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CostConfig {
    /// Hazard probability from which a cell is lethal.
    pub lethal_probability: f32,
}

impl Default for CostConfig {
    fn default() -> Self {
        Self {
            lethal_probability: 0.5,
        }
    }
}

/// Everything the mapper needs besides the model.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct HazardConfig {
    pub grid: GridConfig,
    pub projection: ProjectionConfig,
    pub spatial: SpatialConfig,
    pub temporal: TemporalConfig,
    pub level: LevelConfig,
    pub segments: SegmentConfig,
    pub cost: CostConfig,
}

impl HazardConfig {
    pub fn validate(&self) -> Result<(), String> {
        let g = &self.grid;
        if !(1..=4096).contains(&g.width) || !(1..=4096).contains(&g.height) {
            return Err("grid width and height must be within 1..=4096".into());
        }
        if !(g.resolution_m.is_finite() && g.resolution_m > 0.0) {
            return Err("grid.resolution_m must be > 0".into());
        }
        let p = &self.projection;
        if !(1..=64).contains(&p.row_step) || !(1..=64).contains(&p.col_step) {
            return Err("projection steps must be within 1..=64".into());
        }
        if !(p.min_range_m >= 0.0 && p.max_range_m > p.min_range_m) {
            return Err("projection needs 0 <= min_range_m < max_range_m".into());
        }
        if p.max_height_m.is_nan() || p.min_height_m.is_nan() || p.max_height_m <= p.min_height_m {
            return Err("projection needs min_height_m < max_height_m".into());
        }
        let sf = self.spatial.sparse_max_fraction;
        if !(sf.is_finite() && (0.0..=1.0).contains(&sf)) {
            return Err(format!(
                "spatial.sparse_max_fraction must be within [0, 1], got {sf}"
            ));
        }
        if !(self.temporal.tau_s >= 0.0 && self.temporal.max_gap_s > 0.0) {
            return Err("temporal needs tau_s >= 0 and max_gap_s > 0".into());
        }
        let lv = &self.level;
        if !(lv.max_slope_deg >= 0.0
            && lv.max_slope_deg < 45.0
            && lv.max_offset_m >= 0.0
            && lv.max_range_m > 0.0)
        {
            return Err(
                "level needs 0 <= max_slope_deg < 45, max_offset_m >= 0 and max_range_m > 0".into(),
            );
        }
        let sg = &self.segments;
        if !(sg.min_range_m > 0.0 && sg.join_px > 0.0 && sg.min_points >= 1 && sg.max_mad_px >= 0.0)
        {
            return Err(
                "segments need min_range_m > 0, join_px > 0, min_points >= 1 and max_mad_px >= 0"
                    .into(),
            );
        }
        let l = self.cost.lethal_probability;
        if !(l > 0.0 && l <= 1.0) {
            return Err("cost.lethal_probability must be within (0, 1]".into());
        }
        Ok(())
    }
}

/// Why a frame was not mapped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    #[error("disparity of {pixels} values does not match its header's {width}x{height}")]
    Size {
        pixels: usize,
        width: u32,
        height: u32,
    },
    #[error("disparity image has zero size")]
    Empty,
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    #[error("vessel pose is not finite")]
    VesselPose,
    #[error("output has {got} cells, the grid {expected}")]
    Output { got: usize, expected: usize },
    #[error("more than {MAX_HEADS} heads")]
    TooManyHeads,
}

/// One disparity frame and the vessel pose at its stamp.
pub struct Frame<'a> {
    pub header: &'a DisparityHeader,
    pub disparity: &'a [f32],
    pub vessel: Pose,
}

/// What a frame produced besides the cells.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameSummary {
    pub grid: GridGeometry,
    pub attitude: AttitudeSource,
    /// Projected points that landed in the grid.
    pub points: usize,
    pub observed_cells: usize,
    /// Cells at or above the lethal probability.
    pub hazard_cells: usize,
    /// Cells whose elevated points were dropped as isolated.
    pub isolated_cells: usize,
    /// Far segments projected again at their median disparity ([`SegmentConfig`]).
    pub far_segments: usize,
    /// The residual water level subtracted from the heights, if one was fitted.
    pub level: Option<WaterLevel>,
}

/// A residual water level `h = offset + slope[0] x + slope[1] y` (m; x east and y north of the
/// camera, in metres).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WaterLevel {
    pub offset_m: f64,
    pub slope: [f64; 2],
    /// Cells inside the last trim.
    pub cells: u32,
}

impl WaterLevel {
    /// Tilt of the level plane (deg).
    pub fn tilt_deg(&self) -> f64 {
        self.slope[0].hypot(self.slope[1]).atan().to_degrees()
    }
}

/// A sampled pixel's cell (`u32::MAX` = none), height above the water and optical depth. A pixel
/// with a valid point outside the range limit or the grid keeps its height and depth (depth 0: no
/// point).
#[derive(Clone, Copy, Debug, Default)]
pub struct PointSample {
    pub cell: u32,
    pub height: f32,
    pub depth: f32,
}

const NO_CELL: u32 = u32::MAX;
const NO_POINT: PointSample = PointSample {
    cell: NO_CELL,
    height: 0.0,
    depth: 0.0,
};

#[derive(Clone, Copy, Default)]
struct CellStats {
    count: u32,
    elevated: u32,
    max_h: f32,
    min_h: f32,
    sum_h: f32,
}

/// An observed cell of the current frame with its features and probability.
#[derive(Clone, Copy, Debug)]
pub struct ScoredCell {
    pub cell: u32,
    pub features: Features,
    pub probability: f32,
    pub isolated: bool,
}

#[derive(Clone, Copy, Default)]
struct MemoryCell {
    /// Absolute (world-anchored) cell index this slot holds.
    key: [i64; 2],
    stamp_ns: u64,
    evidence: f32,
    seen: f32,
    /// Bit 0: counted as seen this frame; bit 1: counted as evidence this frame.
    flags: u8,
    used: bool,
}

struct HeadMemory {
    head: Name,
    last_stamp_ns: u64,
    cells: Vec<MemoryCell>,
}

/// The per-frame hazard mapper of one service (any number of heads up to [`MAX_HEADS`]).
pub struct HazardMapper {
    config: HazardConfig,
    model: HazardModel,
    stats: Vec<CellStats>,
    touched: Vec<u32>,
    points: Vec<PointSample>,
    scored: Vec<ScoredCell>,
    heads: Vec<HeadMemory>,
    sampled_cols: usize,
    segments: SegmentScratch,
}

/// Reused buffers of the far-segment grouping (a frame allocates nothing).
#[derive(Default)]
struct SegmentScratch {
    visited: Vec<bool>,
    stack: Vec<u32>,
    members: Vec<u32>,
    disparities: Vec<f32>,
}

/// Absolute index of the grid's south-west cell and the grid, snapped so that cell edges lie on
/// multiples of the resolution (cells are then the same world squares from frame to frame).
fn snapped_grid(g: &GridConfig, vessel: [f64; 2]) -> (GridGeometry, [i64; 2]) {
    let r = g.resolution_m;
    let half = [g.width as f64 * r / 2.0, g.height as f64 * r / 2.0];
    let corner = [
        ((vessel[0] - half[0]) / r).round() as i64,
        ((vessel[1] - half[1]) / r).round() as i64,
    ];
    let grid = GridGeometry {
        width: g.width,
        height: g.height,
        resolution_m: r,
        center: [
            corner[0] as f64 * r + half[0],
            corner[1] as f64 * r + half[1],
        ],
    };
    (grid, corner)
}

impl HazardMapper {
    pub fn new(config: HazardConfig, model: HazardModel) -> Result<Self, String> {
        config.validate()?;
        model.validate()?;
        let n = config.grid.width as usize * config.grid.height as usize;
        Ok(Self {
            stats: vec![CellStats::default(); n],
            touched: Vec::with_capacity(n),
            points: Vec::new(),
            scored: Vec::with_capacity(n),
            heads: Vec::new(),
            sampled_cols: 0,
            segments: SegmentScratch::default(),
            config,
            model,
        })
    }

    pub fn config(&self) -> &HazardConfig {
        &self.config
    }

    pub fn model(&self) -> &HazardModel {
        &self.model
    }

    /// The grid a frame with the vessel at `vessel` (ENU) is mapped into.
    pub fn grid_at(&self, vessel: [f64; 2]) -> GridGeometry {
        snapped_grid(&self.config.grid, vessel).0
    }

    /// The cells of the last frame that had points, in grid order of first touch.
    pub fn scored_cells(&self) -> &[ScoredCell] {
        &self.scored
    }

    /// The last frame's sampled pixels: entry `i` is pixel
    /// `(u, v) = ((i % cols) * col_step, (i / cols) * row_step)` with `cols` the second value.
    pub fn sampled_points(&self) -> (&[PointSample], usize) {
        (&self.points, self.sampled_cols)
    }

    /// Checks a frame without mapping it (the same checks [`Self::process`] makes).
    pub fn check(&self, frame: &Frame<'_>) -> Result<CameraToWorld, FrameError> {
        let h = frame.header;
        if h.width == 0 || h.height == 0 {
            return Err(FrameError::Empty);
        }
        if frame.disparity.len() != h.pixel_count() {
            return Err(FrameError::Size {
                pixels: frame.disparity.len(),
                width: h.width,
                height: h.height,
            });
        }
        let v = &frame.vessel;
        if !(v.position.iter().all(|x| x.is_finite()) && v.yaw.is_finite()) {
            return Err(FrameError::VesselPose);
        }
        Ok(CameraToWorld::from_header(h)?)
    }

    /// Maps one frame into `out` (the whole grid: unobserved cells get cost 255).
    pub fn process(
        &mut self,
        frame: &Frame<'_>,
        out: &mut [MapCell],
    ) -> Result<FrameSummary, FrameError> {
        let xf = self.check(frame)?;
        let (grid, corner) = snapped_grid(
            &self.config.grid,
            [frame.vessel.position[0], frame.vessel.position[1]],
        );
        if out.len() != grid.cell_count() {
            return Err(FrameError::Output {
                got: out.len(),
                expected: grid.cell_count(),
            });
        }
        let head_index = self.head_memory(frame.header)?;
        let projector = Projector::new(frame.header, &self.config.projection, &xf, &grid);
        self.project(frame, &projector);
        let far_segments = self.range_far_segments(&projector);
        self.accumulate();
        let level = self.level(&xf, &grid);
        if let Some(l) = &level {
            self.subtract_level(l, &xf, &grid);
            self.accumulate();
        }
        let isolated_cells = self.score(frame.header, &xf, &grid, head_index, corner);
        self.remember(frame.header.hdr.stamp_ns, head_index, corner);

        out.fill(MapCell {
            cost: MapCell::UNKNOWN_COST,
            ..MapCell::default()
        });
        let lethal = self.config.cost.lethal_probability;
        let mut hazard_cells = 0;
        let mut points = 0;
        for s in &self.scored {
            let st = &self.stats[s.cell as usize];
            points += st.count as usize;
            let p = s.probability;
            let cost = if p >= lethal {
                hazard_cells += 1;
                MapCell::LETHAL_COST
            } else {
                ((p / lethal) * MapCell::LETHAL_COST as f32)
                    .round()
                    .min(MapCell::LETHAL_COST as f32 - 1.0) as u8
            };
            out[s.cell as usize] = MapCell {
                hazard: (p * 255.0).round() as u8,
                cost,
                water: 0,
                observed: st.count.min(255) as u8,
                max_height_cm: cm(st.max_h),
                elevation_cm: cm(st.sum_h / st.count as f32),
            };
        }
        Ok(FrameSummary {
            grid,
            attitude: xf.source,
            points,
            observed_cells: self.scored.len(),
            hazard_cells,
            isolated_cells,
            far_segments,
            level,
        })
    }

    fn head_memory(&mut self, h: &DisparityHeader) -> Result<usize, FrameError> {
        let stamp = h.hdr.stamp_ns;
        let max_gap = (self.config.temporal.max_gap_s * 1e9) as u64;
        if let Some(i) = self.heads.iter().position(|m| m.head == h.head) {
            let m = &mut self.heads[i];
            if stamp < m.last_stamp_ns || stamp - m.last_stamp_ns > max_gap {
                m.cells.fill(MemoryCell::default());
            }
            return Ok(i);
        }
        if self.heads.len() == MAX_HEADS {
            return Err(FrameError::TooManyHeads);
        }
        self.heads.push(HeadMemory {
            head: h.head,
            last_stamp_ns: stamp,
            cells: vec![MemoryCell::default(); self.stats.len()],
        });
        Ok(self.heads.len() - 1)
    }

    /// Disparity -> optical point -> ENU -> cell, in parallel over sampled rows.
    fn project(&mut self, frame: &Frame<'_>, projector: &Projector) {
        let h = frame.header;
        let p = &self.config.projection;
        let (w, ht) = (h.width as usize, h.height as usize);
        let (rs, cs) = (p.row_step, p.col_step);
        let cols = w.div_ceil(cs);
        let rows = ht.div_ceil(rs);
        self.sampled_cols = cols;
        self.points.resize(rows * cols, PointSample::default());
        let (fb, zmin) = (projector.fb, p.min_range_m as f32);
        let disp = frame.disparity;
        self.points
            .par_chunks_mut(cols)
            .enumerate()
            .for_each(|(r, row)| {
                let v = r * rs;
                let line = &disp[v * w..v * w + w];
                for (k, out) in row.iter_mut().enumerate() {
                    let u = k * cs;
                    let d = line[u];
                    *out = NO_POINT;
                    if d.is_nan() || d <= 0.0 {
                        continue; // NaN or at infinity
                    }
                    let z = fb / d;
                    if z < zmin {
                        continue;
                    }
                    *out = projector.sample(u, v, z).unwrap_or(NO_POINT);
                }
            });
    }

    /// Groups far elevated pixels into image segments and projects each agreeing segment again at
    /// its median disparity ([`SegmentConfig`]). Returns the segments so placed.
    fn range_far_segments(&mut self, projector: &Projector) -> usize {
        let sc = &self.config.segments;
        if !sc.enabled() {
            return 0;
        }
        let fb = projector.fb;
        let (zmin, elevated) = (sc.min_range_m as f32, self.model.elevated_height_m);
        let candidate = |p: &PointSample| p.depth >= zmin && p.height > elevated;
        let p = &self.config.projection;
        let (rs, cs, cols) = (p.row_step, p.col_step, self.sampled_cols);
        let n = self.points.len();
        let SegmentScratch {
            visited,
            stack,
            members,
            disparities,
        } = &mut self.segments;
        visited.clear();
        visited.resize(n, false);
        let mut placed = 0;
        for seed in 0..n {
            if visited[seed] || !candidate(&self.points[seed]) {
                continue;
            }
            visited[seed] = true;
            stack.clear();
            members.clear();
            stack.push(seed as u32);
            while let Some(i) = stack.pop() {
                let i = i as usize;
                members.push(i as u32);
                let d = fb / self.points[i].depth;
                let (col, row) = (i % cols, i / cols);
                let neighbours = [
                    (col > 0).then(|| i - 1),
                    (col + 1 < cols).then(|| i + 1),
                    (row > 0).then(|| i - cols),
                    (i + cols < n).then(|| i + cols),
                ];
                for j in neighbours.into_iter().flatten() {
                    let q = &self.points[j];
                    if !visited[j] && candidate(q) && (fb / q.depth - d).abs() <= sc.join_px {
                        visited[j] = true;
                        stack.push(j as u32);
                    }
                }
            }
            if members.len() < sc.min_points as usize {
                continue;
            }
            disparities.clear();
            disparities.extend(members.iter().map(|&i| fb / self.points[i as usize].depth));
            let median = median_of(disparities);
            disparities
                .iter_mut()
                .for_each(|d| *d = (*d - median).abs());
            if median_of(disparities) > sc.max_mad_px {
                continue;
            }
            let z = fb / median;
            for &i in members.iter() {
                let i = i as usize;
                let (u, v) = ((i % cols) * cs, (i / cols) * rs);
                self.points[i] = projector.sample(u, v, z).unwrap_or(NO_POINT);
            }
            placed += 1;
        }
        placed
    }

    /// Grid-local coordinates of the camera (m from the grid's south-west corner).
    fn camera_in_grid(xf: &CameraToWorld, grid: &GridGeometry) -> [f64; 2] {
        [
            xf.origin[0] as f64 - (grid.center[0] - grid.width as f64 * grid.resolution_m / 2.0),
            xf.origin[1] as f64 - (grid.center[1] - grid.height as f64 * grid.resolution_m / 2.0),
        ]
    }

    /// Cell centre relative to the camera (m).
    fn from_camera(cell: u32, cam: [f64; 2], grid: &GridGeometry) -> [f64; 2] {
        let (col, row) = (cell % grid.width, cell / grid.width);
        [
            (col as f64 + 0.5) * grid.resolution_m - cam[0],
            (row as f64 + 0.5) * grid.resolution_m - cam[1],
        ]
    }

    /// Fits the residual water level to the touched cells' mean heights (see [`LevelConfig`]).
    fn level(&self, xf: &CameraToWorld, grid: &GridGeometry) -> Option<WaterLevel> {
        let cfg = &self.config.level;
        if !cfg.enabled {
            return None;
        }
        let cam = Self::camera_in_grid(xf, grid);
        let max_range_sq = cfg.max_range_m * cfg.max_range_m;
        let mut plane = nalgebra::Vector3::<f64>::zeros();
        let mut cells = 0;
        for trim in LEVEL_TRIMS_M {
            let mut ata = nalgebra::Matrix3::<f64>::zeros();
            let mut atb = nalgebra::Vector3::<f64>::zeros();
            cells = 0;
            for &cell in &self.touched {
                let s = &self.stats[cell as usize];
                let [x, y] = Self::from_camera(cell, cam, grid);
                if x * x + y * y > max_range_sq {
                    continue;
                }
                let a = nalgebra::Vector3::new(1.0, x, y);
                let m = (s.sum_h / s.count as f32) as f64;
                if (m - a.dot(&plane)).abs() > trim {
                    continue;
                }
                ata += a * a.transpose();
                atb += a * m;
                cells += 1;
            }
            if cells < cfg.min_cells {
                return None;
            }
            plane = ata.lu().solve(&atb)?;
        }
        let level = WaterLevel {
            offset_m: plane[0],
            slope: [plane[1], plane[2]],
            cells,
        };
        (level.tilt_deg() <= cfg.max_slope_deg && level.offset_m.abs() <= cfg.max_offset_m)
            .then_some(level)
    }

    fn subtract_level(&mut self, level: &WaterLevel, xf: &CameraToWorld, grid: &GridGeometry) {
        let cam = Self::camera_in_grid(xf, grid);
        for p in self.points.iter_mut().filter(|p| p.cell != NO_CELL) {
            let [x, y] = Self::from_camera(p.cell, cam, grid);
            p.height -= (level.offset_m + level.slope[0] * x + level.slope[1] * y) as f32;
        }
    }

    fn accumulate(&mut self) {
        for &c in &self.touched {
            self.stats[c as usize] = CellStats::default();
        }
        self.touched.clear();
        let elevated = self.model.elevated_height_m;
        for p in &self.points {
            if p.cell == NO_CELL {
                continue;
            }
            let s = &mut self.stats[p.cell as usize];
            if s.count == 0 {
                self.touched.push(p.cell);
                s.max_h = f32::MIN;
                s.min_h = f32::MAX;
            }
            s.count += 1;
            s.elevated += (p.height > elevated) as u32;
            s.max_h = s.max_h.max(p.height);
            s.min_h = s.min_h.min(p.height);
            s.sum_h += p.height;
        }
    }

    /// Features, spatial filter and classifier for every touched cell. Returns the isolated count.
    fn score(
        &mut self,
        h: &DisparityHeader,
        xf: &CameraToWorld,
        grid: &GridGeometry,
        head: usize,
        corner: [i64; 2],
    ) -> usize {
        let (gw, gh) = (grid.width as i64, grid.height as i64);
        let res = grid.resolution_m as f32;
        let f = (h.camera.fx * h.camera.fy).sqrt() as f32;
        let fb = (h.camera.fx * h.camera.baseline_m) as f32;
        let cam_h = xf.origin[2].max(0.5);
        let p = &self.config.projection;
        let (rs, cs) = (p.row_step as f32, p.col_step as f32);
        let sp = &self.config.spatial;
        let tau = self.config.temporal.tau_s;
        let stamp = h.hdr.stamp_ns;
        let memory = &self.heads[head].cells;
        let cam = Self::camera_in_grid(xf, grid);
        self.scored.clear();
        let mut isolated_cells = 0;
        for &cell in &self.touched {
            let s = &self.stats[cell as usize];
            let (col, row) = ((cell as i64) % gw, (cell as i64) / gw);
            // Elevated neighbours in this frame (8-neighbourhood), and their elevated points.
            let (mut neighbours, mut block_elevated) = (0u32, s.elevated);
            for dr in -1..=1i64 {
                for dc in -1..=1i64 {
                    let (c2, r2) = (col + dc, row + dr);
                    if (dc, dr) != (0, 0) && c2 >= 0 && r2 >= 0 && c2 < gw && r2 < gh {
                        let e = self.stats[(r2 * gw + c2) as usize].elevated;
                        neighbours += (e > 0) as u32;
                        block_elevated += e;
                    }
                }
            }
            let range = (((col as f64 + 0.5) * grid.resolution_m - cam[0])
                .hypot((row as f64 + 0.5) * grid.resolution_m - cam[1]))
            .max(1.0) as f32;
            // Points per metre of vertical surface one cell wide at this range, spread over the
            // cells that range noise smears one surface across.
            let smear = (2.0 * range * range * sp.disparity_sigma_px / fb / res).max(1.0);
            let density = (f * res / (range * cs)) * (f / (range * rs)) / smear;
            let expected = density * sp.min_obstacle_height_m;
            let isolated = s.elevated > 0
                && (s.elevated <= sp.isolated_max_points
                    && neighbours == 0
                    && expected >= sp.min_expected_points
                    || (block_elevated as f32) < sp.sparse_max_fraction * expected);
            isolated_cells += isolated as usize;
            let key = [corner[0] + col, corner[1] + row];
            let history = recall(memory, grid, key, stamp, tau);
            let mean_h = s.sum_h / s.count as f32;
            let elevated = if isolated { 0 } else { s.elevated };
            let features: Features = [
                s.max_h.clamp(-2.0, 8.0),
                mean_h.clamp(-2.0, 8.0),
                (s.max_h - s.min_h).clamp(0.0, 8.0),
                (elevated as f32 / density).min(8.0),
                elevated as f32 / s.count as f32,
                s.min_h.clamp(-2.0, 8.0),
                history,
                neighbours as f32 / 8.0,
                // The disparity error (px) that would lift water seen along the ray of the
                // cell's highest point to that height: d h / camera height. Small for the
                // "walls" that mismatched water near the horizon builds; large for real objects.
                (fb / range * s.max_h.max(0.0) / cam_h).min(self.model.water_margin_cap_px),
                (s.min_h - LIFT_HINGE_M).clamp(0.0, 8.0),
            ];
            let probability = if isolated {
                0.0
            } else {
                self.model.probability(&features)
            };
            self.scored.push(ScoredCell {
                cell,
                features,
                probability,
                isolated,
            });
        }
        isolated_cells
    }

    /// Updates the head's memory: every observed cell was seen; cells with (non-isolated) elevated
    /// points leave evidence in their 3x3 neighbourhood, which absorbs sub-cell registration error.
    fn remember(&mut self, stamp: u64, head: usize, corner: [i64; 2]) {
        let tau = self.config.temporal.tau_s;
        let g = &self.config.grid;
        let (gw, gh) = (g.width as i64, g.height as i64);
        let m = &mut self.heads[head];
        m.last_stamp_ns = stamp;
        if tau <= 0.0 {
            return;
        }
        for s in &self.scored {
            let (col, row) = ((s.cell as i64) % gw, (s.cell as i64) / gw);
            touch(
                &mut m.cells,
                gw,
                gh,
                [corner[0] + col, corner[1] + row],
                stamp,
                tau,
                true,
                false,
            );
            let st = &self.stats[s.cell as usize];
            if st.elevated > 0 && !s.isolated {
                for dr in -1..=1 {
                    for dc in -1..=1 {
                        let key = [corner[0] + col + dc, corner[1] + row + dr];
                        touch(&mut m.cells, gw, gh, key, stamp, tau, false, true);
                    }
                }
            }
        }
    }
}

/// Optical ray -> ENU relative to the grid's south-west corner -> cell: the projection of one
/// frame, shared by the per-pixel pass and the far segments.
struct Projector {
    /// `world_from_optical` with the origin in grid-local metres (f32 about the camera keeps
    /// precision far from the ENU origin).
    local: CameraToWorld,
    /// Focal length times baseline (px m): depth = fb / disparity.
    fb: f32,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    zmax: f32,
    hmin: f32,
    hmax: f32,
    inv_res: f32,
    grid_size: [f32; 2],
    grid_width: u32,
}

impl Projector {
    fn new(
        h: &DisparityHeader,
        p: &ProjectionConfig,
        xf: &CameraToWorld,
        grid: &GridGeometry,
    ) -> Self {
        let cam = HazardMapper::camera_in_grid(xf, grid);
        let mut local = *xf;
        local.origin[0] = cam[0] as f32;
        local.origin[1] = cam[1] as f32;
        let c = &h.camera;
        Self {
            local,
            fb: (c.fx * c.baseline_m) as f32,
            fx: c.fx as f32,
            fy: c.fy as f32,
            cx: c.cx as f32,
            cy: c.cy as f32,
            zmax: p.max_range_m as f32,
            hmin: p.min_height_m as f32,
            hmax: p.max_height_m as f32,
            inv_res: (1.0 / grid.resolution_m) as f32,
            grid_size: [grid.width as f32, grid.height as f32],
            grid_width: grid.width,
        }
    }

    /// Pixel (u, v) at optical depth `z`: `None` outside the height limits; without a cell beyond
    /// the range limit or off the grid.
    fn sample(&self, u: usize, v: usize, z: f32) -> Option<PointSample> {
        let vy = (v as f32 - self.cy) / self.fy;
        let q = self
            .local
            .apply([(u as f32 - self.cx) / self.fx * z, vy * z, z]);
        if q[2] < self.hmin || q[2] > self.hmax {
            return None;
        }
        let (col, row) = (q[0] * self.inv_res, q[1] * self.inv_res);
        let [gw, gh] = self.grid_size;
        let on_grid = col >= 0.0 && row >= 0.0 && col < gw && row < gh;
        let cell = if z <= self.zmax && on_grid {
            row as u32 * self.grid_width + col as u32
        } else {
            NO_CELL
        };
        Some(PointSample {
            cell,
            height: q[2],
            depth: z,
        })
    }
}

/// Median of a non-empty slice (reorders it).
fn median_of(values: &mut [f32]) -> f32 {
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f32::total_cmp).1
}

fn cm(m: f32) -> i16 {
    (m * 100.0).round().clamp(i16::MIN as f32, i16::MAX as f32) as i16
}

fn slot(gw: i64, gh: i64, key: [i64; 2]) -> usize {
    (key[1].rem_euclid(gh) * gw + key[0].rem_euclid(gw)) as usize
}

fn decay(from_ns: u64, to_ns: u64, tau: f64) -> f32 {
    (-(to_ns.saturating_sub(from_ns) as f64 * 1e-9) / tau).exp() as f32
}

/// Evidence of earlier frames at a world cell: decayed elevated frames over decayed observations
/// plus one (a cell seen once has weak history), in 0..1.
fn recall(memory: &[MemoryCell], grid: &GridGeometry, key: [i64; 2], stamp: u64, tau: f64) -> f32 {
    if tau <= 0.0 {
        return 0.0;
    }
    let m = &memory[slot(grid.width as i64, grid.height as i64, key)];
    if !m.used || m.key != key || m.stamp_ns >= stamp {
        return 0.0;
    }
    let a = decay(m.stamp_ns, stamp, tau);
    (m.evidence * a / (m.seen * a + 1.0)).min(1.0)
}

#[allow(clippy::too_many_arguments)]
fn touch(
    cells: &mut [MemoryCell],
    gw: i64,
    gh: i64,
    key: [i64; 2],
    stamp: u64,
    tau: f64,
    seen: bool,
    evidence: bool,
) {
    let m = &mut cells[slot(gw, gh, key)];
    if !m.used || m.key != key {
        *m = MemoryCell {
            key,
            stamp_ns: stamp,
            used: true,
            ..MemoryCell::default()
        };
    } else if m.stamp_ns != stamp {
        let a = decay(m.stamp_ns, stamp, tau);
        m.evidence *= a;
        m.seen *= a;
        m.stamp_ns = stamp;
        m.flags = 0;
    }
    if seen && m.flags & 1 == 0 {
        m.seen += 1.0;
        m.flags |= 1;
    }
    if evidence && m.flags & 2 == 0 {
        m.evidence += 1.0;
        m.flags |= 2;
    }
}

#[cfg(test)]
mod tests;
