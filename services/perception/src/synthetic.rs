//! Ray-cast disparity of a flat sea with vertical cylinders (buoys, posts), for tests and the
//! benchmark. The camera's axes are derived here independently of [`crate::geometry`] (explicit
//! trigonometry for a camera pitched down over a level plane), so tests that project its output
//! check the projection rather than repeat it.

use messages::{CameraModel, DisparityHeader, Header, Name, Pose, WaterPlane};

/// A vertical cylinder standing on the water (ENU metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    pub east: f64,
    pub north: f64,
    pub radius: f64,
    pub height: f64,
}

/// A pinhole camera `camera_height_m` above a flat sea, pitched down by `pitch_rad`, looking along
/// `heading_rad` (ENU, 0 = east), from the vessel at `position` (the camera is at the vessel's
/// position; its mount has no lever arm and no yaw).
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub width: u32,
    pub height: u32,
    pub focal_px: f64,
    pub baseline_m: f64,
    pub camera_height_m: f64,
    pub pitch_rad: f64,
    pub heading_rad: f64,
    pub position: [f64; 2],
    /// Water farther than this gives no disparity (as a matcher loses it near the horizon).
    pub max_water_range_m: f64,
    /// Peak amplitude of deterministic disparity noise (px); 0 for exact values.
    pub noise_px: f32,
    pub objects: Vec<Cylinder>,
}

impl Scene {
    /// A Hammerhead-like head at `width` x `height` with a 60 degree field of view, 3 m above the sea.
    pub fn hammerhead(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            focal_px: (width as f64 / 2.0) / 30f64.to_radians().tan(),
            baseline_m: 1.0,
            camera_height_m: 3.0,
            pitch_rad: 4f64.to_radians(),
            heading_rad: 90f64.to_radians(),
            position: [0.0, 0.0],
            max_water_range_m: 120.0,
            noise_px: 0.0,
            objects: Vec::new(),
        }
    }

    /// Twelve buoys 15-92 m ahead (every 7 m, bearings within 23 deg, 1-2.5 m high) with
    /// matcher-like noise (0.3 px): the hazard benchmark's scene.
    pub fn buoy_row(width: u32, height: u32) -> Self {
        let mut s = Self::hammerhead(width, height);
        s.noise_px = 0.3;
        for k in 0..12 {
            let range = 15.0 + 7.0 * k as f64;
            let bearing = (k as f64 * 0.7).sin() * 0.4;
            s.objects.push(Cylinder {
                east: range * (90f64.to_radians() + bearing).cos(),
                north: range * (90f64.to_radians() + bearing).sin(),
                radius: 0.5 + 0.1 * (k % 3) as f64,
                height: 1.0 + 0.5 * (k % 4) as f64,
            });
        }
        s
    }

    fn cx(&self) -> f64 {
        (self.width as f64 - 1.0) / 2.0
    }

    fn cy(&self) -> f64 {
        (self.height as f64 - 1.0) / 2.0
    }

    /// The header the stereo service would publish for this view (plane found, stabilized pose).
    pub fn header(&self, stamp_ns: u64, head: &str) -> DisparityHeader {
        let (s, c) = self.pitch_rad.sin_cos();
        DisparityHeader {
            hdr: Header::new(0, stamp_ns, "synthetic"),
            frame_seq: 0,
            head: Name::new(head),
            width: self.width,
            height: self.height,
            num_disparities: 128,
            camera: CameraModel {
                fx: self.focal_px,
                fy: self.focal_px,
                cx: self.cx(),
                cy: self.cy(),
                baseline_m: self.baseline_m,
                mount: Pose::default(),
            },
            plane: WaterPlane {
                valid: 1,
                inliers: 1000,
                normal: [0.0, -c, -s],
                offset: self.camera_height_m,
                camera_height_m: self.camera_height_m,
                roll: 0.0,
                pitch: self.pitch_rad,
            },
            stabilized_pose: Pose {
                position: [self.position[0], self.position[1], 0.0],
                roll: 0.0,
                pitch: self.pitch_rad,
                yaw: self.heading_rad,
            },
        }
    }

    /// Disparity image (px, NaN where nothing is hit), `width * height` values into `out`.
    pub fn render(&self, out: &mut Vec<f32>) {
        let (w, h) = (self.width as usize, self.height as usize);
        out.clear();
        out.resize(w * h, f32::NAN);
        let (sp, cp) = self.pitch_rad.sin_cos();
        let (sy, cy_) = self.heading_rad.sin_cos();
        let fb = self.focal_px * self.baseline_m;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for v in 0..h {
            for u in 0..w {
                let x = (u as f64 - self.cx()) / self.focal_px;
                let y = (v as f64 - self.cy()) / self.focal_px;
                // Ray in the levelled camera frame (forward, left, up) for optical (x, y, 1):
                // x right = -left, y down = (-sin p, 0, -cos p), z forward = (cos p, 0, -sin p).
                let fwd = cp - y * sp;
                let left = -x;
                let up = -sp - y * cp;
                // Heading turns (forward, left) into (east, north).
                let de = cy_ * fwd - sy * left;
                let dn = sy * fwd + cy_ * left;
                // `t` is the optical depth of the hit because the ray's optical z component is 1.
                let mut best = f64::INFINITY;
                if up < -1e-9 {
                    let t = self.camera_height_m / -up;
                    if t * (fwd * fwd + left * left).sqrt() <= self.max_water_range_m {
                        best = t;
                    }
                }
                for o in &self.objects {
                    if let Some(t) = hit_cylinder(self, o, de, dn, up) {
                        best = best.min(t);
                    }
                }
                if best.is_finite() {
                    let mut d = (fb / best) as f32;
                    if self.noise_px > 0.0 {
                        state = state
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        let r = ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0;
                        d += r * self.noise_px;
                    }
                    out[v * w + u] = d;
                }
            }
        }
    }
}

/// Smallest positive `t` where the ray `camera + t (de, dn, up)` meets the cylinder's side.
fn hit_cylinder(s: &Scene, o: &Cylinder, de: f64, dn: f64, up: f64) -> Option<f64> {
    let (px, py) = (s.position[0] - o.east, s.position[1] - o.north);
    let a = de * de + dn * dn;
    let b = 2.0 * (px * de + py * dn);
    let c = px * px + py * py - o.radius * o.radius;
    let disc = b * b - 4.0 * a * c;
    if a < 1e-12 || disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / (2.0 * a);
    let z = s.camera_height_m + t * up;
    (t > 0.0 && (0.0..=o.height).contains(&z)).then_some(t)
}
