//! Rectification of a synthetically rotated, distorted pair, and calibration file errors.

mod common;

use common::{render, Texture};
use nalgebra::{Matrix3, Rotation3, Vector3};
use stereo::bm::{BlockMatcher, BmParams};
use stereo::calib::{CalibError, Calibration, Intrinsics, Rectifier, RectifyError};
use stereo::{DisparityMap, DisparityMatcher, GrayImage};

const W: usize = 320;
const H: usize = 240;
const PLANE_Z: f64 = 4.0;
const BASELINE: f64 = 0.3;

fn rot(rx: f64, ry: f64, rz: f64) -> Matrix3<f64> {
    (Rotation3::from_euler_angles(rx.to_radians(), ry.to_radians(), rz.to_radians())).into_inner()
}

fn intrinsics() -> Intrinsics {
    Intrinsics {
        fx: 300.0,
        fy: 302.0,
        cx: 158.0,
        cy: 122.0,
        k1: -0.08,
        k2: 0.01,
        p1: 0.001,
        p2: -0.0005,
        k3: 0.0,
    }
}

/// Camera with rotation `world -> camera` and centre `c` looking at the textured plane Z = 4 m.
fn view(k: &Intrinsics, cam_from_world: &Matrix3<f64>, c: Vector3<f64>) -> GrayImage {
    let t = Texture::new(3);
    render(W, H, |u, v| {
        let (x, y) = k.undistort_pixel(u, v);
        let ray = cam_from_world.transpose() * Vector3::new(x, y, 1.0);
        let p = c + ray * ((PLANE_Z - c.z) / ray.z);
        t.at(p.x * 50.0, p.y * 50.0)
    })
}

fn calibration(a: &Matrix3<f64>, b: &Matrix3<f64>, oversize: f64) -> Calibration {
    let r = b * a.transpose();
    let t = -(b * Vector3::new(BASELINE, 0.0, 0.0));
    let rows = |m: &Matrix3<f64>| [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]);
    Calibration {
        width: W,
        height: H,
        left: intrinsics(),
        right: intrinsics(),
        rotation: rows(&r),
        translation: [t.x, t.y, t.z],
        oversize,
    }
}

/// Rectify, match, and compare with the disparity predicted from the known geometry.
fn check_pair(a: Matrix3<f64>, b: Matrix3<f64>, oversize: f64) -> (f64, f64) {
    let k = intrinsics();
    let left = view(&k, &a, Vector3::zeros());
    let right = view(&k, &b, Vector3::new(BASELINE, 0.0, 0.0));
    let calib = calibration(&a, &b, oversize);
    let rect = Rectifier::new(&calib).unwrap();
    let cam = rect.camera();
    let (rl, rr) = (
        rect.rectify_left(left.view()).unwrap(),
        rect.rectify_right(right.view()).unwrap(),
    );
    let params = BmParams {
        num_disparities: 48,
        ..Default::default()
    };
    let mut m = BlockMatcher::new(params, cam.width, cam.height).unwrap();
    let mut d = DisparityMap::new(cam.width, cam.height);
    m.compute(rl.view(), rr.view(), &mut d).unwrap();
    // Expected: ray of the rectified left pixel hits the plane; d = f B / Z_rect.
    let world_from_rect = a.transpose() * rect.rect_from_left().transpose();
    let (mut errs, mut inside) = (Vec::new(), 0);
    for v in 0..cam.height {
        for u in 0..cam.width {
            if rl.data[v * cam.width + u] == 0 {
                continue;
            }
            inside += 1;
            let Some(got) = d.get(u, v) else { continue };
            let ray = world_from_rect
                * Vector3::new(
                    (u as f64 - cam.cx) / cam.f,
                    (v as f64 - cam.cy) / cam.f,
                    1.0,
                );
            let p = ray * (PLANE_Z / ray.z);
            let z_rect = (rect.rect_from_left() * a * p).z;
            errs.push((got as f64 - cam.f * cam.baseline / z_rect).abs());
        }
    }
    errs.sort_by(f64::total_cmp);
    (errs[errs.len() / 2], errs.len() as f64 / inside as f64)
}

