//! From the left camera's optical frame (x right, y down, z forward) to the local ENU world with z
//! measured from the water plane, as Hammerhead projects range: roll and pitch from the water plane
//! fitted in this frame, heading and position from the INS.
//!
//! What the stereo service puts in `DisparityHeader::stabilized_pose` today is the INS pose of the
//! vessel body (position, heading) with roll and pitch replaced by the camera's attitude relative to
//! the water plane when the plane was found. The camera's mount (`CameraModel::mount`, body frame) is
//! therefore added here: camera heading = vessel heading + mount yaw, camera position = vessel
//! position + the mount lever arm turned by the heading.
//!
//! When the plane fit failed (`plane.valid == 0`) the stabilized pose carries the INS attitude
//! unchanged, and the transform falls back to it: body attitude x mount x optical axes, heights from
//! the INS altitude of the body origin (the water surface is z = 0).

use messages::{DisparityHeader, Pose};
use nalgebra::{Matrix3, Rotation3, Vector3};

/// Which attitude levelled the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AttitudeSource {
    WaterPlane,
    Ins,
}

/// Why a disparity header cannot be projected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    #[error("camera model invalid: {0}")]
    Camera(&'static str),
    #[error("water plane invalid: {0}")]
    Plane(&'static str),
    #[error("stabilized pose is not finite")]
    Pose,
}

/// `world_from_optical`: a rotation and the camera origin (east, north, height above water).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraToWorld {
    pub rot: [[f32; 3]; 3],
    pub origin: [f32; 3],
    pub source: AttitudeSource,
}

/// Rotation taking optical vectors (x right, y down, z forward) into body-like axes (x forward,
/// y left, z up).
fn bodylike_from_optical() -> Matrix3<f64> {
    Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0)
}

fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn pose_finite(p: &Pose) -> bool {
    finite(&p.position) && finite(&[p.roll, p.pitch, p.yaw])
}

/// Checks the pinhole model of a disparity header.
pub fn validate_camera(h: &DisparityHeader) -> Result<(), GeometryError> {
    let c = &h.camera;
    if !(c.fx.is_finite() && c.fx > 0.0 && c.fy.is_finite() && c.fy > 0.0) {
        return Err(GeometryError::Camera("focal length must be finite and > 0"));
    }
    if !(c.baseline_m.is_finite() && c.baseline_m > 0.0) {
        return Err(GeometryError::Camera("baseline must be finite and > 0"));
    }
    if !(c.cx.is_finite() && c.cy.is_finite()) {
        return Err(GeometryError::Camera("principal point is not finite"));
    }
    if !pose_finite(&c.mount) {
        return Err(GeometryError::Camera("mount pose is not finite"));
    }
    Ok(())
}

impl CameraToWorld {
    /// The transform of one disparity frame; see the module docs for the conventions.
    pub fn from_header(h: &DisparityHeader) -> Result<Self, GeometryError> {
        validate_camera(h)?;
        let pose = &h.stabilized_pose;
        if !pose_finite(pose) {
            return Err(GeometryError::Pose);
        }
        let mount = &h.camera.mount;
        if h.plane.valid == 1 {
            Self::from_plane(h)
        } else {
            let body = Rotation3::from_euler_angles(pose.roll, pose.pitch, pose.yaw);
            let mount_rot = Rotation3::from_euler_angles(mount.roll, mount.pitch, mount.yaw);
            let rot = body.matrix() * mount_rot.matrix() * bodylike_from_optical();
            let origin = Vector3::from(pose.position) + body * Vector3::from(mount.position);
            Ok(Self::new(rot, origin, AttitudeSource::Ins))
        }
    }

    fn from_plane(h: &DisparityHeader) -> Result<Self, GeometryError> {
        let p = &h.plane;
        let n = Vector3::from(p.normal);
        if !finite(&p.normal) || (n.norm() - 1.0).abs() > 0.01 {
            return Err(GeometryError::Plane("normal is not a unit vector"));
        }
        if !(p.offset.is_finite() && p.offset > 0.0) {
            return Err(GeometryError::Plane("camera is not above the plane"));
        }
        // Forward = the optical axis levelled onto the plane; left = up x forward.
        let axis = Vector3::z();
        let fwd = axis - n * axis.dot(&n);
        if fwd.norm() < 0.05 {
            return Err(GeometryError::Plane("camera looks along the plane normal"));
        }
        let fwd = fwd.normalize();
        let left = n.cross(&fwd);
        let level = Matrix3::from_rows(&[fwd.transpose(), left.transpose(), n.transpose()]);
        let pose = &h.stabilized_pose;
        let mount = &h.camera.mount;
        let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), pose.yaw + mount.yaw);
        let rot = heading.matrix() * level;
        let lever = Rotation3::from_axis_angle(&Vector3::z_axis(), pose.yaw)
            * Vector3::new(mount.position[0], mount.position[1], 0.0);
        let origin = Vector3::new(
            pose.position[0] + lever.x,
            pose.position[1] + lever.y,
            p.offset,
        );
        Ok(Self::new(rot, origin, AttitudeSource::WaterPlane))
    }

    fn new(rot: Matrix3<f64>, origin: Vector3<f64>, source: AttitudeSource) -> Self {
        let mut r = [[0f32; 3]; 3];
        for (i, row) in r.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = rot[(i, j)] as f32;
            }
        }
        Self {
            rot: r,
            origin: [origin.x as f32, origin.y as f32, origin.z as f32],
            source,
        }
    }

    /// A point of the optical frame in ENU, z = height above the water plane.
    #[inline(always)]
    pub fn apply(&self, p: [f32; 3]) -> [f32; 3] {
        let r = &self.rot;
        [
            r[0][0] * p[0] + r[0][1] * p[1] + r[0][2] * p[2] + self.origin[0],
            r[1][0] * p[0] + r[1][1] * p[1] + r[1][2] * p[2] + self.origin[1],
            r[2][0] * p[0] + r[2][1] * p[1] + r[2][2] * p[2] + self.origin[2],
        ]
    }
}
