//! The simulator's toed (Hammerhead) heads through the stereo service's own library: the rectified
//! view the simulator renders truth in is the one the service computes from `sim calib`'s file, the
//! rectified pair is row-aligned, and range and body position of a pylon come out right through
//! the published camera model and mount.

use nalgebra::{Rotation3, Vector3};
use sim::{Label, Scenario, Simulator, StereoHead};
use stereo::calib::{Calibration, Rectifier};
use stereo::disparity::MatcherConfig;
use stereo::pipeline::{rectified_mount, FramePipeline, PlaneSearch};
use stereo::GrayImage;

/// Calm open water, a Hammerhead-like left-facing pair (toe 20 deg, bar pitched 4 deg, barrel
/// distortion) at 640x480, pylons ahead-left at ~20 m and ~40 m.
const TOED: &str = r#"
name = "toed"
seed = 9
duration = 10.0
kind = "maritime"

[vessel]
position = [0.0, 0.0]
yaw_deg = 90.0

[environment]
wave_height = 0.05

[[heads]]
name = "hh_left"
width = 640
height = 480
hfov_deg = 60.0
baseline = 1.0
encoding = "mono8"
mount_xyz = [0.5, 0.1, 3.0]
mount_rpy_deg = [0.0, 4.0, 0.0]
pixel_noise = 1.0
toe_deg = 20.0
k1 = -0.05
k2 = 0.01

[[objects]]
kind = "pylon"
id = "near"
position = [-6.0, 20.0]
radius = 1.5
height = 10.0

[[objects]]
kind = "pylon"
id = "far"
position = [-16.0, 40.0]
radius = 1.5
height = 10.0
"#;

fn toed_world() -> sim::World {
    Scenario::parse(TOED, "toed").unwrap().build().unwrap()
}

fn stereo_calibration(head: &StereoHead) -> Calibration {
    Calibration::from_toml(&head.calibration().to_toml()).unwrap()
}

/// The real left camera's mount as `sim calib` prints it for the stereo service's config.
fn raw_mount(head: &StereoHead) -> messages::Pose {
    let (pos, rot) = head.left_camera_mount();
    let (roll, pitch, yaw) = rot.euler_angles();
    messages::Pose {
        position: pos.into(),
        roll,
        pitch,
        yaw,
    }
}

#[test]
fn simulator_and_stereo_service_agree_on_the_rectified_view() {
    let mut heads = StereoHead::maritime_defaults();
    let mut distorted = heads[0].clone();
    distorted.k1 = -0.08;
    distorted.k2 = 0.02;
    let mut ideal = heads[0].clone();
    ideal.toe = 0.0;
    ideal.oversize = 1.0;
    let mut small = heads[1].clone();
    small.width = 640;
    small.height = 480;
    heads.extend([distorted, ideal, small]);
    for head in &heads {
        let ours = head.rectified().unwrap();
        let rect = Rectifier::new(&stereo_calibration(head)).unwrap();
        let theirs = rect.camera();
        assert_eq!(
            (ours.width, ours.height),
            (theirs.width, theirs.height),
            "{}",
            head.name
        );
        for (a, b) in [
            (ours.f, theirs.f),
            (ours.cx, theirs.cx),
            (ours.cy, theirs.cy),
            (ours.baseline, theirs.baseline),
        ] {
            assert!((a - b).abs() < 1e-9, "{}: {a} vs {b}", head.name);
        }
        assert!((ours.rect_from_left - rect.rect_from_left()).abs().max() < 1e-12);
        // The mount the service publishes is the rectified camera the truth is rendered from.
        let published = rectified_mount(&raw_mount(head), &rect.rect_from_left());
        let (pos, rot) = head.rectified_mount(&ours);
        let theirs_rot =
            Rotation3::from_euler_angles(published.roll, published.pitch, published.yaw);
        assert!(
            (rot.matrix() - theirs_rot.matrix()).abs().max() < 1e-12,
            "{}",
            head.name
        );
        assert!((pos - Vector3::from(published.position)).norm() < 1e-12);
    }
}

