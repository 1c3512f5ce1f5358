//! Synthetic frames with known geometry: flat textured ground, sky above the horizon, a puddle that
//! reflects the sky (and, in part, a tree), and a speck of sky colour.
#![allow(dead_code)]

use messages::{CameraModel, Pose};
use water::{Frame, Image};

pub const W: usize = 512;
pub const H: usize = 384;
pub const GROUND: f64 = 1.5;

pub struct Scene {
    pub rgb: Vec<u8>,
    pub disparity: Vec<f32>,
    /// True puddle pixels.
    pub puddle: Vec<bool>,
    pub speck: usize,
    pub camera: CameraModel,
    pub vehicle: Pose,
    pub puddle_center: [f64; 2],
}

fn hash(u: usize, v: usize) -> u32 {
    let mut x = (u as u32).wrapping_mul(0x9E37_79B1) ^ (v as u32).wrapping_mul(0x85EB_CA77);
    x ^= x >> 15;
    x = x.wrapping_mul(0x2C1B_3C6D);
    x ^= x >> 12;
    x
}

pub fn scene() -> Scene {
    let camera = CameraModel {
        fx: 443.0,
        fy: 443.0,
        cx: 255.5,
        cy: 191.5,
        baseline_m: 0.5,
        mount: Pose {
            position: [0.5, 0.0, 2.0],
            pitch: 10f64.to_radians(),
            ..Pose::default()
        },
    };
    let yaw: f64 = 0.3;
    let vehicle = Pose {
        position: [3.0, -2.0, GROUND],
        yaw,
        ..Pose::default()
    };
    // A puddle 12 m ahead, 2 m in radius; a speck 8 m ahead and 2.5 m to the left.
    let ahead = |d: f64, left: f64| {
        [
            3.0 + d * yaw.cos() - left * yaw.sin(),
            -2.0 + d * yaw.sin() + left * yaw.cos(),
        ]
    };
    let pc = ahead(12.0, 0.0);
    let sc = ahead(8.0, 2.5);
    let geo = water::geometry::FrameGeometry::new(&camera, &vehicle);
    let mut rgb = vec![0u8; 3 * W * H];
    let mut disparity = vec![f32::NAN; W * H];
    let mut puddle = vec![false; W * H];
    let mut speck = 0;
    for v in 0..H {
        for u in 0..W {
            let i = v * W + u;
            let n = hash(u, v);
            let px: [u8; 3] = match geo.intersect_plane(u as f64, v as f64, GROUND) {
                None => {
                    // Sky: a smooth gradient, no disparity.
                    let t = (v as f32 / 150.0).min(1.0);
                    let c = [150.0 + 20.0 * t, 175.0 + 10.0 * t, 215.0 + 5.0 * t];
                    c.map(|x| x as u8)
                }
                Some(p) => {
                    let ray = geo.ray(u as f64, v as f64);
                    let depth = (p[0] - geo.origin[0]) / ray[0];
                    let in_puddle = (p[0] - pc[0]).hypot(p[1] - pc[1]) < 2.0;
                    let in_speck = (p[0] - sc[0]).abs() < 0.05 && (p[1] - sc[1]).abs() < 0.05;
                    if in_puddle {
                        puddle[i] = true;
                        if (p[1] - pc[1]) * yaw.cos() - (p[0] - pc[0]) * yaw.sin() > 1.0 {
                            // Left part reflects a tree trunk 22 m away: its mirror image is a
                            // vertical line of range points below the ground, textured dark green.
                            let t = 22.0 / ray[0].hypot(ray[1]);
                            disparity[i] = (camera.fx * camera.baseline_m / t) as f32;
                            let g = (n % 40) as u8;
                            [30 + g / 2, 60 + g, 25 + g / 3]
                        } else {
                            // Sky reflection: dimmer sky colour, featureless, no disparity.
                            [112 + (n % 2) as u8, 127, 152]
                        }
                    } else if in_speck {
                        speck += 1;
                        [112, 127, 152]
                    } else {
                        disparity[i] = (camera.fx * camera.baseline_m / depth) as f32;
                        let g = (n % 60) as u8;
                        [95 + g, 75 + g, 50 + g / 2]
                    }
                }
            };
            rgb[3 * i..3 * i + 3].copy_from_slice(&px);
        }
    }
    Scene {
        rgb,
        disparity,
        puddle,
        speck,
        camera,
        vehicle,
        puddle_center: pc,
    }
}

pub fn frame(s: &Scene) -> Frame<'_> {
    Frame {
        width: W,
        height: H,
        image: Image::Rgb8(&s.rgb),
        disparity: &s.disparity,
        camera: &s.camera,
        vehicle: &s.vehicle,
    }
}
