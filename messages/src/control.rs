use crate::{FixedStr, Header};
use iceoryx2::prelude::ZeroCopySend;

/// Why the sequencer commands what it commands.
pub mod command_mode {
    pub const IDLE: u8 = 0;
    pub const NAVIGATING: u8 = 1;
    /// The watchdog found map, contacts or INS stale: throttle is 0.
    pub const SAFE_STOP: u8 = 2;
    /// No arc free along its whole length: slowing along the arc free close in (`chosen_arc` set),
    /// or, with none, braking and turning away, then, stopped, backing off astern while the water
    /// astern is clear (`chosen_arc` -1).
    pub const BLOCKED: u8 = 3;
}

/// Rudder and throttle for the vessel, clamped and rate-limited by the sequencer.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("usv.ActuatorCommand.v1")]
pub struct ActuatorCommand {
    /// `stamp_ns` is the stamp of the newest input (map or INS) the command was computed from.
    pub hdr: Header,
    /// Rudder angle (rad), positive turns the bow to port (left, counter-clockwise seen from above).
    pub rudder_rad: f32,
    /// Throttle (percent, 0..=100; negative is astern).
    pub throttle_pct: f32,
    /// See [`command_mode`].
    pub mode: u8,
    pub _pad: [u8; 7],
}

/// Largest number of arcs the sequencer can report in [`SequencerStatus::blocked_arcs`].
pub const MAX_ARCS: usize = 128;

/// What the sequencer is doing, once per cycle.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.SequencerStatus.v1")]
pub struct SequencerStatus {
    pub hdr: Header,
    /// See [`command_mode`].
    pub mode: u8,
    /// 1 while a mission is paused.
    pub paused: u8,
    pub _pad: [u8; 2],
    /// Index of the mission step being executed; -1 without a mission.
    pub step: i32,
    /// Index of the chosen arc; -1 when none was chosen.
    pub chosen_arc: i32,
    pub arc_count: u32,
    /// Bit i set: arc i is blocked.
    pub blocked_arcs: [u64; MAX_ARCS / 64],
    /// Current goal (ENU) and the distance to it (m).
    pub goal: [f64; 2],
    pub goal_distance_m: f64,
    /// Bits of stale inputs: 1 map, 2 contacts, 4 INS.
    pub stale_inputs: u32,
    pub mission_name: FixedStr<48>,
    pub step_name: FixedStr<48>,
}

impl SequencerStatus {
    pub fn arc_blocked(&self, arc: usize) -> bool {
        arc < MAX_ARCS && self.blocked_arcs[arc / 64] & (1 << (arc % 64)) != 0
    }
}

/// What a [`MissionCommand`] asks the sequencer to do.
pub mod mission_action {
    pub const LOAD: u32 = 1;
    pub const PAUSE: u32 = 2;
    pub const RESUME: u32 = 3;
    pub const ABORT: u32 = 4;
    pub const STATUS: u32 = 5;
}

/// Largest mission file that can be sent in one [`MissionCommand`].
pub const MAX_MISSION_TEXT: usize = 16 * 1024;

/// Request to the sequencer's mission service (request-response).
#[repr(C)]
#[derive(Clone, Copy, ZeroCopySend)]
#[type_name("usv.MissionCommand.v1")]
pub struct MissionCommand {
    /// See [`mission_action`].
    pub action: u32,
    /// Length of the mission TOML in `text` (for LOAD).
    pub text_len: u32,
    pub text: [u8; MAX_MISSION_TEXT],
}

// By hand: iceoryx2 request-response needs `Debug`, and printing 16 KiB of text bytes helps nobody.
impl std::fmt::Debug for MissionCommand {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MissionCommand")
            .field("action", &self.action)
            .field("text_len", &self.text_len)
            .finish_non_exhaustive()
    }
}

/// The sequencer's answer to a [`MissionCommand`].
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.MissionReply.v1")]
pub struct MissionReply {
    /// 1 if the request was carried out.
    pub accepted: u32,
    pub step: i32,
    /// Error or state text for the operator.
    pub message: FixedStr<240>,
}