/// Half side of the matching and corner windows: the pylons' texture is soft, so a wide window is
/// needed to pin rows as well as columns.
const WINDOW: usize = 10;

/// Sub-pixel (du, dv) at which `b` best matches the patch of `a` at (u, v) (side `2 WINDOW + 1`),
/// searching du in `du_range` and dv in -3..=3 (SSD, parabolas through the best offset and its
/// neighbours in each direction).
fn match_patch(
    a: &GrayImage,
    b: &GrayImage,
    (u, v): (usize, usize),
    du_range: std::ops::RangeInclusive<i64>,
) -> Option<(f64, f64)> {
    const R: i64 = WINDOW as i64;
    let ssd = |du: i64, dv: i64| -> Option<f64> {
        let mut s = 0.0;
        for y in -R..=R {
            for x in -R..=R {
                let (ua, va) = (u as i64 + x, v as i64 + y);
                let (ub, vb) = (ua + du, va + dv);
                if ub < 0 || vb < 0 || ub >= b.width as i64 || vb >= b.height as i64 {
                    return None;
                }
                let pa = a.data[va as usize * a.width + ua as usize] as f64;
                let pb = b.data[vb as usize * b.width + ub as usize] as f64;
                if pa == 0.0 || pb == 0.0 {
                    return None; // outside a raw view
                }
                s += (pa - pb) * (pa - pb);
            }
        }
        Some(s)
    };
    let mut best: Option<(f64, i64, i64)> = None;
    for du in du_range {
        for dv in -3..=3 {
            if let Some(s) = ssd(du, dv) {
                if best.is_none_or(|(b, _, _)| s < b) {
                    best = Some((s, du, dv));
                }
            }
        }
    }
    let (s0, du, dv) = best?;
    let (sm, sp) = (ssd(du, dv - 1)?, ssd(du, dv + 1)?);
    let denom = sm - 2.0 * s0 + sp;
    let frac = if denom > 0.0 {
        0.5 * (sm - sp) / denom
    } else {
        0.0
    };
    let (um, up) = (ssd(du - 1, dv)?, ssd(du + 1, dv)?);
    let denom_u = um - 2.0 * s0 + up;
    let frac_u = if denom_u > 0.0 {
        0.5 * (um - up) / denom_u
    } else {
        0.0
    };
    Some((du as f64 + frac_u, dv as f64 + frac))
}

/// The `count` most corner-like pixels of `img` with label `want` (largest smallest eigenvalue of the
/// windowed gradient structure tensor, so both rows and columns are pinned), on a 3-pixel grid, at
/// least `min_eig` (grey levels squared per pixel), with the whole window on the label, at one
/// depth (`truth` disparity) and inside the raw view.
fn corner_points(
    img: &GrayImage,
    labels: &[u8],
    truth: &[f32],
    want: Label,
    count: usize,
    min_eig: f64,
) -> Vec<(usize, usize)> {
    let px = |x: usize, y: usize| img.data[y * img.width + x] as f64;
    let mut found = Vec::new();
    for v in (WINDOW + 4..img.height - WINDOW - 4).step_by(3) {
        for u in (WINDOW + 4..img.width - WINDOW - 4).step_by(3) {
            if labels[v * img.width + u] != want as u8 {
                continue;
            }
            // Interior points only: silhouettes are aliased (one ray per pixel), and so are depth
            // steps; keep a margin of 3 pixels around the window.
            let m = WINDOW + 3;
            let centre = truth[v * img.width + u];
            let mixed = (v - m..=v + m).any(|y| {
                (u - m..=u + m).any(|x| {
                    let i = y * img.width + x;
                    px(x, y) == 0.0
                        || labels[i] != want as u8
                        || (truth[i] - centre).abs() > 0.05 * centre.abs() + 0.1
                })
            });
            if mixed {
                continue;
            }
            let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
            for y in v - WINDOW..=v + WINDOW {
                for x in u - WINDOW..=u + WINDOW {
                    let gx = (px(x + 1, y) - px(x - 1, y)) / 2.0;
                    let gy = (px(x, y + 1) - px(x, y - 1)) / 2.0;
                    sxx += gx * gx;
                    syy += gy * gy;
                    sxy += gx * gy;
                }
            }
            let half = (sxx + syy) / 2.0;
            let eig = (half - (((sxx - syy) / 2.0).powi(2) + sxy * sxy).sqrt())
                / ((2 * WINDOW + 1) * (2 * WINDOW + 1)) as f64;
            if eig >= min_eig {
                found.push((eig, u, v));
            }
        }
    }
    found.sort_by(|a, b| b.0.total_cmp(&a.0).then((a.1, a.2).cmp(&(b.1, b.2))));
    found
        .into_iter()
        .take(count)
        .map(|(_, u, v)| (u, v))
        .collect()
}

