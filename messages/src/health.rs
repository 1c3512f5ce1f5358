use crate::{FixedStr, Header};
use iceoryx2::prelude::ZeroCopySend;

/// Life-cycle state of a service process.
pub mod service_state {
    pub const STARTING: u8 = 0;
    pub const RUNNING: u8 = 1;
    /// Running, but the last input was bad or a deadline was missed: see `last_error`.
    pub const DEGRADED: u8 = 2;
    pub const STOPPING: u8 = 3;

    pub fn name(state: u8) -> &'static str {
        match state {
            STARTING => "starting",
            RUNNING => "running",
            DEGRADED => "degraded",
            STOPPING => "stopping",
            _ => "?",
        }
    }
}

/// Published by every service periodically and after every processed input. The supervisor restarts a
/// service whose heartbeats stop; lock-step sources wait until every pipeline service reports the
/// frame they sent as processed (`last_input_stamp_ns`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.Heartbeat.v1")]
pub struct Heartbeat {
    /// `source` is the service name; `stamp_ns` is the monotonic clock at publication.
    pub hdr: Header,
    pub pid: u32,
    /// See [`service_state`].
    pub state: u8,
    pub _pad: [u8; 3],
    /// Stamp of the newest input whose processing has finished (0 before the first).
    pub last_input_stamp_ns: u64,
    /// Inputs processed since start.
    pub processed: u64,
    /// Inputs rejected as bad (wrong size, NaN, mismatched frame ...) since start.
    pub rejected: u64,
    /// Handler errors since start.
    pub errors: u64,
    /// Input deadlines missed since start.
    pub missed_deadlines: u64,
    /// Processing time of the last input and the worst so far (us).
    pub last_processing_us: u32,
    pub max_processing_us: u32,
    pub last_error: FixedStr<120>,
}
