//! One stereo head's per-frame work, independent of where frames come from: rectify the raw pair,
//! match, and fit the water plane on the lower image rows. Buffers are allocated once, at the
//! calibration's size, and reused for every frame.

use crate::calib::{CalibError, Calibration, RectifiedCamera, Rectifier, RectifyError};
use crate::disparity::{build_matcher, DisparityMap, DisparityMatcher, MatchError, MatcherConfig};
use crate::image::{GrayImage, GrayView, ImageError};
use crate::plane::{PlaneError, PlaneFitter, PlaneParams, WaterPlane};
use crate::range::collect_points;
use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::Deserialize;

/// Rotation taking optical vectors (x right, y down, z forward) into body-like axes (x forward,
/// y left, z up), the axes a mount's roll, pitch and yaw turn.
fn bodylike_from_optical() -> Matrix3<f64> {
    Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0)
}

/// The mount of the rectified (virtual) left camera, the frame the disparity and the water plane
/// refer to, from the mount of the real left camera (both on the body: x forward, y left, z up).
/// Same optical centre; the attitude is turned by the rectification, which for heads yawed on a
/// common bar is the full toe angle.
pub fn rectified_mount(raw: &messages::Pose, rect_from_left: &Matrix3<f64>) -> messages::Pose {
    let b = bodylike_from_optical();
    let body_from_raw = Rotation3::from_euler_angles(raw.roll, raw.pitch, raw.yaw);
    let m = body_from_raw.matrix() * b * rect_from_left.transpose() * b.transpose();
    let (roll, pitch, yaw) = Rotation3::from_matrix(&m).euler_angles();
    messages::Pose {
        position: raw.position,
        roll,
        pitch,
        yaw,
    }
}

/// Where the water plane is looked for.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct PlaneSearch {
    /// Fraction of the image height, from the bottom, whose points feed the fit.
    pub lower_fraction: f64,
    /// Points farther than this are too noisy for the fit (m).
    pub max_range_m: f64,
    /// Use every n-th pixel in both directions.
    pub step: usize,
    pub fit: PlaneParams,
}

