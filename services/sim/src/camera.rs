//! Stereo heads and the pinhole cameras they produce.
//!
//! A head is a pair of identical cameras on a bar. The head's mount (x, y, z, roll, pitch, yaw in the
//! body frame) is the pose of the bar's centre; the bar's axes follow the body convention (x forward,
//! y left, z up). The left camera sits `baseline / 2` along the bar's +y axis, the right one as far
//! along -y, so the baseline is always perpendicular to the bar's forward axis. Both cameras are yawed
//! by `toe` about the bar's z axis (Hammerhead's left- and right-facing pairs on one bar); with
//! `toe = 0` the head is an ideal rectified pair whose ground-truth disparity is exactly `f * B / Z`.
//! Lenses may have radial distortion (`k1`, `k2`, OpenCV model on normalized coordinates).
//!
//! A camera's optical frame is x right, y down, z forward. Pixel (u, v) = (column, row) has its centre
//! at integer coordinates; the principal point is the image centre.
//!
//! Per-pixel truth is rendered for the rectified (virtual) left camera the stereo service derives from
//! the head's calibration ([`StereoHead::calibration`], [`StereoHead::rectified`]): for a toed head it
//! is rotated with respect to the real left camera and oversized, so the truth lands on the pixels of
//! the service's disparity image.

use crate::math::{bodylike_from_optical, Pose, M3, V3};
use crate::rectify::{HeadCalibration, Lens, RectifiedView, RectifyError};
use nalgebra::{Matrix3, Rotation3, Vector3};

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
    /// `body_from_head`: the bar's centre and axes (position in metres, roll/pitch/yaw in radians).
    pub mount: Pose,
    /// Standard deviation of per-pixel sensor noise, in grey levels.
    pub pixel_noise: f32,
    /// Yaw of both cameras about the bar's z axis (radians, positive = left).
    pub toe: f64,
    /// Radial distortion of both lenses.
    pub k1: f64,
    pub k2: f64,
    /// Rectified view size relative to the raw images (what `sim calib` writes as `oversize`).
    pub oversize: f64,
}

/// Rectified size of a toed head: Hammerhead's ~20 % keeps the forward resolution without losing
/// the sides.
pub const TOED_OVERSIZE: f64 = 1.2;

impl StereoHead {
    /// Focal length in pixels (square pixels).
    pub fn focal_px(&self) -> f64 {
        (self.width as f64 / 2.0) / (self.hfov_deg.to_radians() / 2.0).tan()
    }

    /// The pinhole model of an ideal (untoed) head's left camera, with its images resized by
    /// `1 / scale`: what `sim calib` writes for it and the stereo service publishes with its
    /// disparity (the left lens sits half a baseline to port of the head's mount).
    pub fn ideal_camera_model(&self, scale: f64) -> messages::CameraModel {
        let f = self.focal_px() / scale;
        let (w, h) = (
            (self.width as f64 / scale).floor(),
            (self.height as f64 / scale).floor(),
        );
        let lens = self.mount.position
            + self.mount.rotation() * Vector3::new(0.0, self.baseline / 2.0, 0.0);
        messages::CameraModel {
            fx: f,
            fy: f,
            cx: (w - 1.0) / 2.0,
            cy: (h - 1.0) / 2.0,
            baseline_m: self.baseline,
            mount: messages::Pose {
                position: lens.into(),
                roll: self.mount.rpy[0],
                pitch: self.mount.rpy[1],
                yaw: self.mount.rpy[2],
            },
        }
    }

    /// Bytes of one image of this head.
    pub fn image_len(&self) -> usize {
        self.width as usize * self.height as usize * self.encoding.channels()
    }

    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Rotation of both cameras' body-like axes in the bar frame (the toe yaw).
    fn toe_rotation(&self) -> Rotation3<f64> {
        Rotation3::from_euler_angles(0.0, 0.0, self.toe)
    }

    /// Pose of the real left camera on the body: optical centre and `body_from_camera` rotation of
    /// its body-like axes (x forward along the optical axis, y left, z up).
    pub fn left_camera_mount(&self) -> (Vector3<f64>, Rotation3<f64>) {
        let bar = self.mount.rotation();
        (
            self.mount.position + bar * Vector3::new(0.0, self.baseline / 2.0, 0.0),
            bar * self.toe_rotation(),
        )
    }

