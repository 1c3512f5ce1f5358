//! BM and SGM at the Hammerhead size: 1280x960, 128 disparities, on a synthetic random-texture
//! pair with a disparity ramp (so every disparity range is exercised).

use criterion::{criterion_group, criterion_main, Criterion};
use stereo::bm::{BlockMatcher, BmParams};
use stereo::sgm::{SgmMatcher, SgmParams};
use stereo::{DisparityMap, DisparityMatcher, GrayImage};

const W: usize = 1280;
const H: usize = 960;
const ND: usize = 128;

fn pair() -> (GrayImage, GrayImage) {
    let mut s = 0x1234_5678_9abc_def1u64;
    let mut noise = vec![0u8; (W + ND) * H];
    for v in &mut noise {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        *v = (s >> 56) as u8;
    }
    // Disparity grows from 8 at the top to 100 at the bottom.
    let mut l = GrayImage::new(W, H);
    let mut r = GrayImage::new(W, H);
    for y in 0..H {
        let d = 8 + (92 * y) / H;
        for x in 0..W {
            l.data[y * W + x] = noise[y * (W + ND) + x + ND];
            r.data[y * W + x] = noise[y * (W + ND) + x + ND - d];
        }
    }
    (l, r)
}

fn bench(c: &mut Criterion) {
    let (l, r) = pair();
    let mut out = DisparityMap::new(W, H);
    let mut g = c.benchmark_group("stereo_1280x960_128");
    g.sample_size(10);
    let bm = BmParams {
        num_disparities: ND,
        ..Default::default()
    };
    let mut m = BlockMatcher::new(bm, W, H).unwrap();
    g.bench_function("bm", |b| {
        b.iter(|| m.compute(l.view(), r.view(), &mut out).unwrap())
    });
    let sgm = SgmParams {
        num_disparities: ND,
        ..Default::default()
    };
    let mut m = SgmMatcher::new(sgm, W, H).unwrap();
    g.bench_function("sgm", |b| {
        b.iter(|| m.compute(l.view(), r.view(), &mut out).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