#[test]
fn rectification_restores_row_alignment() {
    // Both cameras rotated differently by a few degrees, with lens distortion.
    let (median, density) = check_pair(rot(2.0, -1.5, 1.0), rot(-1.0, 2.0, -2.0), 1.0);
    println!("rotated pair: median error {median:.3} px, density {density:.3}");
    assert!(
        median < 0.2 && density > 0.6,
        "median {median} density {density}"
    );
}

#[test]
fn heads_yawed_on_a_common_baseline_are_rectified() {
    // Hammerhead-like: both cameras yawed 20 degrees on the same bar, oversized view.
    let (median, density) = check_pair(rot(0.5, 20.0, 0.0), rot(0.0, 20.5, 0.3), 1.2);
    println!("yawed pair: median error {median:.3} px, density {density:.3}");
    assert!(
        median < 0.2 && density > 0.5,
        "median {median} density {density}"
    );
}

#[test]
fn unrectified_rotated_pair_does_not_match() {
    // Control for the test above: the same pair without rectification matches badly.
    let (a, b) = (rot(2.0, -1.5, 1.0), rot(-1.0, 2.0, -2.0));
    let k = intrinsics();
    let left = view(&k, &a, Vector3::zeros());
    let right = view(&k, &b, Vector3::new(BASELINE, 0.0, 0.0));
    let p = BmParams {
        num_disparities: 48,
        ..Default::default()
    };
    let mut m = BlockMatcher::new(p, W, H).unwrap();
    let mut d = DisparityMap::new(W, H);
    m.compute(left.view(), right.view(), &mut d).unwrap();
    assert!(d.density() < 0.3, "density {}", d.density());
}

#[test]
fn mis_sized_frame_is_a_rectify_error() {
    let calib = calibration(&rot(0.0, 0.0, 0.0), &rot(0.0, 1.0, 0.0), 1.0);
    let rect = Rectifier::new(&calib).unwrap();
    let e = rect
        .rectify_left(GrayImage::new(W + 2, H).view())
        .unwrap_err();
    assert_eq!(
        e,
        RectifyError::SizeMismatch {
            which: "left",
            want_w: W,
            want_h: H,
            got_w: W + 2,
            got_h: H
        }
    );
}

const GOOD: &str = r#"
width = 1280
height = 960
rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
translation = [-1.0, 0.0, 0.0]
oversize = 1.2
[left]
fx = 1000.0
fy = 1000.0
cx = 640.0
cy = 480.0
k1 = -0.1
[right]
fx = 1000.0
fy = 1000.0
cx = 640.0
cy = 480.0
"#;

#[test]
fn calibration_file_errors_name_the_field() {
    let c = Calibration::from_toml(GOOD).unwrap();
    assert_eq!(c.left.k1, -0.1);
    let rect = Rectifier::new(&c).unwrap();
    assert_eq!((rect.camera().width, rect.camera().height), (1536, 1152));

    let e = Calibration::from_toml(&GOOD.replace("k1 = -0.1", "k9 = -0.1")).unwrap_err();
    assert!(
        matches!(e, CalibError::Parse(_)) && e.to_string().contains("k9"),
        "{e}"
    );
    let e = Calibration::from_toml(&GOOD.replace("cy = 480.0\nk1", "k1")).unwrap_err();
    assert!(e.to_string().contains("cy"), "{e}");
    let e = Calibration::from_toml(&GOOD.replacen("fx = 1000.0", "fx = -5.0", 1)).unwrap_err();
    assert!(e.to_string().contains("left.fx"), "{e}");
    let e =
        Calibration::from_toml(&GOOD.replace("[0.0, 1.0, 0.0]", "[0.0, 2.0, 0.0]")).unwrap_err();
    assert!(e.to_string().contains("rotation"), "{e}");
    let e =
        Calibration::from_toml(&GOOD.replace("[-1.0, 0.0, 0.0]", "[0.0, 0.0, 0.0]")).unwrap_err();
    assert!(e.to_string().contains("translation"), "{e}");
}
