//! Semi-global matching: center-symmetric census 9x7 (31 bits) with Hamming cost, five aggregation
//! paths (left-right, right-left, top-down and both top diagonals), P1/P2 smoothness penalties,
//! winner-take-all with uniqueness, left-right check and parabola subpixel.
//!
//! All five paths run in a single top-to-bottom sweep, so no cost volume is stored: per row band
//! only the previous row's path costs are kept. Path costs are stored as u8: each path value is the
//! pixel cost plus a penalty-clamped term (at most `31 + P2`), and the previous pixel's minimum is
//! subtracted when it is used, so 32 disparities fit one AVX2 register. Bands start a fixed number
//! of rows early so the vertical paths are warmed up; the band split is fixed, hence the output does
//! not depend on the thread count.

use rayon::prelude::*;
use serde::Deserialize;

use crate::disparity::{
    argmin_lr, argmin_lr_partial, check_frame, check_ndisp, is_unique, lr_check_row, subpixel,
    DisparityMap, DisparityMatcher, MatchError, INVALID,
};
use crate::image::GrayView;
use crate::simd::dispatch_avx2;

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct SgmParams {
    /// Disparity search range 0..num_disparities (multiple of 16, at most 256).
    pub num_disparities: usize,
    /// Penalty for a one-step disparity change along a path (Hamming units, cost range 0..=31).
    pub p1: u8,
    /// Penalty for larger disparity jumps.
    pub p2: u8,
    /// Percent margin by which the best cost must beat any non-adjacent disparity.
    pub uniqueness_ratio: u32,
    /// Max |d_left - d_right| in pixels; negative disables the left-right check.
    pub lr_max_diff: i32,
}

impl Default for SgmParams {
    fn default() -> Self {
        Self {
            num_disparities: 128,
            p1: 10,
            p2: 120,
            // Tuned on Middlebury Motorcycle: best accuracy on produced pixels that still
            // keeps density above OpenCV SGBM's.
            uniqueness_ratio: 20,
            lr_max_diff: 1,
        }
    }
}

const CENSUS_RX: isize = 4;
const CENSUS_RY: isize = 3;
const MAX_COST: u8 = 31;
/// Rows each band runs before its first output row, to warm up the vertical paths.
const WARMUP: usize = 32;
const BANDS: usize = 4;

pub struct SgmMatcher {
    params: SgmParams,
    width: usize,
    height: usize,
    census_l: Vec<u32>,
    /// Right census, rows mirrored and padded to `w + nd` (see `bm` for the layout).
    census_r: Vec<u32>,
    bands: Vec<Band>,
}

struct Band {
    cost: Vec<u8>,
    sum: Vec<u16>,
    /// Vertical and diagonal path states of the previous and the current row, each pixel's `nd`
    /// values with one guard byte (255) either side; swapped after every row.
    prev: Paths,
    cur: Paths,
    /// Horizontal path state of the previous and the current pixel.
    lr: [Vec<u8>; 2],
    zero: Vec<u8>,
    tmp: Vec<u16>,
    mr: Vec<u16>,
    md: Vec<u16>,
    best: Vec<u16>,
}

struct Paths {
    tb: Vec<u8>,
    tlbr: Vec<u8>,
    trbl: Vec<u8>,
    /// Per-pixel minimum of each path.
    min: Vec<[u8; 3]>,
}

impl SgmMatcher {
    pub fn new(params: SgmParams, width: usize, height: usize) -> Result<Self, MatchError> {
        check_ndisp(params.num_disparities)?;
        if params.p1 == 0 || params.p1 >= params.p2 || params.p2 as u16 + MAX_COST as u16 > 254 {
            return Err(MatchError::InvalidParams(format!(
                "p1 = {}, p2 = {}: need 0 < p1 < p2 <= {}",
                params.p1,
                params.p2,
                254 - MAX_COST
            )));
        }
        if width < 16 || height < 8 {
            return Err(MatchError::InvalidParams(format!(
                "image {width}x{height} is too small"
            )));
        }
        let nd = params.num_disparities;
        let st = nd + 2;
        let guarded = |n: usize| {
            let mut v = vec![0u8; n * st];
            for px in v.chunks_exact_mut(st) {
                px[0] = 255;
                px[st - 1] = 255;
            }
            v
        };
        let paths = || Paths {
            tb: guarded(width),
            tlbr: guarded(width),
            trbl: guarded(width),
            min: vec![[0; 3]; width],
        };
        let bands = (0..BANDS)
            .map(|_| Band {
                cost: vec![0; width * nd],
                sum: vec![0; width * nd],
                prev: paths(),
                cur: paths(),
                lr: [guarded(1), guarded(1)],
                zero: guarded(1),
                tmp: vec![0; nd],
                mr: vec![0; width + nd],
                md: vec![0; width + nd],
                best: vec![0; width],
            })
            .collect();
        Ok(Self {
            width,
            height,
            census_l: vec![0; width * height],
            census_r: vec![0; (width + nd) * height],
            bands,
            params,
        })
    }
}

