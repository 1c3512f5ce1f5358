//! Water detection inside the perception service: the colour frames of the configured heads are kept
//! until their disparity arrives, then the `water` library (Rankin & Matthies) runs on the left
//! image and its disparity. The result is the frame's cue mask (published as `WaterMask`) and water
//! cells with the water elevation written into the frame's local map.
//!
//! A disparity is fused only with the colour frame it was computed from (same head, frame sequence
//! number and stamp) and of the same size; anything else is an error the service counts as rejected
//! input. Frames are copied into buffers kept per head, so a steady stream allocates nothing.

use messages::{
    water_cue, DisparityHeader, GridGeometry, MapCell, PixelEncoding, Pose, StereoFrameHeader,
};
use serde::Deserialize;
use water::{Detection, Frame, Image, WaterConfig, WaterDetector, WaterError};

/// `[water]` of the service configuration. Off (no heads) unless configured.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaterSettings {
    /// Heads whose frames go through water detection (colour heads; Mono8 runs without the colour
    /// cue). Empty: water detection is off.
    #[serde(default)]
    pub heads: Vec<String>,
    /// Colour frames kept per head while their disparity is computed.
    #[serde(default = "default_kept")]
    pub frames_kept: usize,
    /// Detector parameters (`[water.detector]`, the `water` crate's `WaterConfig`).
    #[serde(default)]
    pub detector: WaterConfig,
}

fn default_kept() -> usize {
    3
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WaterInputError {
    #[error("frame {seq} of head '{head}': payload or encoding does not match its header")]
    BadFrame { head: String, seq: u64 },
    #[error(
        "no colour frame {seq} (stamp {stamp_ns}) of head '{head}' for its disparity (not received or already replaced)"
    )]
    NoFrame {
        head: String,
        seq: u64,
        stamp_ns: u64,
    },
    #[error("disparity of frame {seq} is {dw}x{dh}, its colour frame {iw}x{ih}: not fused")]
    SizeMismatch {
        seq: u64,
        dw: u32,
        dh: u32,
        iw: u32,
        ih: u32,
    },
    #[error("water detection: {0}")]
    Detector(#[from] WaterError),
}

/// One kept left image, packed (no row padding).
#[derive(Default)]
struct Kept {
    valid: bool,
    seq: u64,
    stamp_ns: u64,
    width: u32,
    height: u32,
    rgb: bool,
    pixels: Vec<u8>,
}

/// Per-frame water detection of the service.
pub struct WaterStage {
    heads: Vec<String>,
    /// `frames_kept` slots per head, in head order; the oldest is replaced.
    kept: Vec<Kept>,
    per_head: usize,
    next: Vec<usize>,
    detector: WaterDetector,
}

/// What one frame's detection produced, for publishing.
pub struct WaterOutput<'a> {
    pub detection: Detection<'a>,
    pub width: u32,
    pub height: u32,
}

impl WaterStage {
    /// `None` when no head is configured.
    pub fn new(settings: &WaterSettings) -> Option<Self> {
        if settings.heads.is_empty() {
            return None;
        }
        let per_head = settings.frames_kept.max(1);
        Some(Self {
            heads: settings.heads.clone(),
            kept: (0..per_head * settings.heads.len())
                .map(|_| Kept::default())
                .collect(),
            per_head,
            next: vec![0; settings.heads.len()],
            detector: WaterDetector::new(settings.detector.clone()),
        })
    }

    fn head_index(&self, head: &str) -> Option<usize> {
        self.heads.iter().position(|h| h == head)
    }

    /// Is water detection run on this head's frames?
    pub fn wants(&self, head: &str) -> bool {
        self.head_index(head).is_some()
    }

    /// Keeps the left image of a frame of a configured head (other heads are ignored: `Ok(false)`).
    pub fn add_frame(
        &mut self,
        h: &StereoFrameHeader,
        payload: &[u8],
    ) -> Result<bool, WaterInputError> {
        let Some(k) = self.head_index(h.head.as_str()) else {
            return Ok(false);
        };
        let bad = || WaterInputError::BadFrame {
            head: h.head.as_str().to_string(),
            seq: h.hdr.seq,
        };
        let encoding = h.encoding().ok_or_else(bad)?;
        let bpp = encoding.bytes_per_pixel();
        let row = h.width as usize * bpp;
        if h.width == 0 || h.height == 0 || (h.stride as usize) < row {
            return Err(bad());
        }
        let (left, _) = h.planes(payload).ok_or_else(bad)?;
        let slot = k * self.per_head + self.next[k];
        self.next[k] = (self.next[k] + 1) % self.per_head;
        let kept = &mut self.kept[slot];
        kept.pixels.clear();
        for r in left.chunks_exact(h.stride as usize) {
            kept.pixels.extend_from_slice(&r[..row]);
        }
        kept.valid = true;
        kept.seq = h.hdr.seq;
        kept.stamp_ns = h.hdr.stamp_ns;
        kept.width = h.width;
        kept.height = h.height;
        kept.rgb = encoding == PixelEncoding::Rgb8;
        Ok(true)
    }

