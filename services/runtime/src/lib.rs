//! Process glue shared by every service, so that a service's `main.rs` is only "subscribe, call the
//! algorithm, publish".
//!
//! - [`Service`]: the one iceoryx2 node of the process, named after the service; typed publishers and
//!   subscribers made from the `messages::topics` descriptors; the single blocking wait loop
//!   ([`Service::run`]) with a deadline per input; heartbeats; cooperative shutdown.
//! - [`config`]: TOML configuration with unknown fields rejected and errors that name the file.
//! - [`cleanup`]: removal of resources that dead processes left in shared memory.

pub mod cleanup;
pub mod clock;
pub mod config;
pub mod domain;
mod health;
pub mod lockstep;
pub mod logging;
mod pubsub;
mod service;
mod shutdown;
pub mod testing;

pub use health::Health;
pub use pubsub::{Pod, PublishRaw, Publisher, Receive, Subscriber};
pub use service::{tool_node, Input, Ports, Service, Wake};
pub use shutdown::Shutdown;

/// Environment variable through which the supervisor tells a process which service name it runs as
/// (node name and heartbeat source). It wins over the name compiled into the binary, so one program
/// can run as several services ("stereo_port", "stereo_starboard").
pub const SERVICE_NAME_ENV: &str = "USV_SERVICE_NAME";
