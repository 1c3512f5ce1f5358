//! The tracker: discrete contacts from the world map (Hammerhead pipeline stage 3, Huntsberger et
//! al. sections 4-5). Each world map goes through
//! 1. [`detect`]: 8-connected components of hazard cells with extent, area, height, elongation
//!    and spread along and across the line of sight;
//! 2. [`classify`]: one Gaussian per class with full covariance (boat, channel marker,
//!    extended/shore, false alarm) trained offline by `--example train` on recorded perception
//!    world maps labelled by the simulator truth, and loaded at start;
//! 3. [`track`]: constant-velocity Kalman filters in ENU, gated optimal assignment (Kuhn-Munkres),
//!    M-of-N confirmation, no births on a confirmed track's hull, merging of duplicates, coasting
//!    and deletion, into a fixed-size `ContactList`.
//!
//! Pure and deterministic: no IPC, no clock. [`eval`] scores contact lists against ground truth.

pub mod bench;
pub mod classify;
pub mod clutter;
pub mod config;
pub mod detect;
pub mod eval;
pub mod line_of_sight;
pub mod track;
pub mod train;

pub use classify::{Model, ModelError, FEATURES};
pub use detect::{Detection, Detector};
pub use track::{TrackError, Tracker, TrackerConfig};
