use crate::FixedStr;
use iceoryx2::prelude::ZeroCopySend;

/// Name of a service, head or sensor; short on purpose so headers stay small.
pub type Name = FixedStr<32>;

/// Common header of every message.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ZeroCopySend)]
pub struct Header {
    /// Per-publisher sequence number, starting at 0 when the publisher (re)starts.
    pub seq: u64,
    /// Sensor time (ns) of the camera frame or INS sample this message derives from. Propagated
    /// unchanged down the pipeline, so any output can be traced back to the frame it came from.
    pub stamp_ns: u64,
    /// Who published it: the service name, or the stereo head for camera-derived data.
    pub source: Name,
}

impl Header {
    pub fn new(seq: u64, stamp_ns: u64, source: &str) -> Self {
        Self {
            seq,
            stamp_ns,
            source: Name::new(source),
        }
    }
}

/// A pose in the local ENU world frame: position (m) and roll/pitch/yaw (rad, ZYX order).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
pub struct Pose {
    pub position: [f64; 3],
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
}