    /// Runs water detection on the colour frame this disparity was computed from. `vehicle` is the
    /// body pose at the frame stamp (the camera mount is in the disparity's camera model).
    pub fn process(
        &mut self,
        h: &DisparityHeader,
        disparity: &[f32],
        vehicle: &Pose,
    ) -> Result<WaterOutput<'_>, WaterInputError> {
        let head = h.head.as_str();
        let no_frame = || WaterInputError::NoFrame {
            head: head.to_string(),
            seq: h.frame_seq,
            stamp_ns: h.hdr.stamp_ns,
        };
        let k = self.head_index(head).ok_or_else(no_frame)?;
        let slots = k * self.per_head..(k + 1) * self.per_head;
        let slot = self.kept[slots.clone()]
            .iter()
            .position(|f| f.valid && f.seq == h.frame_seq && f.stamp_ns == h.hdr.stamp_ns)
            .map(|i| slots.start + i)
            .ok_or_else(no_frame)?;
        let kept = &mut self.kept[slot];
        // A frame is fused once; a second disparity of it would be another frame's.
        kept.valid = false;
        if (kept.width, kept.height) != (h.width, h.height) {
            return Err(WaterInputError::SizeMismatch {
                seq: h.frame_seq,
                dw: h.width,
                dh: h.height,
                iw: kept.width,
                ih: kept.height,
            });
        }
        let image = if kept.rgb {
            Image::Rgb8(&kept.pixels)
        } else {
            Image::Mono8(&kept.pixels)
        };
        let (width, height) = (kept.width, kept.height);
        let detection = self.detector.process(&Frame {
            width: width as usize,
            height: height as usize,
            image,
            disparity,
            camera: &h.camera,
            vehicle,
        })?;
        Ok(WaterOutput {
            detection,
            width,
            height,
        })
    }
}

/// Writes the detection's water cells into a local map on `grid` (nearest cell by centre, so any
/// two resolutions work; with equal resolutions the snapped grids line up cell for cell). A water
/// cell keeps its hazard, takes the water elevation and at least the detector's water cost.
/// Returns the number of local-map cells marked.
pub fn mark_water(detection: &Detection<'_>, grid: &GridGeometry, cells: &mut [MapCell]) -> usize {
    let wg = &detection.grid;
    if cells.len() != grid.cell_count() {
        return 0;
    }
    let mut marked = 0;
    for (i, w) in detection.map.iter().enumerate() {
        if w.water == 0 {
            continue;
        }
        let (col, row) = (i as u32 % wg.width, i as u32 / wg.width);
        let [e, n] = wg.cell_center(col, row);
        let Some((c, r)) = grid.cell_of(e, n) else {
            continue;
        };
        let cell = &mut cells[(r * grid.width + c) as usize];
        if cell.water == 0 {
            marked += 1;
        }
        let cost = if cell.cost == MapCell::UNKNOWN_COST {
            w.cost
        } else {
            cell.cost.max(w.cost)
        };
        *cell = MapCell {
            water: w.water.max(cell.water),
            cost,
            observed: cell.observed.saturating_add(w.observed).max(1),
            elevation_cm: w.elevation_cm,
            ..*cell
        };
    }
    marked
}