#[test]
fn toed_pair_rectifies_row_aligned_and_ranges_pylons() {
    let mut sim = Simulator::new(toed_world());
    let head = sim.world.heads[0].clone();
    let calib = stereo_calibration(&head);
    let view = head.rectified().unwrap();
    let rect = Rectifier::new(&calib).unwrap();
    let cam = rect.camera();
    let (w, h) = (cam.width, cam.height);
    assert_eq!((w, h), (768, 576));

    let n = head.image_len();
    let (mut left, mut right) = (vec![0u8; n], vec![0u8; n]);
    sim.render_head(0, &mut left, &mut right).unwrap();
    let rl = rect
        .rectify_left(stereo::GrayView::new(640, 480, &left).unwrap())
        .unwrap();
    let rr = rect
        .rectify_right(stereo::GrayView::new(640, 480, &right).unwrap())
        .unwrap();

    // Truth in the rectified view, and the view itself rendered directly by the simulator.
    let (mut truth_d, mut labels) = (vec![0f32; w * h], vec![0u8; w * h]);
    sim.render_truth_view(0, &view, &mut truth_d, &mut labels)
        .unwrap();
    let virtual_cam = head.rectified_camera(&view, &sim.state().pose);
    let mut direct = GrayImage::new(w, h);
    sim.render_camera(0, &virtual_cam, &mut direct.data)
        .unwrap();

    // 1. The simulator's rectified view is the stereo service's rectified left image, pixel for
    //    pixel: textured points match with no offset in either direction.
    let pylon_points = corner_points(&rl, &labels, &truth_d, Label::Pylon, 40, 1.0);
    assert!(
        pylon_points.len() >= 20,
        "{} textured pylon points",
        pylon_points.len()
    );
    let (mut worst_u, mut worst_v) = (0f64, 0f64);
    for &(u, v) in &pylon_points {
        let (du, dv) = match_patch(&rl, &direct, (u, v), -3..=3).unwrap();
        worst_u = worst_u.max(du.abs());
        worst_v = worst_v.max(dv.abs());
    }
    println!(
        "truth view vs rectified left over {} points: worst offset {worst_u:.3} px (columns), {worst_v:.3} px (rows)",
        pylon_points.len()
    );
    assert!(worst_u < 0.5 && worst_v < 0.5, "{worst_u} {worst_v}");

    // 2. Epipolar alignment: each textured point of the near pylon (nothing occludes it in the
    //    right image) is found in the rectified right image on the same row (within 0.5 px), at
    //    the true disparity.
    let fb = cam.f * cam.baseline;
    let near: Vec<_> = corner_points(&rl, &labels, &truth_d, Label::Pylon, 400, 1.0)
        .into_iter()
        .filter(|&(u, v)| fb / (truth_d[v * w + u] as f64) < 30.0)
        .take(30)
        .collect();
    assert!(
        near.len() >= 10,
        "{} textured points on the near pylon",
        near.len()
    );
    let (mut worst_dv, mut worst_dd) = (0f64, 0f64);
    for &(u, v) in &near {
        let d = truth_d[v * w + u] as f64;
        let di = d.round() as i64;
        let (du, dv) = match_patch(&rl, &rr, (u, v), -di - 2..=-di + 2).unwrap();
        worst_dv = worst_dv.max(dv.abs());
        worst_dd = worst_dd.max((-du - d).abs());
    }
    println!(
        "rectified pair over {} points: worst row offset {worst_dv:.3} px, worst disparity error {worst_dd:.3} px",
        near.len()
    );
    assert!(worst_dv < 0.5, "row offset {worst_dv}");
    assert!(worst_dd < 0.75, "disparity error {worst_dd}");

    // 3. Range: the service's pipeline on the raw pair, compared with the truth on pylon pixels.
    let matcher: MatcherConfig = toml::from_str("algo = \"bm\"\nnum_disparities = 128").unwrap();
    let mut pipeline = FramePipeline::new(&calib, &matcher, PlaneSearch::default()).unwrap();
    let rect_from_left = pipeline.rect_from_left();
    let result = pipeline.process(640, 480, &left, &right).unwrap();
    let disparity = result.disparity;
    assert_eq!((disparity.width, disparity.height), (w, h));
    const SIGMA_D: f64 = 0.25;
    // Part of the far pylon is hidden from the right camera by the near one: no disparity there.
    for (id, range, min_density) in [("near", 15.0..30.0, 0.8), ("far", 32.0..55.0, 0.35)] {
        let (mut errs, mut seen) = (Vec::new(), 0usize);
        for i in 0..w * h {
            let dt = truth_d[i] as f64;
            if labels[i] != Label::Pylon as u8 || dt <= 0.0 || !range.contains(&(fb / dt)) {
                continue;
            }
            seen += 1;
            if let Some(de) = disparity.get(i % w, i / w) {
                errs.push((fb / de as f64 - fb / dt, fb / dt));
            }
        }
        errs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (median, z) = errs[errs.len() / 2];
        let sigma = z * z * SIGMA_D / fb;
        let density = errs.len() as f64 / seen as f64;
        println!(
            "pylon {id}: Z {z:.1} m, median range error {median:.3} m, sigma_Z {sigma:.3} m, density {density:.2}"
        );
        assert!(density > min_density, "{id}: density {density}");
        assert!(
            median.abs() < 2.0 * sigma,
            "{id}: median error {median} m, sigma {sigma} m"
        );
    }

    // 4. Body position: a pylon pixel's disparity through `CameraModel::point` and the published
    //    (rectified) mount lands on the pylon's surface in the body frame.
    let mount = rectified_mount(&raw_mount(&head), &rect_from_left);
    let model = messages::CameraModel {
        fx: cam.f,
        fy: cam.f,
        cx: cam.cx,
        cy: cam.cy,
        baseline_m: cam.baseline,
        mount,
    };
    let body = sim.state().pose;
    let world_from_body = body.rotation();
    let near_axis = Vector3::new(-6.0, 20.0, 0.0);
    let b_opt = sim::math::bodylike_from_optical();
    let body_from_cam = Rotation3::from_euler_angles(mount.roll, mount.pitch, mount.yaw);
    let mut dists = Vec::new();
    for i in 0..w * h {
        let (u, v) = (i % w, i / w);
        let dt = truth_d[i] as f64;
        if labels[i] != Label::Pylon as u8 || dt <= 0.0 || fb / dt > 30.0 {
            continue; // not the near pylon
        }
        let Some(p) = disparity
            .get(u, v)
            .and_then(|d| model.point(u as f64, v as f64, d))
        else {
            continue;
        };
        let p_body = body_from_cam * (b_opt * Vector3::from(p)) + Vector3::from(mount.position);
        let p_world = body.position + world_from_body * p_body;
        // Horizontal distance from the pylon's axis is its radius, within the range noise.
        let r = (p_world - near_axis).xy().norm();
        dists.push((r - 1.5).abs() / (p[2] * p[2] * SIGMA_D / fb));
    }
    dists.sort_by(f64::total_cmp);
    let med = dists[dists.len() / 2];
    println!(
        "near pylon through the published mount: median |r - radius| {med:.2} sigma_Z over {} pixels",
        dists.len()
    );
    assert!(dists.len() >= 100 && med < 1.0, "median {med} sigma");
}
