//! The contract between the services of the stack: every payload that crosses a process boundary,
//! every topic (name, payload type, QoS) and the frames of reference those payloads are expressed in.
//!
//! # Rules
//! - Every payload is `#[repr(C)]`, self-contained (no pointers, no heap) and carries a versioned type
//!   name (`usv.<Name>.v<N>`). iceoryx2 only checks name, size and alignment when a service is opened,
//!   so changing a field's meaning without bumping the version is a silent bug.
//! - Images and grids are slices (`[u8]`, `[f32]`, `[MapCell]`) behind a user header that gives their
//!   geometry, so their size comes from configuration, not from the code.
//! - Every header carries a [`Header`]: `seq`, `stamp_ns` (sensor time of the camera frame or INS sample
//!   the message derives from, copied unchanged down the pipeline) and the `source` that published it.
//!
//! # Frames of reference
//! - **World (ENU)**: local east-north-up frame, metres, anchored at the geodetic origin carried in
//!   [`InsState::origin`]. Water surface at rest is `z = 0` in maritime scenarios.
//! - **Body**: x forward, y left, z up, origin at the vessel's reference point on the waterline.
//!   Yaw is measured counter-clockwise from east (ENU convention), so yaw 0 = heading east.
//! - **Optical camera**: x right, y down, z forward, origin at the left camera's centre of projection.
//! - **Vessel-centred grid**: axes aligned with world east/north, centred on the vessel's position at
//!   the message stamp (so a map does not rotate as the vessel turns; see [`GridHeader`]).

mod contacts;
mod control;
mod fixed;
mod header;
mod health;
mod maps;
pub mod recording;
mod sensor;
mod stereo;
pub mod summary;
pub mod topics;
mod truth;

pub use contacts::*;
pub use control::*;
pub use fixed::FixedStr;
pub use header::*;
pub use health::*;
pub use maps::*;
pub use sensor::*;
pub use stereo::*;
pub use topics::{Qos, Topic, TopicInfo};
pub use truth::*;

/// Re-exported so that every crate uses exactly the iceoryx2 version the contract was built with.
pub use iceoryx2;
