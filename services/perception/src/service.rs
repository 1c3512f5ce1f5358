//! The service's configuration and its per-frame glue around the mapper: which heads are mapped,
//! the vessel pose from the INS nearest to the frame stamp, and the local-map header.
//!
//! Frames that cannot be mapped are rejected (the caller counts them with `Health::reject`): a
//! payload that does not have `width * height` values, a zero size, an invalid camera model, a
//! water plane that is marked valid but is not (non-unit normal, camera below it) or a non-finite
//! pose. A frame whose water plane was not found (`plane.valid == 0`) is mapped with the INS
//! attitude that the stereo service leaves in the stabilized pose in that case (see
//! [`crate::geometry`]); its heights are then only as good as the INS altitude.

use crate::hazard::{
    CostConfig, Frame, FrameError, FrameSummary, GridConfig, HazardConfig, HazardMapper,
    LevelConfig, ProjectionConfig, SegmentConfig, SpatialConfig, TemporalConfig,
};
use crate::model::HazardModel;
use anyhow::Context;
use messages::{DisparityHeader, Header, InsState, LocalMapHeader, MapCell, Pose};
use serde::Deserialize;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// `perception run --config FILE`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceConfig {
    /// Hazard model file, relative to the config file.
    pub model: PathBuf,
    /// Heads to map; empty = every head on the disparity topic.
    #[serde(default)]
    pub heads: Vec<String>,
    /// Longest expected gap between disparity images before the heartbeat reports it (ms).
    #[serde(default = "default_deadline")]
    pub frame_deadline_ms: u64,
    /// The INS sample used for the vessel pose must be this close to the frame stamp (ms); without
    /// one, the stabilized pose's position and heading are used.
    #[serde(default = "default_ins_gap")]
    pub ins_max_gap_ms: u64,
    /// After the first head of a frame, wait this long for the other heads before publishing the
    /// frame's map without them (ms, wall clock).
    #[serde(default = "default_head_wait")]
    pub head_wait_ms: u64,
    #[serde(default)]
    pub grid: GridConfig,
    #[serde(default)]
    pub projection: ProjectionConfig,
    #[serde(default)]
    pub spatial: SpatialConfig,
    #[serde(default)]
    pub temporal: TemporalConfig,
    #[serde(default)]
    pub level: LevelConfig,
    #[serde(default)]
    pub segments: SegmentConfig,
    #[serde(default)]
    pub cost: CostConfig,
    /// Water detection on colour heads; off unless `[water] heads` names some.
    #[serde(default)]
    pub water: crate::water_stage::WaterSettings,
}

fn default_deadline() -> u64 {
    1000
}

fn default_ins_gap() -> u64 {
    200
}

fn default_head_wait() -> u64 {
    1000
}

impl ServiceConfig {
    pub fn hazard(&self) -> HazardConfig {
        HazardConfig {
            grid: self.grid.clone(),
            projection: self.projection.clone(),
            spatial: self.spatial.clone(),
            temporal: self.temporal.clone(),
            level: self.level.clone(),
            segments: self.segments.clone(),
            cost: self.cost.clone(),
        }
    }

    /// The model path resolved against the config file's directory.
    pub fn model_path(&self, config_path: &Path) -> PathBuf {
        if self.model.is_absolute() {
            self.model.clone()
        } else {
            config_path
                .parent()
                .unwrap_or(Path::new("."))
                .join(&self.model)
        }
    }
}

/// Newest INS samples, for the one nearest a frame stamp.
pub struct InsHistory {
    samples: VecDeque<InsState>,
}

const INS_HISTORY: usize = 256;

impl Default for InsHistory {
    fn default() -> Self {
        Self {
            samples: VecDeque::with_capacity(INS_HISTORY),
        }
    }
}

impl InsHistory {
    /// Keeps a valid sample (stamps in arrival order; an older stamp restarts the history).
    pub fn push(&mut self, s: InsState) -> Result<(), &'static str> {
        s.validate()?;
        if self
            .samples
            .back()
            .is_some_and(|b| s.hdr.stamp_ns < b.hdr.stamp_ns)
        {
            self.samples.clear();
        }
        if self.samples.len() == INS_HISTORY {
            self.samples.pop_front();
        }
        self.samples.push_back(s);
        Ok(())
    }

    /// The sample nearest `stamp_ns`, if within `max_gap_ns`.
    pub fn nearest(&self, stamp_ns: u64, max_gap_ns: u64) -> Option<&InsState> {
        self.samples
            .iter()
            .min_by_key(|s| s.hdr.stamp_ns.abs_diff(stamp_ns))
            .filter(|s| s.hdr.stamp_ns.abs_diff(stamp_ns) <= max_gap_ns)
    }
}

/// The mapper plus what the service adds around it.
pub struct Perception {
    mapper: HazardMapper,
    heads: Vec<String>,
    ins: InsHistory,
    ins_max_gap_ns: u64,
}