impl Default for PlaneSearch {
    fn default() -> Self {
        Self {
            lower_fraction: 0.3,
            max_range_m: 40.0,
            step: 4,
            fit: PlaneParams::default(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error(transparent)]
    Rectify(#[from] RectifyError),
    #[error(transparent)]
    Match(#[from] MatchError),
}

pub struct FramePipeline {
    rectifier: Rectifier,
    matcher: Box<dyn DisparityMatcher>,
    fitter: PlaneFitter,
    search: PlaneSearch,
    raw_size: (usize, usize),
    left: GrayImage,
    right: GrayImage,
    disparity: DisparityMap,
    points: Vec<Vector3<f32>>,
}

/// What one frame produced.
pub struct FrameResult<'a> {
    pub disparity: &'a DisparityMap,
    /// `Err` when no plane was found in this frame (not a frame error: open water far away, say).
    pub plane: Result<WaterPlane, PlaneError>,
}

impl FramePipeline {
    pub fn new(
        calibration: &Calibration,
        matcher: &MatcherConfig,
        search: PlaneSearch,
    ) -> Result<Self, PipelineSetupError> {
        let rectifier = Rectifier::new(calibration)?;
        let cam = rectifier.camera();
        let matcher = build_matcher(matcher, cam.width, cam.height)?;
        Ok(Self {
            fitter: PlaneFitter::new(search.fit.clone()),
            search,
            raw_size: (calibration.width, calibration.height),
            left: GrayImage::new(cam.width, cam.height),
            right: GrayImage::new(cam.width, cam.height),
            disparity: DisparityMap::new(cam.width, cam.height),
            points: Vec::new(),
            rectifier,
            matcher,
        })
    }

    /// The rectified camera the disparity refers to.
    pub fn camera(&self) -> RectifiedCamera {
        self.rectifier.camera()
    }

    /// Rotation from the raw left camera frame to the rectified one.
    pub fn rect_from_left(&self) -> Matrix3<f64> {
        self.rectifier.rect_from_left()
    }

    /// Raw frame size the calibration expects (width, height).
    pub fn raw_size(&self) -> (usize, usize) {
        self.raw_size
    }

    pub fn num_disparities(&self) -> usize {
        self.matcher.num_disparities()
    }

    /// Processes one raw Mono8 pair (rows packed, `width` bytes each).
    pub fn process(
        &mut self,
        width: usize,
        height: usize,
        left: &[u8],
        right: &[u8],
    ) -> Result<FrameResult<'_>, FrameError> {
        let left_view = GrayView::new(width, height, left)?;
        let right_view = GrayView::new(width, height, right)?;
        self.rectifier
            .rectify_left_into(left_view, &mut self.left)?;
        self.rectifier
            .rectify_right_into(right_view, &mut self.right)?;
        self.matcher
            .compute(self.left.view(), self.right.view(), &mut self.disparity)?;
        let cam = self.rectifier.camera();
        let h = self.disparity.height;
        let first_row = ((1.0 - self.search.lower_fraction.clamp(0.0, 1.0)) * h as f64) as usize;
        collect_points(
            &cam,
            &self.disparity,
            first_row..h,
            self.search.step,
            self.search.max_range_m,
            &mut self.points,
        );
        let plane = self.fitter.fit(&self.points);
        Ok(FrameResult {
            disparity: &self.disparity,
            plane,
        })
    }
}

#[derive(Debug, thiserror::Error)]
pub enum PipelineSetupError {
    #[error(transparent)]
    Calibration(#[from] CalibError),
    #[error(transparent)]
    Matcher(#[from] MatchError),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::{Calibration, Intrinsics};

    fn lens() -> Intrinsics {
        Intrinsics {
            fx: 554.0,
            fy: 554.0,
            cx: 319.5,
            cy: 239.5,
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        }
    }

    /// A point at a known body position, seen by a pair toed 20 deg left on a bar pitched 4 deg
    /// down, comes back at that position through rectified disparity, `CameraModel::point` and the
    /// published (rectified) mount, as perception and water detection transform it.
    #[test]
    fn rectified_disparity_and_mount_give_back_body_points() {
        let toe = 20f64.to_radians();
        let b = 1.0;
        let bar = Rotation3::from_euler_angles(0.0, 4f64.to_radians(), 0.0);
        let bar_pos = Vector3::new(0.5, 0.1, 3.0);
        let left_pos = bar_pos + bar * Vector3::new(0.0, b / 2.0, 0.0);
        let body_from_left = bar * Rotation3::from_euler_angles(0.0, 0.0, toe);
        let calib = Calibration {
            width: 640,
            height: 480,
            left: lens(),
            right: lens(),
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [-b * toe.cos(), 0.0, b * toe.sin()],
            oversize: 1.2,
        };
        let rect = crate::calib::Rectifier::new(&calib).unwrap();
        let cam = rect.camera();
        let (roll, pitch, yaw) = body_from_left.euler_angles();
        let raw = messages::Pose {
            position: left_pos.into(),
            roll,
            pitch,
            yaw,
        };
        let mount = rectified_mount(&raw, &rect.rect_from_left());
        // The rectified camera has the bar's attitude: the toe is undone, the pitch kept.
        assert!(mount.yaw.abs() < 1e-9, "yaw {}", mount.yaw.to_degrees());
        assert!((mount.pitch - 4f64.to_radians()).abs() < 1e-9);
        assert!(mount.roll.abs() < 1e-9);
        let model = messages::CameraModel {
            fx: cam.f,
            fy: cam.f,
            cx: cam.cx,
            cy: cam.cy,
            baseline_m: cam.baseline,
            mount,
        };
        let b_opt = bodylike_from_optical();
        let body_from_rect = Rotation3::from_euler_angles(mount.roll, mount.pitch, mount.yaw);
        for p_body in [
            Vector3::new(30.0, 12.0, 0.5),
            Vector3::new(12.0, -1.0, 0.0),
            Vector3::new(60.0, 40.0, 4.0),
        ] {
            // Project through the real left camera, then the rectification (the right camera of
            // the rectified pair is the left one moved by the baseline along x).
            let raw_opt = b_opt.transpose() * (body_from_left.inverse() * (p_body - left_pos));
            let q = rect.rect_from_left() * raw_opt;
            let ul = cam.f * q.x / q.z + cam.cx;
            let vl = cam.f * q.y / q.z + cam.cy;
            let ur = cam.f * (q.x - cam.baseline) / q.z + cam.cx;
            let p = model.point(ul, vl, (ul - ur) as f32).unwrap();
            let back = body_from_rect * (b_opt * Vector3::from(p)) + Vector3::from(mount.position);
            // f32 disparity: relative precision ~1e-7 of the range.
            assert!(
                (back - p_body).norm() < 1e-5 * p_body.norm(),
                "{p_body:?} came back at {back:?}"
            );
            // Through the real camera's mount instead the point lands elsewhere (toe not undone).
            let wrong = body_from_left * (b_opt * Vector3::from(p)) + left_pos;
            assert!((wrong - p_body).norm() > 0.2 * p_body.norm());
        }
    }
}