    /// The lens model shared by both cameras (principal point at the image centre).
    pub fn lens(&self) -> Lens {
        Lens {
            f: self.focal_px(),
            cx: (self.width as f64 - 1.0) / 2.0,
            cy: (self.height as f64 - 1.0) / 2.0,
            k1: self.k1,
            k2: self.k2,
        }
    }

    /// The head's true calibration in the stereo service's OpenCV conventions. Both cameras share
    /// their orientation, so `R = I`; the left-to-right offset `(0, -B, 0)` of the bar frame, seen in
    /// the left camera's optical frame, is `T = (-B cos toe, 0, B sin toe)`.
    pub fn calibration(&self) -> HeadCalibration {
        let (s, c) = self.toe.sin_cos();
        HeadCalibration {
            width: self.width as usize,
            height: self.height as usize,
            left: self.lens(),
            right: self.lens(),
            rotation: Matrix3::identity(),
            translation: Vector3::new(-self.baseline * c, 0.0, self.baseline * s),
            oversize: self.oversize,
        }
    }

    /// The rectified left camera of [`Self::calibration`], as the stereo service computes it.
    pub fn rectified(&self) -> Result<RectifiedView, RectifyError> {
        self.calibration().rectify()
    }

    /// Pose of the rectified (virtual) left camera on the body: same optical centre as the real one,
    /// `body_from_camera` rotation of its body-like axes.
    pub fn rectified_mount(&self, view: &RectifiedView) -> (Vector3<f64>, Rotation3<f64>) {
        let (pos, rot) = self.left_camera_mount();
        let b = bodylike_from_optical();
        let m = rot.matrix() * b * view.rect_from_left.transpose() * b.transpose();
        (pos, Rotation3::from_matrix(&m))
    }

