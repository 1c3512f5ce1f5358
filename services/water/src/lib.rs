//! Daytime water detection and localization for a ground vehicle's colour stereo head, after Rankin &
//! Matthies, "Daytime water detection and localization for unmanned ground vehicle autonomous
//! navigation" (sections 2 and 3).
//!
//! Per frame, [`WaterDetector::process`] takes the left image (Rgb8, or Mono8 with the colour cue
//! off), its disparity, the camera model and the vehicle pose, and produces:
//! - a per-pixel cue mask with [`messages::water_cue`] bits: the raw colour, texture, stereo
//!   reflection and zero-disparity cues, and `WATER` on regions the rule base accepted;
//! - the accepted regions ([`WaterRegion`]): size, bounding box, cue counts, water elevation from the
//!   ground around the region's perimeter, and where the region lies in the world;
//! - an instantaneous terrain map ([`messages::MapCell`] on a vehicle-centred, ENU-aligned
//!   [`messages::GridGeometry`]): ground elevation, traversability cost from slope and step height,
//!   and water.
//!
//! Pure and deterministic (no I/O, no clock); buffers live in the detector, so frames of a fixed size
//! allocate nothing after the first. [`eval`] scores detections against simulator ground truth.

pub mod config;
pub mod cues;
pub mod detector;
pub mod eval;
pub mod geometry;
pub mod ground;
pub mod map;
pub mod morph;
pub mod regions;
pub mod render;

pub use config::WaterConfig;
pub use cues::SkyReference;
pub use detector::{Detection, Frame, Image, WaterDetector, WaterError, WaterRegion};