impl DisparityMatcher for SgmMatcher {
    fn compute(
        &mut self,
        left: GrayView<'_>,
        right: GrayView<'_>,
        out: &mut DisparityMap,
    ) -> Result<(), MatchError> {
        let want = (self.width, self.height);
        check_frame(want, &left, &right, out)?;
        let (w, nd) = (self.width, self.params.num_disparities);
        self.census_l
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, row)| census_row(left, y, row));
        self.census_r
            .par_chunks_mut(w + nd)
            .enumerate()
            .for_each(|(y, row)| {
                let (img, pad) = row.split_at_mut(w);
                census_row(right, y, img);
                img.reverse();
                // Disparities reaching left of the image see the first column repeated.
                pad.fill(img[w - 1]);
            });
        let band_rows = self.height.div_ceil(BANDS);
        let inp = Input {
            w,
            h: self.height,
            nd,
            cl: &self.census_l,
            cr: &self.census_r,
        };
        let p = &self.params;
        out.data
            .par_chunks_mut(band_rows * w)
            .zip(self.bands.par_iter_mut())
            .enumerate()
            .for_each(|(b, (o, band))| sgm_band(&inp, p, b * band_rows, o, band));
        Ok(())
    }
    fn num_disparities(&self) -> usize {
        self.params.num_disparities
    }
    fn name(&self) -> &'static str {
        "sgm"
    }
}

/// Center-symmetric census: each bit compares one pixel pair mirrored about the centre, 31
/// pairs for a 9x7 window. Coordinates are clamped at the border.
fn census_row(img: GrayView<'_>, y: usize, out: &mut [u32]) {
    let (w, h) = (img.width() as isize, img.height() as isize);
    out.fill(0);
    let mut bit = 0;
    for dy in -CENSUS_RY..=0 {
        for dx in -CENSUS_RX..=CENSUS_RX {
            if dy == 0 && dx >= 0 {
                break;
            }
            let ra = img.row((y as isize + dy).clamp(0, h - 1) as usize);
            let rb = img.row((y as isize - dy).clamp(0, h - 1) as usize);
            let at = |r: &[u8], x: isize| r[x.clamp(0, w - 1) as usize];
            let r = CENSUS_RX;
            // Interior: straight slices so the compare vectorizes.
            let (x0, x1) = (r, w - r);
            let a = &ra[(x0 + dx) as usize..(x1 + dx) as usize];
            let b = &rb[(x0 - dx) as usize..(x1 - dx) as usize];
            for ((o, &a), &b) in out[x0 as usize..x1 as usize].iter_mut().zip(a).zip(b) {
                *o |= ((a > b) as u32) << bit;
            }
            for x in (0..x0).chain(x1..w) {
                out[x as usize] |= ((at(ra, x + dx) > at(rb, x - dx)) as u32) << bit;
            }
            bit += 1;
        }
    }
}

struct Input<'a> {
    w: usize,
    h: usize,
    nd: usize,
    cl: &'a [u32],
    cr: &'a [u32],
}

dispatch_avx2!(fn sgm_band<'a, 'b, 'c>(inp: &'a Input<'a>, p: &'b SgmParams, y0: usize, out: &'c mut [i16], s: &'c mut Band) => sgm_band_impl);

#[inline(always)]
fn sgm_band_impl(inp: &Input<'_>, p: &SgmParams, y0: usize, out: &mut [i16], s: &mut Band) {
    let (w, nd) = (inp.w, inp.nd);
    let st = nd + 2;
    let y1 = y0 + out.len() / w;
    out.fill(INVALID);
    let ys = y0.saturating_sub(WARMUP);
    // Fresh start: zero previous cost makes the first row's path cost equal the pixel cost.
    for buf in [&mut s.prev.tb, &mut s.prev.tlbr, &mut s.prev.trbl] {
        for px in buf.chunks_exact_mut(st) {
            px[1..=nd].fill(0);
        }
    }
    s.prev.min.fill([0; 3]);
    for y in ys..y1.min(inp.h) {
        let cl = &inp.cl[y * w..(y + 1) * w];
        let cr = &inp.cr[y * (w + nd)..(y + 1) * (w + nd)];
        for (x, c) in s.cost.chunks_exact_mut(nd).enumerate() {
            let a = cl[x];
            for (c, &b) in c.iter_mut().zip(&cr[w - 1 - x..]) {
                *c = (a ^ b).count_ones() as u8;
            }
        }
        forward_row(s, w, nd, p);
        std::mem::swap(&mut s.prev, &mut s.cur);
        if y >= y0 {
            backward_row(s, w, nd, p, &mut out[(y - y0) * w..(y - y0 + 1) * w]);
        }
    }
}

