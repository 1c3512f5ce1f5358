use crate::{Header, Name, Pose};
use iceoryx2::prelude::ZeroCopySend;

/// Rectified pinhole model of a stereo head (left camera), in pixels of the disparity image.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
pub struct CameraModel {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// Distance between the two optical centres (m).
    pub baseline_m: f64,
    /// Left camera pose in the body frame (x forward, y left, z up).
    pub mount: Pose,
}

impl CameraModel {
    /// Range along the optical axis (m) for a disparity (px); `None` for invalid or non-positive.
    pub fn depth(&self, disparity: f32) -> Option<f64> {
        (disparity.is_finite() && disparity > 0.0)
            .then(|| self.fx * self.baseline_m / disparity as f64)
    }

    /// 3D point in the optical camera frame (x right, y down, z forward) of pixel (u, v).
    pub fn point(&self, u: f64, v: f64, disparity: f32) -> Option<[f64; 3]> {
        let z = self.depth(disparity)?;
        Some([(u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z])
    }
}

/// The water plane seen by a head, fitted from its disparity: the camera's height above the plane and
/// its attitude relative to it. The stabilized pose is the camera pose with roll and pitch taken from
/// the plane rather than from the INS, which is what Hammerhead projects range with.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
pub struct WaterPlane {
    /// 1 if the fit succeeded for this frame, 0 otherwise (then the other fields are stale or zero).
    pub valid: u32,
    pub inliers: u32,
    /// Plane in the optical frame: `normal . p + offset = 0`, unit normal pointing up (towards the sky).
    pub normal: [f64; 3],
    pub offset: f64,
    pub camera_height_m: f64,
    pub roll: f64,
    pub pitch: f64,
}

/// User header of a disparity image. The payload is `[f32]`, `width * height` values in pixels,
/// row-major, NaN where no disparity was produced. `L(u, v)` matches `R(u - d, v)`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.Disparity.v1")]
pub struct DisparityHeader {
    /// `stamp_ns` is the stereo frame's stamp; `seq` is the disparity publisher's own counter.
    pub hdr: Header,
    /// Sequence number of the stereo frame it was computed from.
    pub frame_seq: u64,
    pub head: Name,
    pub width: u32,
    pub height: u32,
    /// Disparity search range used (px).
    pub num_disparities: u32,
    pub camera: CameraModel,
    pub plane: WaterPlane,
    /// Stabilized left-camera pose in the ENU world frame at the frame stamp.
    pub stabilized_pose: Pose,
}

impl DisparityHeader {
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// Per-pixel cue bits of a [`WaterMaskHeader`] payload.
pub mod water_cue {
    pub const COLOR: u8 = 1 << 0;
    pub const TEXTURE: u8 = 1 << 1;
    pub const REFLECTION: u8 = 1 << 2;
    pub const ZERO_DISPARITY: u8 = 1 << 3;
    /// The pixel belongs to a region the rule base accepted as water.
    pub const WATER: u8 = 1 << 7;
}

/// User header of a water mask. The payload is `[u8]`, `width * height`, one bit per cue per pixel
/// (see [`water_cue`]).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.WaterMask.v1")]
pub struct WaterMaskHeader {
    pub hdr: Header,
    pub frame_seq: u64,
    pub head: Name,
    pub width: u32,
    pub height: u32,
    /// Number of accepted water regions in the mask.
    pub regions: u32,
}
