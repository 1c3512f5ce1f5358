use crate::Header;
use iceoryx2::prelude::ZeroCopySend;

/// Class of a tracked contact.
pub mod contact_class {
    pub const UNKNOWN: u8 = 0;
    pub const BOAT: u8 = 1;
    pub const CHANNEL_MARKER: u8 = 2;
    /// Shore, bridge, pylon or any extended obstacle.
    pub const EXTENDED: u8 = 3;
    pub const FALSE_ALARM: u8 = 4;

    pub fn name(class: u8) -> &'static str {
        match class {
            BOAT => "boat",
            CHANNEL_MARKER => "marker",
            EXTENDED => "extended",
            FALSE_ALARM => "false-alarm",
            _ => "unknown",
        }
    }
}

/// One tracked contact in the ENU world frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
pub struct Contact {
    /// Track id, stable for the life of the track.
    pub id: u32,
    /// See [`contact_class`].
    pub class: u8,
    /// 1 once the track is confirmed, 0 while tentative.
    pub confirmed: u8,
    /// 1 while the track is coasting (no detection this cycle).
    pub coasting: u8,
    pub _pad: u8,
    pub class_confidence: f32,
    pub position: [f64; 2],
    pub velocity: [f64; 2],
    /// Covariance of (x, y, vx, vy), row-major.
    pub covariance: [f32; 16],
    /// Extent along east and north (m), and height above water (m).
    pub extent: [f32; 3],
    /// Seconds since the track was born.
    pub age_s: f32,
}

/// Maximum number of contacts in one [`ContactList`].
pub const MAX_CONTACTS: usize = 64;

/// Every track the tracker holds at the stamp of the map it last processed.
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("usv.ContactList.v1")]
pub struct ContactList {
    pub hdr: Header,
    pub count: u32,
    pub contacts: [Contact; MAX_CONTACTS],
}

impl Default for ContactList {
    fn default() -> Self {
        Self {
            hdr: Header::default(),
            count: 0,
            contacts: [Contact::default(); MAX_CONTACTS],
        }
    }
}

impl ContactList {
    pub fn as_slice(&self) -> &[Contact] {
        &self.contacts[..(self.count as usize).min(MAX_CONTACTS)]
    }
}
