//! Camera geometry for one frame: the left camera's pose in the world (ENU), pixel rays, the horizon
//! line and back-projection of disparity to world points.

use messages::{CameraModel, Pose};
use nalgebra::{Matrix3, Rotation3, Vector3};

/// `bodylike_from_optical`: optical x right / y down / z forward into body-like x forward / y left /
/// z up (columns are the optical axes written in body axes).
fn bodylike_from_optical() -> Matrix3<f64> {
    Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0)
}

fn rotation(p: &Pose) -> Rotation3<f64> {
    Rotation3::from_euler_angles(p.roll, p.pitch, p.yaw)
}

/// The left camera of a frame placed in the world.
#[derive(Clone, Copy, Debug)]
pub struct FrameGeometry {
    /// `world_from_optical`, row-major.
    pub r: [[f64; 3]; 3],
    /// Optical centre in the world (ENU, m).
    pub origin: [f64; 3],
    /// Body (vehicle) position in the world; swaths and the map are centred here.
    pub vehicle: [f64; 3],
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub baseline: f64,
}

impl FrameGeometry {
    /// `vehicle` is the body pose in the world; `camera.mount` the left camera in the body.
    pub fn new(camera: &CameraModel, vehicle: &Pose) -> FrameGeometry {
        let rwb = rotation(vehicle);
        let rbm = rotation(&camera.mount);
        let pw = Vector3::from(vehicle.position);
        let origin = pw + rwb * Vector3::from(camera.mount.position);
        let m = rwb.matrix() * rbm.matrix() * bodylike_from_optical();
        let mut r = [[0.0; 3]; 3];
        for (i, row) in r.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = m[(i, j)];
            }
        }
        FrameGeometry {
            r,
            origin: origin.into(),
            vehicle: vehicle.position,
            fx: camera.fx,
            fy: camera.fy,
            cx: camera.cx,
            cy: camera.cy,
            baseline: camera.baseline_m,
        }
    }

    /// World direction of the ray through pixel (u, v), scaled so its optical-axis component is 1
    /// (a point at depth `z` is `origin + z * ray`).
    #[inline]
    pub fn ray(&self, u: f64, v: f64) -> [f64; 3] {
        let a = (u - self.cx) / self.fx;
        let b = (v - self.cy) / self.fy;
        let r = &self.r;
        [
            r[0][0] * a + r[0][1] * b + r[0][2],
            r[1][0] * a + r[1][1] * b + r[1][2],
            r[2][0] * a + r[2][1] * b + r[2][2],
        ]
    }

    /// Whether the camera is upright enough for a horizon line that crosses every column once
    /// (image "up" points to world up).
    pub fn upright(&self) -> bool {
        self.r[2][1] < -1e-3
    }

    /// Image row of the horizon in column `u` (rays below it point down). Only for upright cameras.
    #[inline]
    pub fn horizon_row(&self, u: f64) -> f64 {
        let r = &self.r[2];
        self.cy - self.fy * (r[2] + r[0] * (u - self.cx) / self.fx) / r[1]
    }

    /// Depth along the optical axis for a disparity (px).
    #[inline]
    pub fn depth(&self, disparity: f32) -> f64 {
        self.fx * self.baseline / disparity as f64
    }

    /// Where the ray through (u, v) meets the horizontal plane at `elevation`, if in front.
    pub fn intersect_plane(&self, u: f64, v: f64, elevation: f64) -> Option<[f64; 3]> {
        let d = self.ray(u, v);
        let t = (elevation - self.origin[2]) / d[2];
        (d[2] < -1e-9 && t > 0.0).then(|| {
            [
                self.origin[0] + t * d[0],
                self.origin[1] + t * d[1],
                elevation,
            ]
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(pitch_deg: f64) -> CameraModel {
        CameraModel {
            fx: 400.0,
            fy: 400.0,
            cx: 255.5,
            cy: 191.5,
            baseline_m: 0.5,
            mount: Pose {
                position: [0.5, 0.0, 2.0],
                pitch: pitch_deg.to_radians(),
                ..Pose::default()
            },
        }
    }

    #[test]
    fn level_camera_sees_horizon_at_principal_row_and_forward_is_east() {
        let g = FrameGeometry::new(&model(0.0), &Pose::default());
        assert!(g.upright());
        assert!((g.horizon_row(10.0) - 191.5).abs() < 1e-9);
        let d = g.ray(255.5, 191.5);
        assert!((d[0] - 1.0).abs() < 1e-12 && d[1].abs() < 1e-12 && d[2].abs() < 1e-12);
        // Pixel to the right of centre looks to the south (-y) in ENU for yaw 0.
        assert!(g.ray(400.0, 191.5)[1] < 0.0);
    }

    #[test]
    fn pitched_down_camera_moves_horizon_up_and_hits_ground() {
        // Positive pitch is nose down: the horizon moves up the image by f * tan(pitch).
        let g = FrameGeometry::new(&model(10.0), &Pose::default());
        let want = 191.5 - 400.0 * 10f64.to_radians().tan();
        assert!((g.horizon_row(255.5) - want).abs() < 1e-6);
        // The optical axis meets the ground at h / tan(pitch) ahead of the camera.
        let p = g.intersect_plane(255.5, 191.5, 0.0).unwrap();
        assert!((p[0] - (0.5 + 2.0 / 10f64.to_radians().tan())).abs() < 1e-6);
        assert!(g.intersect_plane(255.5, 10.0, 0.0).is_none());
    }

    #[test]
    fn yawed_vehicle_rotates_rays_and_mount() {
        let v = Pose {
            position: [10.0, 5.0, 1.0],
            yaw: std::f64::consts::FRAC_PI_2,
            ..Pose::default()
        };
        let g = FrameGeometry::new(&model(0.0), &v);
        assert!((g.origin[0] - 10.0).abs() < 1e-9 && (g.origin[1] - 5.5).abs() < 1e-9);
        assert!((g.origin[2] - 3.0).abs() < 1e-9);
        let d = g.ray(255.5, 191.5);
        assert!(d[0].abs() < 1e-9 && (d[1] - 1.0).abs() < 1e-9);
    }
}
