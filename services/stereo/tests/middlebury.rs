//! Accuracy on the Middlebury 2014 Motorcycle pair (741x500, see testdata/README.md).
//! Thresholds are the measured figures plus a margin, so a regression fails.

use std::path::PathBuf;

use stereo::bm::{BlockMatcher, BmParams};
use stereo::eval::{evaluate, Metrics};
use stereo::sgm::{SgmMatcher, SgmParams};
use stereo::{DisparityMap, DisparityMatcher, GrayImage};

const NDISP: usize = 96;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("testdata")
        .join(name)
}

fn gray(name: &str) -> GrayImage {
    let img = image::open(data(name)).unwrap().to_luma8();
    let (w, h) = img.dimensions();
    GrayImage::from_vec(w as usize, h as usize, img.into_raw()).unwrap()
}

fn ground_truth() -> (Vec<f32>, Vec<u64>) {
    let mut npz = npyz::npz::NpzArchive::open(data("motorcycle_disp.npz")).unwrap();
    let arr = npz.by_name("arr_0").unwrap().expect("arr_0 in npz");
    let shape = arr.shape().to_vec();
    (arr.into_vec::<f32>().unwrap(), shape)
}

fn run(m: &mut dyn DisparityMatcher) -> Metrics {
    let (l, r) = (gray("motorcycle_left.png"), gray("motorcycle_right.png"));
    let (gt, shape) = ground_truth();
    assert_eq!(shape, vec![l.height as u64, l.width as u64]);
    let mut d = DisparityMap::new(l.width, l.height);
    m.compute(l.view(), r.view(), &mut d).unwrap();
    let e = evaluate(&d, &gt);
    println!(
        "{:4} density {:5.1}%  bad>1 all {:5.1}% valid {:5.1}%  bad>2 all {:5.1}% valid {:5.1}%  mae {:.2}",
        m.name(),
        100.0 * e.density,
        100.0 * e.bad1_all,
        100.0 * e.bad1_valid,
        100.0 * e.bad2_all,
        100.0 * e.bad2_valid,
        e.mae_valid
    );
    e
}

#[test]
fn block_matching_accuracy() {
    let p = BmParams {
        num_disparities: NDISP,
        ..Default::default()
    };
    let e = run(&mut BlockMatcher::new(p, 741, 500).unwrap());
    assert!(e.density > DENSITY_BM, "{e:?}");
    assert!(
        e.bad2_valid < BAD2_VALID_BM && e.bad1_valid < BAD1_VALID_BM,
        "{e:?}"
    );
    assert!(e.bad2_all < BAD2_ALL_BM, "{e:?}");
}

/// The coarse-to-fine search (default) against the full-range search at every pixel: it may not
/// lose density, nor produce more bad pixels (small margins for rounding between builds).
#[test]
fn coarse_to_fine_is_as_accurate_as_full_search() {
    let p = BmParams {
        num_disparities: NDISP,
        ..Default::default()
    };
    assert!(p.refine_margin >= 0, "coarse-to-fine is the default");
    let fast = run(&mut BlockMatcher::new(p.clone(), 741, 500).unwrap());
    let full = BmParams {
        refine_margin: -1,
        ..p
    };
    let full = run(&mut BlockMatcher::new(full, 741, 500).unwrap());
    assert!(fast.density >= full.density - 0.002, "{fast:?} vs {full:?}");
    assert!(
        fast.bad1_valid <= full.bad1_valid + 0.001,
        "{fast:?} vs {full:?}"
    );
    assert!(
        fast.bad2_valid <= full.bad2_valid + 0.001,
        "{fast:?} vs {full:?}"
    );
    assert!(
        fast.bad2_all <= full.bad2_all + 0.001,
        "{fast:?} vs {full:?}"
    );
}

#[test]
fn sgm_accuracy() {
    let p = SgmParams {
        num_disparities: NDISP,
        ..Default::default()
    };
    let e = run(&mut SgmMatcher::new(p, 741, 500).unwrap());
    assert!(e.density > DENSITY_SGM, "{e:?}");
    assert!(
        e.bad2_valid < BAD2_VALID_SGM && e.bad1_valid < BAD1_VALID_SGM,
        "{e:?}"
    );
    assert!(e.bad2_all < BAD2_ALL_SGM, "{e:?}");
}

// Measured: BM density 80.1%, bad>1 valid 6.3%, bad>2 valid 4.6%, bad>2 all 23.6%;
// SGM density 87.4%, bad>1 valid 9.0%, bad>2 valid 6.1%, bad>2 all 18.0%.
const DENSITY_BM: f64 = 0.77;
const BAD1_VALID_BM: f64 = 0.075;
const BAD2_VALID_BM: f64 = 0.055;
const BAD2_ALL_BM: f64 = 0.26;
const DENSITY_SGM: f64 = 0.85;
const BAD1_VALID_SGM: f64 = 0.105;
const BAD2_VALID_SGM: f64 = 0.072;
const BAD2_ALL_SGM: f64 = 0.20;
