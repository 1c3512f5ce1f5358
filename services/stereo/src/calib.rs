//! Stereo calibration (TOML), Bouguet-style rectification (as OpenCV's stereoRectify) and bilinear
//! remapping of Mono8 frames through tables computed once.
//!
//! Conventions follow OpenCV: intrinsics fx, fy, cx, cy with distortion k1, k2, p1, p2, k3, and the
//! stereo extrinsics map left-camera points to right-camera points, `X_r = R X_l + T` (T in metres).
//! Both rectified cameras share f, cx, cy, so `d = x_left - x_right = f B / Z`.

use std::path::Path;

use nalgebra::{Matrix3, Rotation3, Vector3};
use rayon::prelude::*;
use serde::Deserialize;
use thiserror::Error;

use crate::image::{GrayImage, GrayView};

#[derive(Debug, Error)]
pub enum CalibError {
    #[error("reading calibration {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("parsing calibration: {0}")]
    Parse(#[from] toml::de::Error),
    #[error("calibration field `{field}`: {reason}")]
    Invalid { field: &'static str, reason: String },
}

#[derive(Debug, Error, PartialEq, Eq)]
pub enum RectifyError {
    #[error("{which} frame is {got_w}x{got_h}, calibration is for {want_w}x{want_h}")]
    SizeMismatch {
        which: &'static str,
        want_w: usize,
        want_h: usize,
        got_w: usize,
        got_h: usize,
    },
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    #[serde(default)]
    pub k1: f64,
    #[serde(default)]
    pub k2: f64,
    #[serde(default)]
    pub p1: f64,
    #[serde(default)]
    pub p2: f64,
    #[serde(default)]
    pub k3: f64,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// Raw image size in pixels.
    pub width: usize,
    pub height: usize,
    pub left: Intrinsics,
    pub right: Intrinsics,
    /// Row-major rotation, left camera frame to right camera frame.
    pub rotation: [[f64; 3]; 3],
    /// Translation in metres, `X_r = R X_l + T`.
    pub translation: [f64; 3],
    /// Rectified image size relative to the raw one. Heads yawed away from the baseline normal
    /// need ~1.2 to keep forward resolution without losing the sides.
    #[serde(default = "one")]
    pub oversize: f64,
}

fn one() -> f64 {
    1.0
}

impl Calibration {
    /// An ideal rectified pair (no distortion, no rotation, principal point at the image centre),
    /// as the simulator's untoed heads are: what tools that render and match simulated frames use.
    pub fn ideal(width: usize, height: usize, focal_px: f64, baseline_m: f64) -> Self {
        let intrinsics = Intrinsics {
            fx: focal_px,
            fy: focal_px,
            cx: (width as f64 - 1.0) / 2.0,
            cy: (height as f64 - 1.0) / 2.0,
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        };
        Self {
            width,
            height,
            left: intrinsics.clone(),
            right: intrinsics,
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [-baseline_m, 0.0, 0.0],
            oversize: 1.0,
        }
    }

    pub fn load(path: &Path) -> Result<Self, CalibError> {
        let text = std::fs::read_to_string(path).map_err(|source| CalibError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml(&text)
    }

    pub fn from_toml(text: &str) -> Result<Self, CalibError> {
        let c: Calibration = toml::from_str(text)?;
        c.validate()?;
        Ok(c)
    }

    pub fn validate(&self) -> Result<(), CalibError> {
        let bad = |field, reason: String| Err(CalibError::Invalid { field, reason });
        if self.width < 8 || self.height < 8 {
            return bad(
                "width",
                format!("{}x{} is too small", self.width, self.height),
            );
        }
        for (name, k) in [("left", &self.left), ("right", &self.right)] {
            let vals = [k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.p1, k.p2, k.k3];
            if vals.iter().any(|v| !v.is_finite()) {
                return bad(field_name(name, "intrinsics"), "not finite".into());
            }
            if k.fx <= 0.0 || k.fy <= 0.0 {
                return bad(
                    field_name(name, "fx"),
                    format!("focal {} {} must be > 0", k.fx, k.fy),
                );
            }
        }
        let r = self.rotation_matrix();
        let err = (r.transpose() * r - Matrix3::identity()).abs().max();
        if !err.is_finite() || err > 1e-3 || r.determinant() < 0.0 {
            return bad("rotation", "not a proper rotation matrix".into());
        }
        let t = Vector3::from(self.translation);
        if t.norm() <= 1e-9 || !t.norm().is_finite() {
            return bad("translation", "baseline must be non-zero".into());
        }
        if !(self.oversize >= 0.5 && self.oversize <= 3.0) {
            return bad("oversize", format!("{} not in 0.5..=3", self.oversize));
        }
        Ok(())
    }

    fn rotation_matrix(&self) -> Matrix3<f64> {
        let r = self.rotation;
        Matrix3::new(
            r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
        )
    }
}

fn field_name(cam: &str, f: &'static str) -> &'static str {
    match (cam, f) {
        ("left", "fx") => "left.fx",
        ("right", "fx") => "right.fx",
        ("left", _) => "left",
        _ => "right",
    }
}

/// The rectified pinhole pair: shared focal and principal point, baseline along x.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RectifiedCamera {
    pub width: usize,
    pub height: usize,
    pub f: f64,
    pub cx: f64,
    pub cy: f64,
    /// Metres.
    pub baseline: f64,
}

impl Intrinsics {
    /// Normalized undistorted coordinates to normalized distorted ones.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Pixel to normalized undistorted coordinates (fixed-point iteration, as OpenCV).
    pub fn undistort_pixel(&self, u: f64, v: f64) -> (f64, f64) {
        let (xd, yd) = ((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            x = (xd - dx) / radial;
            y = (yd - dy) / radial;
        }
        (x, y)
    }
}

/// Per rectified pixel: offset of the top-left source pixel and 8-bit bilinear weights.
/// `u32::MAX` marks pixels whose source lies outside the raw image (written as 0).
struct RemapTable {
    offset: Vec<u32>,
    frac: Vec<[u8; 2]>,
}

pub struct Rectifier {
    raw_w: usize,
    raw_h: usize,
    camera: RectifiedCamera,
    /// Rotation from the raw left camera frame to the rectified frame.
    rect_from_left: Matrix3<f64>,
    left: RemapTable,
    right: RemapTable,
}

impl Rectifier {
    pub fn new(c: &Calibration) -> Result<Self, CalibError> {
        c.validate()?;
        let r = c.rotation_matrix();
        let t = Vector3::from(c.translation);
        // Split the relative rotation in half so both cameras turn by the same amount...
        let half = Rotation3::from_matrix_unchecked(r).scaled_axis() * -0.5;
        let r_r = Rotation3::from_scaled_axis(half).into_inner();
        let t_half = r_r * t;
        // ...then turn both so the baseline lies along x.
        let (idx, axis) = if t_half.x.abs() >= t_half.y.abs() {
            (0, Vector3::new(t_half.x.signum(), 0.0, 0.0))
        } else {
            (1, Vector3::new(0.0, t_half.y.signum(), 0.0))
        };
        let ww = t_half.cross(&axis);
        let w_r = if ww.norm() > 1e-12 {
            let angle = (t_half[idx].abs() / t_half.norm()).clamp(-1.0, 1.0).acos();
            Rotation3::from_scaled_axis(ww.normalize() * angle).into_inner()
        } else {
            Matrix3::identity()
        };
        if idx == 1 {
            return Err(CalibError::Invalid {
                field: "translation",
                reason: "vertical baselines are not supported".into(),
            });
        }
        let rect_l = w_r * r_r.transpose();
        let rect_r = w_r * r_r;

        // Focal and principal point: the largest focal (at most the raw one) whose rectified
        // image of the oversized size still shows both raw views whole.
        let (rw, rh) = (
            (c.width as f64 * c.oversize).round() as usize,
            (c.height as f64 * c.oversize).round() as usize,
        );
        let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
        for (k, rot) in [(&c.left, &rect_l), (&c.right, &rect_r)] {
            for p in border_points(c.width, c.height) {
                let (x, y) = k.undistort_pixel(p.0, p.1);
                let q = rot * Vector3::new(x, y, 1.0);
                if q.z <= 1e-6 {
                    return Err(CalibError::Invalid {
                        field: "rotation",
                        reason: "field of view reaches 90 degrees from the rectified axis".into(),
                    });
                }
                let n = Vector3::new(q.x / q.z, q.y / q.z, 0.0);
                lo = lo.inf(&n);
                hi = hi.sup(&n);
            }
        }
        let f_raw = [c.left.fx, c.left.fy, c.right.fx, c.right.fy]
            .into_iter()
            .fold(f64::MAX, f64::min);
        let f = f_raw
            .min((rw - 1) as f64 / (hi.x - lo.x))
            .min((rh - 1) as f64 / (hi.y - lo.y));
        let cx = (rw - 1) as f64 / 2.0 - f * (hi.x + lo.x) / 2.0;
        let cy = (rh - 1) as f64 / 2.0 - f * (hi.y + lo.y) / 2.0;
        let camera = RectifiedCamera {
            width: rw,
            height: rh,
            f,
            cx,
            cy,
            baseline: t.norm(),
        };
        Ok(Self {
            raw_w: c.width,
            raw_h: c.height,
            camera,
            rect_from_left: rect_l,
            left: remap_table(&c.left, &rect_l, &camera, c.width, c.height),
            right: remap_table(&c.right, &rect_r, &camera, c.width, c.height),
        })
    }

    pub fn camera(&self) -> RectifiedCamera {
        self.camera
    }

    /// Rotation taking raw left-camera coordinates to the rectified frame.
    pub fn rect_from_left(&self) -> Matrix3<f64> {
        self.rect_from_left
    }

    pub fn rectify_left_into(
        &self,
        src: GrayView<'_>,
        dst: &mut GrayImage,
    ) -> Result<(), RectifyError> {
        self.apply(&self.left, "left", src, dst)
    }

    pub fn rectify_right_into(
        &self,
        src: GrayView<'_>,
        dst: &mut GrayImage,
    ) -> Result<(), RectifyError> {
        self.apply(&self.right, "right", src, dst)
    }

    /// Allocating convenience for offline use.
    pub fn rectify_left(&self, src: GrayView<'_>) -> Result<GrayImage, RectifyError> {
        let mut out = GrayImage::new(self.camera.width, self.camera.height);
        self.rectify_left_into(src, &mut out)?;
        Ok(out)
    }

    pub fn rectify_right(&self, src: GrayView<'_>) -> Result<GrayImage, RectifyError> {
        let mut out = GrayImage::new(self.camera.width, self.camera.height);
        self.rectify_right_into(src, &mut out)?;
        Ok(out)
    }

    fn apply(
        &self,
        t: &RemapTable,
        which: &'static str,
        src: GrayView<'_>,
        dst: &mut GrayImage,
    ) -> Result<(), RectifyError> {
        let (w, h) = (self.camera.width, self.camera.height);
        for (what, (gw, gh), (ww, wh)) in [
            (which, (src.width(), src.height()), (self.raw_w, self.raw_h)),
            ("rectified output", (dst.width, dst.height), (w, h)),
        ] {
            if (gw, gh) != (ww, wh) {
                return Err(RectifyError::SizeMismatch {
                    which: what,
                    want_w: ww,
                    want_h: wh,
                    got_w: gw,
                    got_h: gh,
                });
            }
        }
        let s = src.data();
        let sw = self.raw_w;
        dst.data
            .par_chunks_mut(w)
            .zip(t.offset.par_chunks(w).zip(t.frac.par_chunks(w)))
            .for_each(|(out, (off, frac))| {
                for ((o, &i), &[fx, fy]) in out.iter_mut().zip(off).zip(frac) {
                    if i == u32::MAX {
                        *o = 0;
                        continue;
                    }
                    let i = i as usize;
                    let (fx, fy) = (fx as u32, fy as u32);
                    let top = s[i] as u32 * (256 - fx) + s[i + 1] as u32 * fx;
                    let bot = s[i + sw] as u32 * (256 - fx) + s[i + sw + 1] as u32 * fx;
                    *o = ((top * (256 - fy) + bot * fy + (1 << 15)) >> 16) as u8;
                }
            });
        Ok(())
    }
}

fn border_points(w: usize, h: usize) -> impl Iterator<Item = (f64, f64)> {
    const N: usize = 16;
    let (w, h) = ((w - 1) as f64, (h - 1) as f64);
    (0..=N).flat_map(move |i| {
        let s = i as f64 / N as f64;
        [(s * w, 0.0), (s * w, h), (0.0, s * h), (w, s * h)]
    })
}

fn remap_table(
    k: &Intrinsics,
    rect: &Matrix3<f64>,
    cam: &RectifiedCamera,
    raw_w: usize,
    raw_h: usize,
) -> RemapTable {
    let n = cam.width * cam.height;
    let mut offset = vec![u32::MAX; n];
    let mut frac = vec![[0u8; 2]; n];
    let back = rect.transpose();
    for v in 0..cam.height {
        for u in 0..cam.width {
            let ray = back
                * Vector3::new(
                    (u as f64 - cam.cx) / cam.f,
                    (v as f64 - cam.cy) / cam.f,
                    1.0,
                );
            if ray.z <= 0.0 {
                continue;
            }
            let (xd, yd) = k.distort(ray.x / ray.z, ray.y / ray.z);
            let (sx, sy) = (k.fx * xd + k.cx, k.fy * yd + k.cy);
            // Both bilinear neighbours must be inside the raw image.
            if !(sx >= 0.0 && sy >= 0.0 && sx < (raw_w - 1) as f64 && sy < (raw_h - 1) as f64) {
                continue;
            }
            let (x0, y0) = (sx.floor(), sy.floor());
            let i = v * cam.width + u;
            offset[i] = (y0 as usize * raw_w + x0 as usize) as u32;
            frac[i] = [
                ((sx - x0) * 256.0).round().min(255.0) as u8,
                ((sy - y0) * 256.0).round().min(255.0) as u8,
            ];
        }
    }
    RemapTable { offset, frac }
}
