//! The bridge's library: everything that needs no IPC and no sockets.
//!
//! - [`config`]: `bridge run --config FILE` (TOML, unknown fields rejected).
//! - [`protocol`]: the Foxglove WebSocket protocol (`foxglove.websocket.v1`) messages.
//! - [`hub`]: channels, clients and their subscriptions; the bounded per-client queues (oldest
//!   dropped, drops counted) through which the IPC thread hands encoded messages to the server.
//! - [`image`]: image rate limiting and downscaling, so a slow link does not cost the boat.
//! - [`link`]: framing of raw topic bytes for the cross-host link.

pub mod config;
pub mod hub;
pub mod image;
pub mod link;
pub mod protocol;

pub use config::Config;
pub use hub::Hub;
