//! The mapper: a vessel-centred world map that scrolls with the vessel (whole cells, in place; what
//! leaves the square falls off), fuses every local map through its ENU geometry (re-registered with
//! the INS when a sample brackets the frame stamp), averages the last N costs per cell, reports water
//! only once it was seen at least twice, re-localizes water every cycle as its elevation estimate
//! improves (Rankin & Matthies, sections 3-4), and lets hazard evidence decay with a half-life in
//! stream time so moving boats leave no trails.
//!
//! Pure and deterministic: no IPC, no clock, no allocation per update after construction.
//! `main.rs` is the thin service around [`WorldMapper`].

pub mod bench;
pub mod eval;
mod map;

pub use map::{Config, MapError, WorldMapper, MAX_COST_HISTORY};