/// Number of pixels with the fused water bit.
pub fn water_pixels(mask: &[u8]) -> usize {
    mask.iter().filter(|&&m| m & water_cue::WATER != 0).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::{Header, Name};

    fn frame_header(head: &str, seq: u64, w: u32, h: u32, stride: u32) -> StereoFrameHeader {
        StereoFrameHeader {
            hdr: Header::new(seq, 1_000 + seq, "sim"),
            head: Name::new(head),
            width: w,
            height: h,
            stride,
            encoding: PixelEncoding::Rgb8 as u32,
        }
    }

    fn stage() -> WaterStage {
        WaterStage::new(&WaterSettings {
            heads: vec!["color".into()],
            frames_kept: 2,
            detector: WaterConfig::default(),
        })
        .unwrap()
    }

    #[test]
    fn off_without_heads_and_frames_are_kept_packed() {
        assert!(WaterStage::new(&WaterSettings::default()).is_none());
        let mut s = stage();
        // 2x2 Rgb8 with 2 bytes of row padding.
        let h = frame_header("color", 4, 2, 2, 8);
        let plane: Vec<u8> = (0..16).collect();
        let payload = [plane.clone(), plane].concat();
        assert!(s.add_frame(&h, &payload).unwrap());
        assert_eq!(
            s.kept[0].pixels,
            vec![0, 1, 2, 3, 4, 5, 8, 9, 10, 11, 12, 13]
        );
        assert!(!s
            .add_frame(&frame_header("hh_left", 5, 2, 2, 8), &payload)
            .unwrap());
        assert!(matches!(
            s.add_frame(&h, &payload[..20]),
            Err(WaterInputError::BadFrame { .. })
        ));
    }

    #[test]
    fn disparity_of_another_frame_or_size_is_not_fused() {
        let mut s = stage();
        let (w, h) = (32u32, 24u32);
        let plane = vec![100u8; (3 * w * h) as usize];
        let payload = [plane.clone(), plane].concat();
        for seq in [1, 2, 3] {
            s.add_frame(&frame_header("color", seq, w, h, 3 * w), &payload)
                .unwrap();
        }
        let mut d = DisparityHeader {
            head: Name::new("color"),
            width: w,
            height: h,
            frame_seq: 1,
            ..Default::default()
        };
        d.hdr.stamp_ns = 1_001;
        let disparity = vec![f32::NAN; (w * h) as usize];
        let pose = Pose::default();
        // Frame 1 was replaced by frame 3 (two kept per head).
        assert!(matches!(
            s.process(&d, &disparity, &pose),
            Err(WaterInputError::NoFrame { seq: 1, .. })
        ));
        // Right seq, wrong stamp.
        d.frame_seq = 2;
        assert!(matches!(
            s.process(&d, &disparity, &pose),
            Err(WaterInputError::NoFrame { seq: 2, .. })
        ));
        d.hdr.stamp_ns = 1_002;
        d.width = 16;
        assert!(matches!(
            s.process(&d, &disparity, &pose),
            Err(WaterInputError::SizeMismatch { dw: 16, iw: 32, .. })
        ));
        // The frame was used up by the mismatched disparity.
        d.width = w;
        assert!(matches!(
            s.process(&d, &disparity, &pose),
            Err(WaterInputError::NoFrame { .. })
        ));
        // Frame 3 with an invalid camera model reaches the detector, which refuses it.
        d.frame_seq = 3;
        d.hdr.stamp_ns = 1_003;
        assert!(matches!(
            s.process(&d, &disparity, &pose),
            Err(WaterInputError::Detector(WaterError::Camera(_)))
        ));
    }

    #[test]
    fn water_cells_land_in_the_local_grid_at_their_position() {
        let wgrid = GridGeometry {
            width: 4,
            height: 4,
            resolution_m: 0.5,
            center: [10.0, 20.0],
        };
        let mut wmap = vec![MapCell::default(); 16];
        // Water cell (2, 3): centre (10.25, 20.75), elevation 1.23 m.
        wmap[3 * 4 + 2] = MapCell {
            water: 1,
            cost: 200,
            observed: 5,
            elevation_cm: 123,
            ..MapCell::default()
        };
        let detection = Detection {
            mask: &[],
            regions: &[],
            candidates: 0,
            rejected: [0; 4],
            map: &wmap,
            grid: wgrid,
            sky: water::SkyReference::from_rgb([0.0; 3], 0),
            horizon_row: 0.0,
        };
        let grid = GridGeometry {
            width: 10,
            height: 10,
            resolution_m: 0.5,
            center: [11.0, 19.0],
        };
        let mut cells = vec![
            MapCell {
                cost: MapCell::UNKNOWN_COST,
                ..MapCell::default()
            };
            100
        ];
        let (c, r) = grid.cell_of(10.25, 20.75).unwrap();
        cells[(r * 10 + c) as usize].hazard = 30;
        assert_eq!(mark_water(&detection, &grid, &mut cells), 1);
        let cell = cells[(r * 10 + c) as usize];
        assert_eq!(
            (
                cell.water,
                cell.cost,
                cell.elevation_cm,
                cell.hazard,
                cell.observed
            ),
            (1, 200, 123, 30, 5)
        );
        assert_eq!(cells.iter().filter(|c| c.water > 0).count(), 1);
        assert_eq!(mark_water(&detection, &grid, &mut cells[..5]), 0);
    }
}
