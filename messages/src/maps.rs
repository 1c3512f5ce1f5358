use crate::{Header, Pose};
use iceoryx2::prelude::ZeroCopySend;

/// Geometry of a vessel-centred grid. Axes are aligned with world east (columns, +x) and north
/// (rows, +y); cell `(0, 0)` is the south-west corner. The vessel is at `center` (ENU) at the stamp.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
pub struct GridGeometry {
    pub width: u32,
    pub height: u32,
    /// Cell edge length (m).
    pub resolution_m: f64,
    /// ENU position of the grid centre (m).
    pub center: [f64; 2],
}

impl GridGeometry {
    pub fn cell_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// ENU position of the centre of cell (col, row).
    pub fn cell_center(&self, col: u32, row: u32) -> [f64; 2] {
        let r = self.resolution_m;
        [
            self.center[0] + (col as f64 + 0.5 - self.width as f64 / 2.0) * r,
            self.center[1] + (row as f64 + 0.5 - self.height as f64 / 2.0) * r,
        ]
    }

    /// Cell (col, row) containing an ENU position, if inside the grid.
    pub fn cell_of(&self, east: f64, north: f64) -> Option<(u32, u32)> {
        let r = self.resolution_m;
        let c = ((east - self.center[0]) / r + self.width as f64 / 2.0).floor();
        let w = ((north - self.center[1]) / r + self.height as f64 / 2.0).floor();
        (c >= 0.0 && w >= 0.0 && c < self.width as f64 && w < self.height as f64)
            .then_some((c as u32, w as u32))
    }
}

/// One cell of a local or world map.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("usv.MapCell.v1")]
pub struct MapCell {
    /// Hazard probability, 0..=255 for 0..=1. 0 also means "no evidence": see `observed`.
    pub hazard: u8,
    /// Traversal cost, 0 free ..= 254 lethal; 255 unknown.
    pub cost: u8,
    /// Water state: 0 none, 1 candidate (seen once), 2 confirmed.
    pub water: u8,
    /// Number of range points or observations that fell in the cell this cycle (saturating).
    pub observed: u8,
    /// Highest point in the cell above the water plane / ground (cm).
    pub max_height_cm: i16,
    /// Mean elevation of the cell (cm); water elevation for water cells.
    pub elevation_cm: i16,
}

impl MapCell {
    pub const UNKNOWN_COST: u8 = 255;
    pub const LETHAL_COST: u8 = 254;
}

/// User header of a local map (one stereo frame's instantaneous map). Payload: `[MapCell]`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.LocalMap.v1")]
pub struct LocalMapHeader {
    pub hdr: Header,
    pub frame_seq: u64,
    pub grid: GridGeometry,
    /// Vessel pose at the frame stamp (ENU).
    pub vessel: Pose,
}

/// User header of the fused world map. Payload: `[MapCell]`, whose `observed` counts the latest
/// fused local map's observations (the sensors' coverage now; v1 counted every local map that had
/// ever observed the cell). A cell observed before has a known cost.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.WorldMap.v2")]
pub struct WorldMapHeader {
    pub hdr: Header,
    pub grid: GridGeometry,
    pub vessel: Pose,
    /// Local maps fused so far.
    pub fused: u64,
}
