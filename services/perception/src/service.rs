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
    ProjectionConfig, SpatialConfig, TemporalConfig,
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
    #[serde(default)]
    pub grid: GridConfig,
    #[serde(default)]
    pub projection: ProjectionConfig,
    #[serde(default)]
    pub spatial: SpatialConfig,
    #[serde(default)]
    pub temporal: TemporalConfig,
    #[serde(default)]
    pub cost: CostConfig,
}

fn default_deadline() -> u64 {
    1000
}

fn default_ins_gap() -> u64 {
    200
}

impl ServiceConfig {
    pub fn hazard(&self) -> HazardConfig {
        HazardConfig {
            grid: self.grid.clone(),
            projection: self.projection.clone(),
            spatial: self.spatial.clone(),
            temporal: self.temporal.clone(),
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

    /// Checks a frame before an output sample is loaned for it.
    pub fn check(&self, h: &DisparityHeader, disparity: &[f32]) -> Result<(), FrameError> {
        let frame = Frame {
            header: h,
            disparity,
            vessel: self.vessel_pose(h),
        };
        self.mapper.check(&frame).map(|_| ())
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
