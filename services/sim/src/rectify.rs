//! A head's true calibration in the stereo service's conventions, and the rectified (virtual) camera
//! the stereo service derives from it.
//!
//! The simulator must not link the stereo service, yet its per-pixel truth has to land on exactly the
//! pixels the service's disparity refers to. So this module repeats the small amount of math of
//! `stereo::calib::Rectifier::new` (Bouguet split of the relative rotation, baseline turned onto x,
//! focal and principal point fitted to the oversized view); a test with the stereo library as a
//! dev-dependency checks that both agree on the same calibration (`tests/geometry.rs`).
//!
//! Conventions (OpenCV, as the stereo service): `X_r = R X_l + T` in raw optical frames (x right,
//! y down, z forward), T in metres; distortion is radial `k1, k2` on normalized coordinates.

use nalgebra::{Matrix3, Rotation3, Vector3};

/// Pinhole intrinsics with radial distortion (square pixels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    pub f: f64,
    pub cx: f64,
    pub cy: f64,
    pub k1: f64,
    pub k2: f64,
}

impl Lens {
    /// Normalized undistorted to normalized distorted coordinates.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * self.k2);
        (x * radial, y * radial)
    }

    /// Pixel to normalized undistorted coordinates: the stereo service's fixed-point iteration
    /// (20 steps, as OpenCV), so both sides invert the lens identically.
    pub fn undistort_pixel(&self, u: f64, v: f64) -> (f64, f64) {
        let (xd, yd) = ((u - self.cx) / self.f, (v - self.cy) / self.f);
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * self.k2);
            x = xd / radial;
            y = yd / radial;
        }
        (x, y)
    }
}

/// A head's calibration as `sim calib` writes it.
#[derive(Clone, Debug, PartialEq)]
pub struct HeadCalibration {
    pub width: usize,
    pub height: usize,
    pub left: Lens,
    pub right: Lens,
    /// Left raw optical frame to right raw optical frame.
    pub rotation: Matrix3<f64>,
    /// Metres, `X_r = R X_l + T`.
    pub translation: Vector3<f64>,
    pub oversize: f64,
}

/// The rectified left camera: pinhole, no distortion, baseline along its x axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RectifiedView {
    pub width: usize,
    pub height: usize,
    pub f: f64,
    pub cx: f64,
    pub cy: f64,
    pub baseline: f64,
    /// Rotation taking raw left optical coordinates to rectified ones.
    pub rect_from_left: Matrix3<f64>,
}

#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum RectifyError {
    #[error("vertical baselines are not supported")]
    VerticalBaseline,
    #[error("field of view reaches 90 degrees from the rectified axis")]
    FieldOfView,
    #[error("baseline must be non-zero")]
    NoBaseline,
}

impl HeadCalibration {
    /// The calibration file the stereo service reads (`stereo::calib::Calibration`). Numbers are
    /// written in Rust's shortest round-trip form, so the service parses exactly these values.
    pub fn to_toml(&self) -> String {
        let r = &self.rotation;
        let row = |i: usize| format!("[{:?}, {:?}, {:?}]", r[(i, 0)], r[(i, 1)], r[(i, 2)]);
        let t = &self.translation;
        let mut s = format!(
            "width = {}\nheight = {}\nrotation = [{}, {}, {}]\ntranslation = [{:?}, {:?}, {:?}]\noversize = {:?}\n",
            self.width,
            self.height,
            row(0),
            row(1),
            row(2),
            t.x,
            t.y,
            t.z,
            self.oversize
        );
        for (side, k) in [("left", &self.left), ("right", &self.right)] {
            s += &format!(
                "\n[{side}]\nfx = {:?}\nfy = {:?}\ncx = {:?}\ncy = {:?}\nk1 = {:?}\nk2 = {:?}\n",
                k.f, k.f, k.cx, k.cy, k.k1, k.k2
            );
        }
        s
    }

    /// The stereo service's rectification of this calibration (see the module docs).
    pub fn rectify(&self) -> Result<RectifiedView, RectifyError> {
        let t = self.translation;
        if t.norm() <= 1e-9 {
            return Err(RectifyError::NoBaseline);
        }
        let half = Rotation3::from_matrix_unchecked(self.rotation).scaled_axis() * -0.5;
        let r_r = Rotation3::from_scaled_axis(half).into_inner();
        let t_half = r_r * t;
        if t_half.x.abs() < t_half.y.abs() {
            return Err(RectifyError::VerticalBaseline);
        }
        let axis = Vector3::new(t_half.x.signum(), 0.0, 0.0);
        let ww = t_half.cross(&axis);
        let w_r = if ww.norm() > 1e-12 {
            let angle = (t_half.x.abs() / t_half.norm()).clamp(-1.0, 1.0).acos();
            Rotation3::from_scaled_axis(ww.normalize() * angle).into_inner()
        } else {
            Matrix3::identity()
        };
        let rect_l = w_r * r_r.transpose();
        let rect_r = w_r * r_r;
        let (rw, rh) = (
            (self.width as f64 * self.oversize).round() as usize,
            (self.height as f64 * self.oversize).round() as usize,
        );
        let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
        for (k, rot) in [(&self.left, &rect_l), (&self.right, &rect_r)] {
            for p in border_points(self.width, self.height) {
                let (x, y) = k.undistort_pixel(p.0, p.1);
                let q = rot * Vector3::new(x, y, 1.0);
                if q.z <= 1e-6 {
                    return Err(RectifyError::FieldOfView);
                }
                let n = Vector3::new(q.x / q.z, q.y / q.z, 0.0);
                lo = lo.inf(&n);
                hi = hi.sup(&n);
            }
        }
        let f_raw = self.left.f.min(self.right.f);
        // The largest focal (at most the raw one) that shows both raw views whole.
        let f = f_raw
            .min((rw - 1) as f64 / (hi.x - lo.x))
            .min((rh - 1) as f64 / (hi.y - lo.y));
        Ok(RectifiedView {
            width: rw,
            height: rh,
            f,
            cx: (rw - 1) as f64 / 2.0 - f * (hi.x + lo.x) / 2.0,
            cy: (rh - 1) as f64 / 2.0 - f * (hi.y + lo.y) / 2.0,
            baseline: t.norm(),
            rect_from_left: rect_l,
        })
    }
}

/// The same sampling of the raw image border as the stereo service.
fn border_points(w: usize, h: usize) -> impl Iterator<Item = (f64, f64)> {
    const N: usize = 16;
    let (w, h) = ((w - 1) as f64, (h - 1) as f64);
    (0..=N).flat_map(move |i| {
        let s = i as f64 / N as f64;
        [(s * w, 0.0), (s * w, h), (0.0, s * h), (w, s * h)]
    })
}
