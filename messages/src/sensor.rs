use crate::{Header, Name, Pose};
use iceoryx2::prelude::ZeroCopySend;

/// Pixel encoding of an image plane. Stored in headers as its `u32` value (see
/// [`StereoFrameHeader::encoding`]) so that a corrupted sample can never hold an invalid enum.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PixelEncoding {
    #[default]
    Mono8 = 1,
    Rgb8 = 3,
}

impl PixelEncoding {
    pub fn bytes_per_pixel(self) -> usize {
        self as usize
    }

    pub fn from_u32(value: u32) -> Option<Self> {
        match value {
            1 => Some(Self::Mono8),
            3 => Some(Self::Rgb8),
            _ => None,
        }
    }
}

/// User header of a stereo frame. The payload is `[u8]`: the left plane followed by the right plane,
/// each `height * stride` bytes, rows top to bottom. Both planes are taken at `hdr.stamp_ns`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.StereoFrame.v1")]
pub struct StereoFrameHeader {
    pub hdr: Header,
    /// Stereo head that took the pair (matches the calibration and configuration name).
    pub head: Name,
    pub width: u32,
    pub height: u32,
    /// Bytes per row of one plane (>= width * bytes per pixel).
    pub stride: u32,
    /// A [`PixelEncoding`] value; read it with [`StereoFrameHeader::encoding`].
    pub encoding: u32,
}

impl StereoFrameHeader {
    pub fn encoding(&self) -> Option<PixelEncoding> {
        PixelEncoding::from_u32(self.encoding)
    }

    pub fn plane_len(&self) -> usize {
        self.stride as usize * self.height as usize
    }

    /// Payload length of a frame with this header (two planes).
    pub fn payload_len(&self) -> usize {
        2 * self.plane_len()
    }

    /// Splits a payload into its (left, right) planes, or `None` if the length does not match.
    pub fn planes<'a>(&self, payload: &'a [u8]) -> Option<(&'a [u8], &'a [u8])> {
        (payload.len() == self.payload_len()).then(|| payload.split_at(self.plane_len()))
    }
}

/// Geodetic anchor of the local ENU frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
pub struct GeodeticOrigin {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub altitude_m: f64,
}

/// Navigation solution of the INS at `hdr.stamp_ns`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.InsState.v1")]
pub struct InsState {
    pub hdr: Header,
    pub origin: GeodeticOrigin,
    /// Body pose in the ENU world frame.
    pub pose: Pose,
    /// Velocity in the ENU world frame (m/s).
    pub velocity: [f64; 3],
    /// Body angular rates about x, y, z (rad/s).
    pub angular_rate: [f64; 3],
    /// 1-sigma position uncertainty (m).
    pub position_sigma: f64,
}

impl InsState {
    /// Checks the fields a consumer relies on; an INS that reports NaN or infinity is a fault, not data.
    pub fn validate(&self) -> Result<(), &'static str> {
        let values = self
            .pose
            .position
            .iter()
            .chain(&self.velocity)
            .chain(&self.angular_rate)
            .chain([&self.pose.roll, &self.pose.pitch, &self.pose.yaw]);
        for v in values {
            if !v.is_finite() {
                return Err("INS state contains NaN or infinity");
            }
        }
        Ok(())
    }

    /// Speed over ground (m/s).
    pub fn speed(&self) -> f64 {
        self.velocity[0].hypot(self.velocity[1])
    }
}
