use crate::{Header, Pose};
use iceoryx2::prelude::ZeroCopySend;

/// Class of a ground-truth object or pixel label.
pub mod truth_class {
    pub const NONE: u8 = 0;
    pub const SKY: u8 = 1;
    pub const WATER: u8 = 2;
    pub const TERRAIN: u8 = 3;
    pub const BUOY: u8 = 4;
    pub const MARKER: u8 = 5;
    pub const PYLON: u8 = 6;
    pub const BOAT: u8 = 7;
    pub const VEGETATION: u8 = 8;
    pub const TRAIL: u8 = 9;
    pub const PUDDLE: u8 = 10;
    pub const OWN_VESSEL: u8 = 11;

    pub fn name(class: u8) -> &'static str {
        [
            "none",
            "sky",
            "water",
            "terrain",
            "buoy",
            "marker",
            "pylon",
            "boat",
            "vegetation",
            "trail",
            "puddle",
            "own-vessel",
        ]
        .get(class as usize)
        .copied()
        .unwrap_or("?")
    }
}

/// One object of the simulated world.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
pub struct TruthObject {
    pub id: u32,
    /// See [`truth_class`].
    pub class: u8,
    pub _pad: [u8; 3],
    pub pose: Pose,
    pub velocity: [f64; 3],
    /// Length, width, height (m).
    pub extent: [f32; 3],
}

/// A body of water (puddle, pond) with its true surface elevation.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
pub struct TruthWater {
    pub id: u32,
    pub _pad: u32,
    pub center: [f64; 2],
    /// Semi-axes along east and north (m).
    pub radii: [f64; 2],
    pub elevation_m: f64,
}

pub const MAX_TRUTH_OBJECTS: usize = 128;
pub const MAX_TRUTH_WATER: usize = 16;

/// What the simulator knows at a frame stamp. Only tests and evaluation read it.
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("usv.GroundTruth.v1")]
pub struct GroundTruth {
    pub hdr: Header,
    pub own: TruthObject,
    pub object_count: u32,
    pub water_count: u32,
    pub objects: [TruthObject; MAX_TRUTH_OBJECTS],
    pub water: [TruthWater; MAX_TRUTH_WATER],
}

impl Default for GroundTruth {
    fn default() -> Self {
        Self {
            hdr: Header::default(),
            own: TruthObject::default(),
            object_count: 0,
            water_count: 0,
            objects: [TruthObject::default(); MAX_TRUTH_OBJECTS],
            water: [TruthWater::default(); MAX_TRUTH_WATER],
        }
    }
}

impl GroundTruth {
    pub fn objects(&self) -> &[TruthObject] {
        &self.objects[..(self.object_count as usize).min(MAX_TRUTH_OBJECTS)]
    }

    pub fn water(&self) -> &[TruthWater] {
        &self.water[..(self.water_count as usize).min(MAX_TRUTH_WATER)]
    }
}

/// User header of a per-pixel ground-truth image for one head's left camera. Payload: `[f32]` of
/// `2 * width * height`: first the disparity plane (px, NaN for sky), then the label plane holding each
/// pixel's [`truth_class`] as a float.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.TruthImage.v1")]
pub struct TruthImageHeader {
    pub hdr: Header,
    pub head: crate::Name,
    pub width: u32,
    pub height: u32,
}
