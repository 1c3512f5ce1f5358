//! R4SA-like behaviours for the boat: a mission sequencer (command dictionary executed as finite
//! state machines), arc-based avoidance on the world map, waypoint navigation, target following and
//! an input watchdog. Pure and deterministic: no IPC, no clock (the input stamps are the time); the
//! `sequencer` binary is the thin process around [`Sequencer`].
//!
//! - [`mission`]: mission files and their execution.
//! - [`arcs`]: the arc set, its lookup table and the per-cycle blocked set.
//! - [`wake`]: the followed target's recent path, whose map cells block no arc.
//! - [`control`]: guidance and the heading/speed PIDs with actuator limits.
//! - [`watchdog`]: stale-input detection in stream time.
//! - [`cycle`]: all of it as one object, one cycle per call.
//! - [`bench`]: the figures of `usv bench arcs`.

pub mod arcs;
pub mod bench;
pub mod control;
pub mod cycle;
pub mod mission;
pub mod wake;
pub mod watchdog;

pub use cycle::{Config, CycleOn, Sequencer};