    /// Left and right cameras for the vehicle at `body` (`world_from_body`).
    pub fn cameras(&self, body: &Pose) -> [Camera; 2] {
        let (head_pos, head_rot) = body.compose(&self.mount);
        let world_from_optical =
            (head_rot * self.toe_rotation()).matrix() * bodylike_from_optical();
        let left_offset = head_rot * Vector3::new(0.0, self.baseline / 2.0, 0.0);
        let f = self.focal_px();
        let cam = |pos: Vector3<f64>, index| Camera {
            width: self.width,
            height: self.height,
            f: f as f32,
            cx: (self.width as f32 - 1.0) / 2.0,
            cy: (self.height as f32 - 1.0) / 2.0,
            k1: self.k1 as f32,
            k2: self.k2 as f32,
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

    /// The rectified (virtual) left camera `view` of this head for the vehicle at `body`: pinhole,
    /// the view's size and intrinsics, rotated from the real left camera by the rectification.
    pub fn rectified_camera(&self, view: &RectifiedView, body: &Pose) -> Camera {
        let [left, _] = self.cameras(body);
        let rot64 = left.rot64 * view.rect_from_left.transpose();
        Camera {
            width: view.width as u32,
            height: view.height as u32,
            f: view.f as f32,
            cx: view.cx as f32,
            cy: view.cy as f32,
            k1: 0.0,
            k2: 0.0,
            rot: rot64.cast::<f32>(),
            rot64,
            baseline: view.baseline as f32,
            ..left
        }
    }

    /// Hammerhead's sensor head: one bar facing forward, 3 m above the water and pitched 4 deg down,
    /// carrying four 1280x960 mono cameras (60 deg HFOV) on one line along the bar. The left-facing
    /// pair (`hh_left`, toe +20 deg) has its cameras at bar y = +0.6 / -0.4 m, the right-facing pair
    /// (`hh_right`, toe -20 deg) at +0.4 / -0.6 m: 1 m baseline each, interleaved 0.2 m apart, about
    /// 100 deg combined. Plus an ideal colour head.
    pub fn maritime_defaults() -> Vec<StereoHead> {
        let mount =
            |y: f64, pitch_deg: f64| Pose::new([0.5, y, 3.0], [0.0, pitch_deg.to_radians(), 0.0]);
        let mono = |name: &str, y, toe_deg: f64| StereoHead {
            name: name.into(),
            width: 1280,
            height: 960,
            hfov_deg: 60.0,
            baseline: 1.0,
            encoding: Encoding::Mono8,
            mount: mount(y, 4.0),
            pixel_noise: 1.0,
            toe: toe_deg.to_radians(),
            k1: 0.0,
            k2: 0.0,
            oversize: TOED_OVERSIZE,
        };
        vec![
            mono("hh_left", 0.1, 20.0),
            mono("hh_right", -0.1, -20.0),
            StereoHead {
                name: "color".into(),
                width: 640,
                height: 480,
                hfov_deg: 70.0,
                baseline: 0.5,
                encoding: Encoding::Rgb8,
                mount: mount(0.0, 6.0),
                pixel_noise: 1.0,
                toe: 0.0,
                k1: 0.0,
                k2: 0.0,
                oversize: 1.0,
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
            toe: 0.0,
            k1: 0.0,
            k2: 0.0,
            oversize: 1.0,
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
    /// Radial distortion (OpenCV model on normalized coordinates).
    pub k1: f32,
    pub k2: f32,
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
        let (mut x, mut y) = ((u - self.cx) / self.f, (v - self.cy) / self.f);
        if self.k1 != 0.0 || self.k2 != 0.0 {
            // Invert the radial model by fixed-point iteration (as OpenCV's undistortPoints).
            let (xd, yd) = (x, y);
            for _ in 0..20 {
                let r2 = x * x + y * y;
                let radial = 1.0 + r2 * (self.k1 + r2 * self.k2);
                x = xd / radial;
                y = yd / radial;
            }
        }
        self.rot * V3::new(x, y, 1.0)
    }

    /// Pixel (u, v) and depth Z of a world point, or `None` behind the camera.
    pub fn project(&self, p: Vector3<f64>) -> Option<(f64, f64, f64)> {
        let q = self.rot64.transpose() * (p - self.pos64);
        if q.z <= 1e-9 {
            return None;
        }
        let f = self.f as f64;
        let (x, y) = (q.x / q.z, q.y / q.z);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 as f64 + r2 * self.k2 as f64);
        Some((
            f * x * radial + self.cx as f64,
            f * y * radial + self.cy as f64,
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
            toe: 0.0,
            k1: 0.0,
            k2: 0.0,
            oversize: 1.0,
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

    fn hammerhead() -> (StereoHead, StereoHead) {
        let heads = StereoHead::maritime_defaults();
        (heads[0].clone(), heads[1].clone())
    }

    #[test]
    fn hammerhead_cameras_lie_on_one_line_along_the_bar() {
        let (l, r) = hammerhead();
        assert_eq!((l.name.as_str(), r.name.as_str()), ("hh_left", "hh_right"));
        let body = Pose::new([3.0, -2.0, 0.2], [0.05, -0.02, 1.0]);
        let [a, b] = l.cameras(&body);
        let [c, d] = r.cameras(&body);
        // Bar axis in the world: body pose times the bar's y axis.
        let (_, bar_rot) = body.compose(&l.mount);
        let axis = bar_rot * Vector3::y();
        for p in [&b, &c, &d] {
            let off = p.pos64 - a.pos64;
            assert!(
                off.cross(&axis).norm() < 1e-9,
                "camera {:?} is off the bar line through {:?}",
                p.pos64,
                a.pos64
            );
        }
        // Positions along the bar (left is +y): hh_left +0.6/-0.4, hh_right +0.4/-0.6.
        let along = |p: &Camera| (p.pos64 - a.pos64).dot(&axis) + 0.6;
        let got = [along(&a), along(&b), along(&c), along(&d)];
        for (g, want) in got.iter().zip([0.6, -0.4, 0.4, -0.6]) {
            assert!((g - want).abs() < 1e-9, "{got:?}");
        }
        assert!(((a.pos64 - b.pos64).norm() - 1.0).abs() < 1e-12);
        assert!(((c.pos64 - d.pos64).norm() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn toe_yaws_the_cameras_but_not_the_baseline() {
        let (l, r) = hammerhead();
        // Level body at the origin facing east (+x).
        let body = Pose::new([0.0; 3], [0.0; 3]);
        for (head, toe_deg) in [(&l, 20.0f64), (&r, -20.0)] {
            let [a, b] = head.cameras(&body);
            // Optical axes of both cameras: yawed by the toe about the bar's (pitched) z axis,
            // so their horizontal heading is atan2(y, x) of the axis.
            for cam in [&a, &b] {
                let z = cam.rot64 * Vector3::z();
                let heading = z.y.atan2(z.x).to_degrees();
                let expected = (toe_deg.to_radians().tan() / 4f64.to_radians().cos())
                    .atan()
                    .to_degrees();
                assert!((heading - expected).abs() < 1e-6, "{heading} vs {expected}");
                assert!(z.z < 0.0, "pitched down");
            }
            assert_eq!(a.rot64, b.rot64, "cameras of a pair are parallel");
            // The baseline stays perpendicular to the bar's forward axis.
            let fwd = head.mount.rotation() * Vector3::x();
            assert!((a.pos64 - b.pos64).dot(&fwd).abs() < 1e-12);
        }
        let (pos, rot) = l.left_camera_mount();
        let [a, _] = l.cameras(&body);
        assert!((pos - a.pos64).norm() < 1e-12);
        assert!(
            ((rot.matrix() * bodylike_from_optical()) - a.rot64)
                .abs()
                .max()
                < 1e-12
        );
    }

    #[test]
    fn calibration_maps_left_camera_points_to_right_ones() {
        for toe_deg in [20.0f64, -20.0, 0.0, 7.5] {
            let mut head = hammerhead().0;
            head.toe = toe_deg.to_radians();
            head.k1 = -0.05;
            let c = head.calibration();
            let body = Pose::new([10.0, 5.0, 0.3], [0.02, -0.03, 0.7]);
            let [l, r] = head.cameras(&body);
            for p in [
                Vector3::new(40.0, 30.0, 2.0),
                Vector3::new(-5.0, 20.0, -1.0),
                Vector3::new(12.0, 4.0, 0.0),
            ] {
                let xl = l.rot64.transpose() * (p - l.pos64);
                let xr = r.rot64.transpose() * (p - r.pos64);
                let mapped = c.rotation * xl + c.translation;
                assert!(
                    (mapped - xr).norm() < 1e-9,
                    "toe {toe_deg}: {mapped:?} vs {xr:?}"
                );
            }
            assert!((c.translation.norm() - head.baseline).abs() < 1e-12);
            assert_eq!((c.left.k1, c.oversize), (-0.05, 1.2));
        }
        // An ideal head keeps the old calibration exactly.
        let mut ideal = hammerhead().0;
        ideal.toe = 0.0;
        let c = ideal.calibration();
        assert_eq!(c.translation, Vector3::new(-1.0, 0.0, 0.0));
        assert_eq!(c.rotation, Matrix3::identity());
    }

    #[test]
    fn toed_head_rectifies_to_the_bar_attitude_with_the_oversized_view() {
        let (l, r) = hammerhead();
        for head in [&l, &r] {
            let view = head.rectified().unwrap();
            assert_eq!((view.width, view.height), (1536, 1152));
            // Whole raw views inside 1536x1152: the vertical extent of the far corners limits f.
            assert!(view.f > 900.0 && view.f < head.focal_px(), "f {}", view.f);
            let (pos, rot) = head.rectified_mount(&view);
            let (roll, pitch, yaw) = rot.euler_angles();
            assert!(roll.abs() < 1e-9 && yaw.abs() < 1e-9, "{roll} {yaw}");
            assert!((pitch - 4f64.to_radians()).abs() < 1e-9);
            assert!((pos - head.left_camera_mount().0).norm() < 1e-12);
            // The forward direction of the bar is inside the view, on the side the head looks
            // away from: left-toed heads see forward right of the rectified centre.
            let side = view.cx - (view.width as f64 - 1.0) / 2.0;
            assert!(side.signum() == head.toe.signum(), "cx {}", view.cx);
        }
        // An ideal head's rectified view is its raw left image.
        let mut ideal = l.clone();
        ideal.toe = 0.0;
        ideal.oversize = 1.0;
        let v = ideal.rectified().unwrap();
        assert_eq!((v.width, v.height), (1280, 960));
        assert!((v.f - ideal.focal_px()).abs() < 1e-9 && (v.cx - 639.5).abs() < 1e-9);
        assert_eq!(v.rect_from_left, Matrix3::identity());
    }
}
