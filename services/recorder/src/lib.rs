//! The recorder's library: MCAP writing (no IPC). The binary subscribes to topics and feeds
//! [`recording::Recording`].
//!
//! A recording holds, for every topic, a replay channel with the exact bytes of each message (schema
//! named after the versioned type name, encoding `usv-raw`, framing in `messages::recording`) and,
//! where one fits, Foxglove channels (`<topic>/image`, `/grid`, `/scene`, `/fix`, `/tf`, `/log`)
//! with JSON-encoded well-known schemas for viewing. Images and grids go to "bulk" chunks
//! (uncompressed or lz4), small messages to their own chunks (zstd by default).

pub mod bench;
/// The Foxglove views live in the shared `views` crate (the live bridge encodes the same way).
pub use views as foxglove;
pub mod mcap;
pub mod output;
pub mod recording;

pub use mcap::{Compression, WriteError, WriterOptions};
pub use recording::{Recording, RecordingOptions, TopicStats};
