//! Stereo heads and the pinhole cameras they produce.
//!
//! A head is an ideal rectified pair: both cameras share orientation and intrinsics, the right camera
//! sits `baseline` metres along the head's -y (right) axis from the left one, so ground-truth disparity
//! is exactly `f * B / Z`. The head is mounted on the body with a pose (x, y, z, roll, pitch, yaw) in
//! the body frame; the head's own axes follow the body convention (x forward, y left, z up) and its
//! optical frame is x right, y down, z forward. Pixel (u, v) = (column, row) has its centre at integer
//! coordinates; the principal point is the image centre.

use crate::math::{bodylike_from_optical, Pose, M3, V3};
use nalgebra::{Matrix3, Vector3};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Encoding {
    Mono8,
    Rgb8,
}

impl Encoding {
    pub fn channels(self) -> usize {
        match self {
            Encoding::Mono8 => 1,
            Encoding::Rgb8 => 3,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct StereoHead {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub hfov_deg: f64,
    pub baseline: f64,
    pub encoding: Encoding,
    /// `body_from_head` (position in metres, roll/pitch/yaw in radians).
    pub mount: Pose,
    /// Standard deviation of per-pixel sensor noise, in grey levels.
    pub pixel_noise: f32,
}

impl StereoHead {
    /// Focal length in pixels (square pixels).
    pub fn focal_px(&self) -> f64 {
        (self.width as f64 / 2.0) / (self.hfov_deg.to_radians() / 2.0).tan()
    }

    /// Bytes of one image of this head.
    pub fn image_len(&self) -> usize {
        self.width as usize * self.height as usize * self.encoding.channels()
    }

    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Left and right cameras for the vehicle at `body` (`world_from_body`).
    pub fn cameras(&self, body: &Pose) -> [Camera; 2] {
        let (head_pos, head_rot) = body.compose(&self.mount);
        let world_from_optical = head_rot.matrix() * bodylike_from_optical();
        let left_offset = head_rot * Vector3::new(0.0, self.baseline / 2.0, 0.0);
        let f = self.focal_px();
        let cam = |pos: Vector3<f64>, index| Camera {
            width: self.width,
            height: self.height,
            f: f as f32,
            cx: (self.width as f32 - 1.0) / 2.0,
            cy: (self.height as f32 - 1.0) / 2.0,
            rot: world_from_optical.cast::<f32>(),
            rot64: world_from_optical,
            pos: pos.cast::<f32>(),
            pos64: pos,
            baseline: self.baseline as f32,
            index,
        };
        [
            cam(head_pos + left_offset, 0),
            cam(head_pos - left_offset, 1),
        ]
    }

    /// Hammerhead-like maritime set: two 1280x960 mono heads on one 1 m baseline bar, yawed 20 deg
    /// left and right (about 100 deg combined), 3 m above the water, plus a colour head.
    pub fn maritime_defaults() -> Vec<StereoHead> {
        let mount = |yaw_deg: f64, pitch_deg: f64| {
            Pose::new(
                [0.5, 0.0, 3.0],
                [0.0, pitch_deg.to_radians(), yaw_deg.to_radians()],
            )
        };
        let mono = |name: &str, yaw| StereoHead {
            name: name.into(),
            width: 1280,
            height: 960,
            hfov_deg: 60.0,
            baseline: 1.0,
            encoding: Encoding::Mono8,
            mount: mount(yaw, 4.0),
            pixel_noise: 1.0,
        };
        vec![
            mono("hh_left", 20.0),
            mono("hh_right", -20.0),
            StereoHead {
                name: "color".into(),
                width: 640,
                height: 480,
                hfov_deg: 70.0,
                baseline: 0.5,
                encoding: Encoding::Rgb8,
                mount: mount(0.0, 6.0),
                pixel_noise: 1.0,
            },
        ]
    }

    /// Ground vehicle: one colour head 2 m up, pitched down to see the trail (as in water detection).
    pub fn ground_defaults() -> Vec<StereoHead> {
        vec![StereoHead {
            name: "color".into(),
            width: 1024,
            height: 768,
            hfov_deg: 60.0,
            baseline: 0.5,
            encoding: Encoding::Rgb8,
            mount: Pose::new([0.5, 0.0, 2.0], [0.0, 10f64.to_radians(), 0.0]),
            pixel_noise: 1.0,
        }]
    }
}

/// A posed pinhole camera in the world.
#[derive(Clone, Debug)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub f: f32,
    pub cx: f32,
    pub cy: f32,
    /// `world_from_optical`.
    pub rot: M3,
    pub rot64: Matrix3<f64>,
    /// Optical centre in the world.
    pub pos: V3,
    pub pos64: Vector3<f64>,
    pub baseline: f32,
    /// 0 = left, 1 = right.
    pub index: u32,
}

impl Camera {
    /// Un-normalised world direction through pixel (u, v); its optical-axis component is 1, so the
    /// depth of a point at distance `s` along the normalised ray is `s / |dir|`.
    #[inline]
    pub fn ray(&self, u: f32, v: f32) -> V3 {
        self.rot * V3::new((u - self.cx) / self.f, (v - self.cy) / self.f, 1.0)
    }

    /// Pixel (u, v) and depth Z of a world point, or `None` behind the camera.
    pub fn project(&self, p: Vector3<f64>) -> Option<(f64, f64, f64)> {
        let q = self.rot64.transpose() * (p - self.pos64);
        if q.z <= 1e-9 {
            return None;
        }
        let f = self.f as f64;
        Some((
            f * q.x / q.z + self.cx as f64,
            f * q.y / q.z + self.cy as f64,
            q.z,
        ))
    }

    /// Angular size of one pixel (radians), for texture level of detail.
    pub fn pixel_angle(&self) -> f32 {
        1.0 / self.f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_head_looks_forward_and_left_is_left() {
        let head = StereoHead {
            name: "t".into(),
            width: 640,
            height: 480,
            hfov_deg: 90.0,
            baseline: 1.0,
            encoding: Encoding::Mono8,
            mount: Pose::new([0.0, 0.0, 2.0], [0.0; 3]),
            pixel_noise: 0.0,
        };
        // Vehicle faces north.
        let body = Pose::new([10.0, 20.0, 0.0], [0.0, 0.0, std::f64::consts::FRAC_PI_2]);
        let [l, r] = head.cameras(&body);
        let c = l.ray(l.cx, l.cy).normalize();
        assert!(
            (c - V3::new(0.0, 1.0, 0.0)).norm() < 1e-6,
            "optical axis faces north: {c:?}"
        );
        // Facing north, left is west: the left camera has the smaller x.
        assert!(l.pos.x < r.pos.x);
        assert!((l.pos.x - 9.5).abs() < 1e-6 && (l.pos.z - 2.0).abs() < 1e-6);
        // A point 10 m ahead projects to the centre with depth 10 m; right image shifts it left by f*B/Z.
        let p = Vector3::new(10.0, 30.0, 2.0);
        let (ul, vl, z) = l.project(p).unwrap();
        let (ur, _, _) = r.project(p).unwrap();
        // Left camera is 0.5 m west of the point: it appears right of centre, f * 0.5 / 10 = 16 px.
        assert!((ul - l.cx as f64 - 16.0).abs() < 1e-3, "{ul}");
        assert!((vl - l.cy as f64).abs() < 1e-6 && (z - 10.0).abs() < 1e-9);
        assert!(((ul - ur) - l.f as f64 * 1.0 / 10.0).abs() < 1e-6);
    }
}
