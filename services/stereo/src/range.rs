//! Disparity to 3D in the optical camera frame of the rectified left camera (x right, y down,
//! z forward): `Z = f B / d`, `X = (u - cx) Z / f`, `Y = (v - cy) Z / f`.

use nalgebra::Vector3;

use crate::calib::RectifiedCamera;
use crate::disparity::DisparityMap;

/// 3D point for pixel (u, v) with disparity `d` pixels; `None` for d <= 0 (at infinity).
#[inline]
pub fn point(cam: &RectifiedCamera, u: f64, v: f64, d: f64) -> Option<Vector3<f64>> {
    if d.is_nan() || d <= 0.0 {
        return None;
    }
    let z = cam.f * cam.baseline / d;
    Some(Vector3::new(
        (u - cam.cx) * z / cam.f,
        (v - cam.cy) * z / cam.f,
        z,
    ))
}

/// Range standard deviation for a disparity standard deviation: `Z^2 sigma_d / (f B)`.
pub fn range_sigma(cam: &RectifiedCamera, z: f64, sigma_d: f64) -> f64 {
    z * z * sigma_d / (cam.f * cam.baseline)
}

/// Points of the valid pixels in rows `rows` (every `step`-th pixel both ways) closer than
/// `max_range`, appended to `out` (cleared first; its capacity is reused).
pub fn collect_points(
    cam: &RectifiedCamera,
    disp: &DisparityMap,
    rows: std::ops::Range<usize>,
    step: usize,
    max_range: f64,
    out: &mut Vec<Vector3<f32>>,
) {
    out.clear();
    let step = step.max(1);
    for v in rows.filter(|v| v % step == 0 && *v < disp.height) {
        for u in (0..disp.width).step_by(step) {
            if let Some(p) = disp
                .get(u, v)
                .and_then(|d| point(cam, u as f64, v as f64, d as f64))
            {
                if p.z <= max_range {
                    out.push(p.cast());
                }
            }
        }
    }
}