/// One path step: `out[d] = C[d] + min(prev[d], prev[d±1] + P1, min(prev) + P2) - min(prev)`.
/// `prev` and `out` are guarded (`nd + 2` long); returns `min(out)`.
#[inline(always)]
fn step(prev: &[u8], pmin: u8, cost: &[u8], out: &mut [u8], p1: u8, p2: u8) -> u8 {
    let lim = pmin.saturating_add(p2);
    let mut m = u8::MAX;
    let nb = prev.iter().zip(&prev[1..]).zip(&prev[2..]);
    for ((o, &c), ((&lo, &mid), &hi)) in out[1..].iter_mut().zip(cost).zip(nb) {
        let t = mid
            .min(lo.saturating_add(p1))
            .min(hi.saturating_add(p1))
            .min(lim)
            - pmin;
        let v = c + t;
        *o = v;
        m = m.min(v);
    }
    m
}

/// Left-to-right, top-down and both top diagonal paths for one row; leaves their sum in `sum`.
#[inline(always)]
fn forward_row(s: &mut Band, w: usize, nd: usize, p: &SgmParams) {
    fn px(v: &[u8], x: usize, st: usize) -> &[u8] {
        &v[x * st..(x + 1) * st]
    }
    let st = nd + 2;
    let (p1, p2) = (p.p1, p.p2);
    let [lr_prev, lr_cur] = &mut s.lr;
    let mut lr_min = 0u8;
    lr_prev[1..=nd].fill(0);
    let (prev, cur) = (&s.prev, &mut s.cur);
    for x in 0..w {
        let cost = &s.cost[x * nd..(x + 1) * nd];
        let o = x * st..(x + 1) * st;
        lr_min = step(lr_prev, lr_min, cost, lr_cur, p1, p2);
        std::mem::swap(lr_prev, lr_cur);
        // Diagonals start fresh at the image sides.
        let (left, lmin) = if x > 0 {
            (px(&prev.tlbr, x - 1, st), prev.min[x - 1][1])
        } else {
            (&s.zero[..], 0)
        };
        let (right, rmin) = if x + 1 < w {
            (px(&prev.trbl, x + 1, st), prev.min[x + 1][2])
        } else {
            (&s.zero[..], 0)
        };
        cur.min[x] = [
            step(
                px(&prev.tb, x, st),
                prev.min[x][0],
                cost,
                &mut cur.tb[o.clone()],
                p1,
                p2,
            ),
            step(left, lmin, cost, &mut cur.tlbr[o.clone()], p1, p2),
            step(right, rmin, cost, &mut cur.trbl[o.clone()], p1, p2),
        ];
        let sum = &mut s.sum[x * nd..(x + 1) * nd];
        let (a, b, c, d) = (
            &lr_prev[1..],
            &cur.tb[o.start + 1..],
            &cur.tlbr[o.start + 1..],
            &cur.trbl[o.start + 1..],
        );
        for ((((o, &a), &b), &c), &d) in sum.iter_mut().zip(a).zip(b).zip(c).zip(d) {
            *o = a as u16 + b as u16 + c as u16 + d as u16;
        }
    }
}

#[inline(always)]
fn backward_row(s: &mut Band, w: usize, nd: usize, p: &SgmParams, out: &mut [i16]) {
    let (p1, p2) = (p.p1, p.p2);
    let [rl_prev, rl_cur] = &mut s.lr;
    let mut rl_min = 0u8;
    rl_prev[1..=nd].fill(0);
    s.mr.fill(u16::MAX);
    s.md.fill(0);
    s.best.fill(u16::MAX);
    for x in (0..w).rev() {
        let cost = &s.cost[x * nd..(x + 1) * nd];
        rl_min = step(rl_prev, rl_min, cost, rl_cur, p1, p2);
        std::mem::swap(rl_prev, rl_cur);
        let sum = &mut s.sum[x * nd..(x + 1) * nd];
        for (o, &v) in sum.iter_mut().zip(&rl_prev[1..]) {
            *o += v as u16;
        }
        let j = w - 1 - x;
        let dmax = (nd - 1).min(x);
        let (d, m) = if dmax == nd - 1 {
            argmin_lr(sum, None, &mut s.mr[j..], &mut s.md[j..])
        } else {
            argmin_lr_partial(sum, dmax, &mut s.tmp, &mut s.mr[j..], &mut s.md[j..])
        };
        if !is_unique(sum, dmax, d, m, p.uniqueness_ratio) {
            continue;
        }
        s.best[x] = d as u16;
        out[x] = subpixel(sum, dmax, d);
    }
    lr_check_row(out, &s.best, &s.md, p.lr_max_diff);
}
