//! Matchers and rectification on synthetic scenes with known disparity.

mod common;

use common::{render, Texture, TEX_SCALE};
use stereo::bm::{BlockMatcher, BmParams};
use stereo::sgm::{SgmMatcher, SgmParams};
use stereo::{DisparityMap, DisparityMatcher, GrayImage, MatchError};

const W: usize = 240;
const H: usize = 160;

fn matchers(nd: usize) -> Vec<Box<dyn DisparityMatcher>> {
    let bm = BmParams {
        num_disparities: nd,
        ..Default::default()
    };
    let sgm = SgmParams {
        num_disparities: nd,
        ..Default::default()
    };
    vec![
        Box::new(BlockMatcher::new(bm, W, H).unwrap()),
        Box::new(SgmMatcher::new(sgm, W, H).unwrap()),
    ]
}

/// Pair whose left-image disparity is `disp(x)`; R(xr) = L(xl) with xl - disp(xl) = xr.
fn pair(disp_inv: impl Fn(f64) -> f64) -> (GrayImage, GrayImage) {
    let t = Texture::new(7);
    let left = render(W, H, |x, y| t.at(x * TEX_SCALE, y * TEX_SCALE));
    let right = render(W, H, |x, y| t.at(disp_inv(x) * TEX_SCALE, y * TEX_SCALE));
    (left, right)
}

/// Mean and 95th percentile of |error| over valid pixels, and density, inside a margin.
fn errors(d: &DisparityMap, truth: impl Fn(usize) -> f64, x0: usize) -> (f64, f64, f64) {
    let mut e = Vec::new();
    let mut n = 0;
    for y in 8..H - 8 {
        for x in x0..W - 8 {
            n += 1;
            if let Some(v) = d.get(x, y) {
                e.push((v as f64 - truth(x)).abs());
            }
        }
    }
    e.sort_by(f64::total_cmp);
    let mean = e.iter().sum::<f64>() / e.len().max(1) as f64;
    (mean, e[e.len() * 95 / 100], e.len() as f64 / n as f64)
}

#[test]
fn constant_subpixel_disparity_is_recovered() {
    let d0 = 9.3;
    let (l, r) = pair(|xr| xr + d0);
    for mut m in matchers(32) {
        let mut out = DisparityMap::new(W, H);
        m.compute(l.view(), r.view(), &mut out).unwrap();
        let (mean, p95, density) = errors(&out, |_| d0, 48);
        println!(
            "{}: mean {mean:.3} p95 {p95:.3} density {density:.3}",
            m.name()
        );
        assert!(density > 0.9, "{} density {density}", m.name());
        assert!(
            mean < 0.25 && p95 < 0.5,
            "{} mean {mean} p95 {p95}",
            m.name()
        );
    }
}

#[test]
fn planar_disparity_is_recovered() {
    // d(xl) = a + b xl  =>  xl = (xr + a) / (1 - b).
    let (a, b) = (4.0, 0.05);
    let (l, r) = pair(|xr| (xr + a) / (1.0 - b));
    for mut m in matchers(32) {
        let mut out = DisparityMap::new(W, H);
        m.compute(l.view(), r.view(), &mut out).unwrap();
        let (mean, p95, density) = errors(&out, |x| a + b * x as f64, 48);
        println!(
            "{}: mean {mean:.3} p95 {p95:.3} density {density:.3}",
            m.name()
        );
        assert!(density > 0.85, "{} density {density}", m.name());
        assert!(
            mean < 0.25 && p95 < 0.6,
            "{} mean {mean} p95 {p95}",
            m.name()
        );
    }
}

#[test]
fn left_right_check_invalidates_occlusions() {
    // Background at d = 4, a square at d = 16 over x in 80..150: left pixels in 68..80 see
    // background that the square hides in the right image.
    let (bg, fg) = (Texture::new(1), Texture::new(2));
    let inside = |x: f64, y: f64| (80.0..150.0).contains(&x) && (40.0..120.0).contains(&y);
    let left = render(W, H, |x, y| {
        if inside(x, y) {
            fg.at(x * TEX_SCALE, y * TEX_SCALE)
        } else {
            bg.at(x * TEX_SCALE, y * TEX_SCALE)
        }
    });
    let right = render(W, H, |x, y| {
        if inside(x + 16.0, y) {
            fg.at((x + 16.0) * TEX_SCALE, y * TEX_SCALE)
        } else {
            bg.at((x + 4.0) * TEX_SCALE, y * TEX_SCALE)
        }
    });
    let occluded_valid = |lr: i32, sgm: bool| {
        let mut m: Box<dyn DisparityMatcher> = if sgm {
            let p = SgmParams {
                num_disparities: 32,
                lr_max_diff: lr,
                uniqueness_ratio: 0,
                ..Default::default()
            };
            Box::new(SgmMatcher::new(p, W, H).unwrap())
        } else {
            let p = BmParams {
                num_disparities: 32,
                lr_max_diff: lr,
                uniqueness_ratio: 0,
                multiscale_max_diff: -1.0,
                ..Default::default()
            };
            Box::new(BlockMatcher::new(p, W, H).unwrap())
        };
        let mut out = DisparityMap::new(W, H);
        m.compute(left.view(), right.view(), &mut out).unwrap();
        let (mut n, mut valid) = (0, 0);
        for y in 50..110 {
            for x in 70..79 {
                n += 1;
                valid += out.get(x, y).is_some() as usize;
            }
        }
        valid as f64 / n as f64
    };
    for sgm in [false, true] {
        let (on, off) = (occluded_valid(1, sgm), occluded_valid(-1, sgm));
        println!("sgm {sgm}: occluded band valid {on:.3} with LR check, {off:.3} without");
        assert!(on < 0.15, "sgm {sgm}: {on}");
        assert!(off > on + 0.4, "sgm {sgm}: {off} vs {on}");
    }
}

#[test]
fn mis_sized_frame_is_an_error() {
    for mut m in matchers(32) {
        let ok = GrayImage::new(W, H);
        let bad = GrayImage::new(W, H + 1);
        let mut out = DisparityMap::new(W, H);
        let e = m.compute(ok.view(), bad.view(), &mut out).unwrap_err();
        assert!(
            matches!(e, MatchError::SizeMismatch { which: "right", .. }),
            "{e}"
        );
        let e = m
            .compute(bad.view(), ok.view(), &mut out)
            .unwrap_err()
            .to_string();
        assert!(e.contains("left") && e.contains("240x161"), "{e}");
    }
}

#[test]
fn output_is_deterministic_across_thread_counts() {
    let (l, r) = pair(|xr| (xr + 4.0) / 0.95);
    for mut m in matchers(32) {
        let mut a = DisparityMap::new(W, H);
        let mut b = DisparityMap::new(W, H);
        m.compute(l.view(), r.view(), &mut a).unwrap();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        pool.install(|| m.compute(l.view(), r.view(), &mut b))
            .unwrap();
        assert!(a == b, "{}", m.name());
    }
}

#[test]
fn bad_params_are_rejected() {
    let p = BmParams {
        num_disparities: 20,
        ..Default::default()
    };
    assert!(matches!(
        BlockMatcher::new(p, W, H),
        Err(MatchError::InvalidParams(_))
    ));
    let p = SgmParams {
        p1: 50,
        p2: 40,
        ..Default::default()
    };
    assert!(matches!(
        SgmMatcher::new(p, W, H),
        Err(MatchError::InvalidParams(_))
    ));
}
