//! Perception: the Hammerhead hazard map. Each disparity image (any head) becomes one local map:
//! range points projected into a vessel-centred ENU grid, spatially and temporally filtered, and a
//! per-cell hazard probability from a classifier trained offline against simulator ground truth.
//! Pure and deterministic: no IPC, no clock; the `perception` binary is the thin process around
//! [`hazard::HazardMapper`].
//!
//! - [`geometry`]: optical frame -> ENU over the water plane (stabilized pose).
//! - [`hazard`]: projection, cell statistics, filters, classifier, cost.
//! - [`model`]: the logistic-regression cell classifier and its JSON file.
//! - [`eval`]: scoring a hazard map against ground truth.
//! - [`service`]: the service's configuration and per-frame glue (INS matching, checks).
//! - [`train`]: offline training from rendered scenarios (sim + stereo libraries).
//! - [`bench`]: the `perception bench hazard` figures; [`water_bench`]: `perception bench water`.
//! - [`synthetic`]: ray-cast disparity of buoys on a flat sea, for tests and the benchmark.
//!
//! - [`water_stage`]: water detection (the `water` library) on the configured colour heads: the
//!   frame's left image kept until its disparity arrives, the cue mask, water cells for the local map.

pub mod bench;
pub mod eval;
pub mod geometry;
pub mod hazard;
pub mod model;
pub mod service;
pub mod synthetic;
pub mod train;
pub mod water_bench;
pub mod water_stage;

pub use hazard::{HazardConfig, HazardMapper};
pub use model::HazardModel;