impl Perception {
    /// Builds from a config file's contents; the model is loaded from `model_path` (a missing or
    /// corrupt model is an error).
    pub fn new(config: &ServiceConfig, model_path: &Path) -> anyhow::Result<Self> {
        let model = HazardModel::load(model_path)?;
        let mapper = HazardMapper::new(config.hazard(), model)
            .map_err(|e| anyhow::anyhow!("invalid configuration: {e}"))
            .context("hazard mapper")?;
        Ok(Self {
            mapper,
            heads: config.heads.clone(),
            ins: InsHistory::default(),
            ins_max_gap_ns: config.ins_max_gap_ms * 1_000_000,
        })
    }

    pub fn mapper(&self) -> &HazardMapper {
        &self.mapper
    }

    pub fn cell_count(&self) -> usize {
        let g = &self.mapper.config().grid;
        g.width as usize * g.height as usize
    }

    /// Is this head one the configuration maps?
    pub fn accepts(&self, head: &str) -> bool {
        self.heads.is_empty() || self.heads.iter().any(|h| h == head)
    }

    pub fn add_ins(&mut self, s: InsState) -> Result<(), &'static str> {
        self.ins.push(s)
    }

    /// Vessel pose at the frame: the nearest INS sample, else the stabilized pose's position and
    /// heading (level).
    pub fn vessel_pose(&self, h: &DisparityHeader) -> Pose {
        match self.ins.nearest(h.hdr.stamp_ns, self.ins_max_gap_ns) {
            Some(s) => s.pose,
            None => Pose {
                position: h.stabilized_pose.position,
                yaw: h.stabilized_pose.yaw,
                ..Pose::default()
            },
        }
    }

    /// Maps one frame into `out`; returns the local map's header (seq and source from the caller).
    pub fn process(
        &mut self,
        h: &DisparityHeader,
        disparity: &[f32],
        out: &mut [MapCell],
        header: Header,
    ) -> Result<(LocalMapHeader, FrameSummary), FrameError> {
        let vessel = self.vessel_pose(h);
        let frame = Frame {
            header: h,
            disparity,
            vessel,
        };
        let summary = self.mapper.process(&frame, out)?;
        Ok((
            LocalMapHeader {
                hdr: header,
                frame_seq: h.frame_seq,
                grid: summary.grid,
                vessel,
            },
            summary,
        ))
    }
}

/// One local map per camera frame: the maps of every configured head with the same stamp merged
/// into one, so the mapper fuses (and the sequencer decides on) each frame once, and a lock-step
/// source sees the frame done only when all its heads are in the map.
pub struct FrameMerge {
    heads: Vec<String>,
    seen: Vec<bool>,
    /// The frame `seen` refers to (a head can be accounted for before any map of the frame).
    seen_stamp: Option<u64>,
    header: Option<LocalMapHeader>,
    cells: Vec<MapCell>,
    /// Where the caller maps one head's frame before [`FrameMerge::add_scratch`].
    pub scratch: Vec<MapCell>,
}

impl FrameMerge {
    /// `heads`: the heads a frame is complete with (empty: every map is a frame on its own).
    pub fn new(heads: &[String], cells: usize) -> Self {
        Self {
            heads: heads.to_vec(),
            seen: vec![false; heads.len()],
            seen_stamp: None,
            header: None,
            cells: vec![MapCell::default(); cells],
            scratch: vec![MapCell::default(); cells],
        }
    }

    /// Stamp of the frame being collected.
    pub fn pending_stamp(&self) -> Option<u64> {
        self.header.map(|h| h.hdr.stamp_ns)
    }

    /// Merges the scratch map of `head` into the frame (which must have the same stamp and grid).
    pub fn add_scratch(&mut self, head: &str, header: LocalMapHeader) {
        self.mark_seen(head, header.hdr.stamp_ns);
        match &self.header {
            Some(h) if h.grid == header.grid => {
                for (acc, new) in self.cells.iter_mut().zip(&self.scratch) {
                    merge_cell(acc, new);
                }
            }
            // A different grid (the vessel crossed a cell between two INS samples) cannot be merged
            // cell by cell: the newest head's map stands for the frame.
            _ => {
                self.cells.copy_from_slice(&self.scratch);
                self.header = Some(header);
            }
        }
    }

    /// `head` delivered nothing usable for the frame at `stamp` (its input was rejected): the frame
    /// is complete without it rather than waiting out the head timeout.
    pub fn skip(&mut self, head: &str, stamp: u64) {
        self.mark_seen(head, stamp);
    }

    fn mark_seen(&mut self, head: &str, stamp: u64) {
        if self.seen_stamp != Some(stamp) {
            self.seen.fill(false);
            self.seen_stamp = Some(stamp);
        }
        if let Some(i) = self.heads.iter().position(|h| h == head) {
            self.seen[i] = true;
        }
    }

    /// Every configured head is in (always true without a head list).
    pub fn complete(&self) -> bool {
        self.header.is_some() && self.seen.iter().all(|&s| s)
    }

    /// The merged frame, and a fresh start for the next one.
    pub fn take(&mut self) -> Option<(LocalMapHeader, &[MapCell])> {
        let header = self.header.take()?;
        self.seen.fill(false);
        self.seen_stamp = None;
        Some((header, &self.cells))
    }
}

/// Two observations of one cell: the more hazardous wins, evidence adds up.
fn merge_cell(acc: &mut MapCell, new: &MapCell) {
    let unseen = |c: &MapCell| c.cost == MapCell::UNKNOWN_COST && c.observed == 0;
    if unseen(new) {
        return;
    }
    if unseen(acc) {
        *acc = *new;
        return;
    }
    // Water's elevation is the water surface's; otherwise the better-observed head's elevation, ties
    // broken by value so the merge does not depend on which head arrived first.
    let elevation = (new.water.min(1), new.observed, new.elevation_cm)
        .max((acc.water.min(1), acc.observed, acc.elevation_cm))
        .2;
    *acc = MapCell {
        hazard: acc.hazard.max(new.hazard),
        cost: acc.cost.max(new.cost),
        water: acc.water.max(new.water),
        observed: acc.observed.saturating_add(new.observed),
        max_height_cm: acc.max_height_cm.max(new.max_height_cm),
        elevation_cm: elevation,
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demo_config_loads_with_its_model() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../launch/sets/perception.toml");
        let config: ServiceConfig = runtime::config::load(&path).unwrap();
        let p = Perception::new(&config, &config.model_path(&path)).unwrap();
        assert_eq!(p.cell_count(), 400 * 400);
        assert!(p.accepts("hh_right") && !p.accepts("color"));
        let bad = runtime::config::parse::<ServiceConfig>("model = \"m.json\"\ngird = 3\n", "test");
        assert!(bad.is_err());
    }

    #[test]
    fn heads_of_one_frame_merge_into_one_map() {
        let heads = vec!["hh_left".to_string(), "hh_right".to_string()];
        let mut merge = FrameMerge::new(&heads, 3);
        let mut header = LocalMapHeader::default();
        header.hdr.stamp_ns = 7;
        let unknown = MapCell {
            cost: MapCell::UNKNOWN_COST,
            ..MapCell::default()
        };
        let cell = |hazard, observed| MapCell {
            hazard,
            cost: hazard / 2,
            observed,
            ..MapCell::default()
        };
        merge.scratch = vec![cell(200, 3), unknown, cell(10, 1)];
        merge.add_scratch("hh_left", header);
        assert!(!merge.complete());
        assert_eq!(merge.pending_stamp(), Some(7));
        merge.scratch = vec![cell(20, 2), cell(90, 4), unknown];
        merge.add_scratch("hh_right", header);
        assert!(merge.complete());
        let (h, cells) = merge.take().unwrap();
        assert_eq!(h.hdr.stamp_ns, 7);
        assert_eq!((cells[0].hazard, cells[0].observed), (200, 5));
        assert_eq!(cells[1], cell(90, 4));
        assert_eq!(cells[2], cell(10, 1));
        assert!(merge.take().is_none() && !merge.complete());
    }

    #[test]
    fn a_rejected_head_completes_its_frame_but_not_the_next() {
        let heads = vec!["hh_left".to_string(), "hh_right".to_string()];
        let mut merge = FrameMerge::new(&heads, 1);
        let mut header = LocalMapHeader::default();
        // The left head of frame 7 was rejected before the right one arrived.
        merge.skip("hh_left", 7);
        assert!(!merge.complete(), "no map of frame 7 yet");
        header.hdr.stamp_ns = 7;
        merge.add_scratch("hh_right", header);
        assert!(merge.complete());
        assert!(merge.take().is_some());
        // A skip of frame 8's left head says nothing about frame 9.
        merge.skip("hh_left", 8);
        header.hdr.stamp_ns = 9;
        merge.add_scratch("hh_right", header);
        assert!(!merge.complete());
    }

    #[test]
    fn nearest_ins_sample_within_the_gap() {
        let mut ins = InsHistory::default();
        for k in 0..10u64 {
            let mut s = InsState::default();
            s.hdr.stamp_ns = 1_000_000_000 + k * 10_000_000;
            s.pose.position = [k as f64, 0.0, 0.0];
            ins.push(s).unwrap();
        }
        let s = ins.nearest(1_000_000_000 + 31_000_000, 5_000_000).unwrap();
        assert_eq!(s.pose.position[0], 3.0);
        assert!(ins.nearest(2_000_000_000, 5_000_000).is_none());
        let mut nan = InsState::default();
        nan.pose.yaw = f64::NAN;
        assert!(ins.push(nan).is_err());
    }
}
