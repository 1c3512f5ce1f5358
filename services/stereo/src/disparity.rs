//! Disparity output type, the matcher trait shared by BM and SGM, and the winner-take-all steps both
//! use (argmin, uniqueness, parabola subpixel, left-right check).
//!
//! Disparity format: `i16` fixed point, `DISP_SCALE` (16) steps per pixel; any negative value is
//! invalid (`INVALID` = -1). Half the bandwidth of f32 and exact to compare, which keeps the output
//! deterministic byte for byte.

use serde::Deserialize;
use thiserror::Error;

use crate::bm::{BlockMatcher, BmParams};
use crate::image::GrayView;
use crate::sgm::{SgmMatcher, SgmParams};

pub const DISP_SCALE: i16 = 16;
pub const INVALID: i16 = -1;

#[derive(Debug, Error, PartialEq)]
pub enum MatchError {
    #[error("{which} image is {got_w}x{got_h}, matcher is configured for {want_w}x{want_h}")]
    SizeMismatch {
        which: &'static str,
        want_w: usize,
        want_h: usize,
        got_w: usize,
        got_h: usize,
    },
    #[error("invalid matcher parameter: {0}")]
    InvalidParams(String),
}

/// Dense disparity of the left image in fixed point (see module doc).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DisparityMap {
    pub width: usize,
    pub height: usize,
    pub data: Vec<i16>,
}

impl DisparityMap {
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![INVALID; width * height],
        }
    }
    /// Disparity in pixels, `None` where invalid.
    pub fn get(&self, x: usize, y: usize) -> Option<f32> {
        let v = self.data[y * self.width + x];
        (v >= 0).then(|| v as f32 / DISP_SCALE as f32)
    }
    pub fn density(&self) -> f64 {
        self.data.iter().filter(|&&v| v >= 0).count() as f64 / self.data.len().max(1) as f64
    }
}

/// A stereo matcher: rectified left + right Mono8 in, left disparity out. Implementations keep
/// their scratch buffers between calls and reject frames of another size than configured.
pub trait DisparityMatcher: Send {
    fn compute(
        &mut self,
        left: GrayView<'_>,
        right: GrayView<'_>,
        out: &mut DisparityMap,
    ) -> Result<(), MatchError>;
    fn num_disparities(&self) -> usize;
    fn name(&self) -> &'static str;
}

/// Matcher choice as it appears in a service config: `algo = "bm"` or `algo = "sgm"` plus that
/// algorithm's parameters, so swapping the matcher is a config change.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "algo", rename_all = "lowercase", deny_unknown_fields)]
pub enum MatcherConfig {
    Bm(BmParams),
    Sgm(SgmParams),
}

pub fn build_matcher(
    config: &MatcherConfig,
    width: usize,
    height: usize,
) -> Result<Box<dyn DisparityMatcher>, MatchError> {
    Ok(match config {
        MatcherConfig::Bm(p) => Box::new(BlockMatcher::new(p.clone(), width, height)?),
        MatcherConfig::Sgm(p) => Box::new(SgmMatcher::new(p.clone(), width, height)?),
    })
}

/// Checks that a matcher's inputs and output all have the size it was built for.
pub(crate) fn check_frame(
    want: (usize, usize),
    left: &GrayView<'_>,
    right: &GrayView<'_>,
    out: &DisparityMap,
) -> Result<(), MatchError> {
    check_size("left", want, (left.width(), left.height()))?;
    check_size("right", want, (right.width(), right.height()))?;
    check_size("output", want, (out.width, out.height))
}

fn check_size(
    which: &'static str,
    want: (usize, usize),
    got: (usize, usize),
) -> Result<(), MatchError> {
    if want != got {
        return Err(MatchError::SizeMismatch {
            which,
            want_w: want.0,
            want_h: want.1,
            got_w: got.0,
            got_h: got.1,
        });
    }
    Ok(())
}

pub(crate) fn check_ndisp(n: usize) -> Result<(), MatchError> {
    if n == 0 || !n.is_multiple_of(16) || n > 256 {
        return Err(MatchError::InvalidParams(format!(
            "num_disparities = {n}: must be a multiple of 16 in 16..=256"
        )));
    }
    Ok(())
}

const LANES: usize = 16;

/// Argmin over a full cost vector (length multiple of 16) fused with the update of the right
/// image's best match: `mr[d]`/`md[d]` belong to right pixel `x - d`, so one pass over the costs
/// also yields the right disparity map used by the left-right check. Ties keep the smaller d.
/// With `slide = Some((add, sub))` the costs are first updated in place as `c += add - sub`
/// (block matching's sliding window), saving a separate pass.
#[inline(always)]
pub(crate) fn argmin_lr(
    costs: &mut [u16],
    slide: Option<(&[u16], &[u16])>,
    mr: &mut [u16],
    md: &mut [u16],
) -> (usize, u16) {
    argmin_lr_from(costs, slide, mr, md, 0)
}

/// `argmin_lr` over a disparity window starting at `base`: `costs[k]` belongs to disparity
/// `base + k`, which is what `md` records; the returned index is relative to the window.
#[inline(always)]
pub(crate) fn argmin_lr_from(
    costs: &mut [u16],
    slide: Option<(&[u16], &[u16])>,
    mr: &mut [u16],
    md: &mut [u16],
    base: u16,
) -> (usize, u16) {
    let n = costs.len();
    assert!(n.is_multiple_of(LANES) && mr.len() >= n && md.len() >= n);
    if let Some((a, s)) = slide {
        assert!(a.len() >= n && s.len() >= n);
    }
    #[cfg(target_arch = "x86_64")]
    if crate::simd::has_avx2() {
        // SAFETY: AVX2 is present; lengths checked above.
        return unsafe { argmin_lr_avx2(costs, slide, mr, md, base) };
    }
    argmin_lr_scalar(costs, slide, mr, md, base)
}

/// Portable `argmin_lr_from` (also the reference the vector path is tested against).
#[inline(always)]
pub(crate) fn argmin_lr_scalar(
    costs: &mut [u16],
    slide: Option<(&[u16], &[u16])>,
    mr: &mut [u16],
    md: &mut [u16],
    base: u16,
) -> (usize, u16) {
    if let Some((a, s)) = slide {
        for ((c, &a), &s) in costs.iter_mut().zip(a).zip(s) {
            *c = c.wrapping_add(a).wrapping_sub(s);
        }
    }
    let mut best = (0usize, u16::MAX);
    for (d, ((&v, r), m)) in costs
        .iter()
        .zip(mr.iter_mut())
        .zip(md.iter_mut())
        .enumerate()
    {
        if v < best.1 {
            best = (d, v);
        }
        if v < *r {
            *r = v;
            *m = base + d as u16;
        }
    }
    best
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn argmin_lr_avx2(
    costs: &mut [u16],
    slide: Option<(&[u16], &[u16])>,
    mr: &mut [u16],
    md: &mut [u16],
    base: u16,
) -> (usize, u16) {
    use std::arch::x86_64::*;
    let mut bv = _mm256_set1_epi16(-1);
    let mut bd = _mm256_set1_epi16(base as i16);
    let mut idx = _mm256_add_epi16(
        _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15),
        _mm256_set1_epi16(base as i16),
    );
    let step = _mm256_set1_epi16(LANES as i16);
    let (c, r, m) = (costs.as_mut_ptr(), mr.as_mut_ptr(), md.as_mut_ptr());
    for k in (0..costs.len() / LANES).map(|i| i * LANES) {
        let mut v = _mm256_loadu_si256(c.add(k) as *const __m256i);
        if let Some((a, s)) = slide {
            let a = _mm256_loadu_si256(a.as_ptr().add(k) as *const __m256i);
            let s = _mm256_loadu_si256(s.as_ptr().add(k) as *const __m256i);
            v = _mm256_sub_epi16(_mm256_add_epi16(v, a), s);
            _mm256_storeu_si256(c.add(k) as *mut __m256i, v);
        }
        // Unsigned "v < best" shows as a changed minimum.
        let nb = _mm256_min_epu16(v, bv);
        bd = _mm256_blendv_epi8(idx, bd, _mm256_cmpeq_epi16(nb, bv));
        bv = nb;
        let rv = _mm256_loadu_si256(r.add(k) as *const __m256i);
        let nr = _mm256_min_epu16(v, rv);
        let rsame = _mm256_cmpeq_epi16(nr, rv);
        _mm256_storeu_si256(r.add(k) as *mut __m256i, nr);
        let mv = _mm256_loadu_si256(m.add(k) as *const __m256i);
        _mm256_storeu_si256(m.add(k) as *mut __m256i, _mm256_blendv_epi8(idx, mv, rsame));
        idx = _mm256_add_epi16(idx, step);
    }
    // Lane reduction: the minimum value, then the smallest d among lanes holding it.
    let v8 = _mm_min_epu16(_mm256_castsi256_si128(bv), _mm256_extracti128_si256(bv, 1));
    let min = _mm_extract_epi16(_mm_minpos_epu16(v8), 0) as u16;
    let hit = _mm256_cmpeq_epi16(bv, _mm256_set1_epi16(min as i16));
    let ds = _mm256_blendv_epi8(_mm256_set1_epi16(-1), bd, hit);
    let d8 = _mm_min_epu16(_mm256_castsi256_si128(ds), _mm256_extracti128_si256(ds, 1));
    let d = _mm_extract_epi16(_mm_minpos_epu16(d8), 0) as usize;
    (d - base as usize, min)
}

/// Smallest cost more than one step away from `best` within `0..=dmax`.
#[inline(always)]
pub(crate) fn second_min(costs: &[u16], dmax: usize, best: usize) -> u16 {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::has_avx2() && dmax + 1 == costs.len() && costs.len().is_multiple_of(LANES) {
        // SAFETY: AVX2 is present; the loop reads whole vectors inside `costs`.
        return unsafe { second_min_avx2(costs, best) };
    }
    let below = costs[..best.saturating_sub(1)].iter().copied().min();
    let above = costs[(best + 2).min(dmax + 1)..=dmax].iter().copied().min();
    below.unwrap_or(u16::MAX).min(above.unwrap_or(u16::MAX))
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn second_min_avx2(costs: &[u16], best: usize) -> u16 {
    use std::arch::x86_64::*;
    let mut idx = _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let step = _mm256_set1_epi16(LANES as i16);
    // Lanes with d in best-1..=best+1 satisfy (d - (best-1)) as unsigned <= 2.
    let lo = _mm256_set1_epi16(best as i16 - 1);
    let two = _mm256_set1_epi16(2);
    let mut m = _mm256_set1_epi16(-1);
    for k in (0..costs.len() / LANES).map(|i| i * LANES) {
        let v = _mm256_loadu_si256(costs.as_ptr().add(k) as *const __m256i);
        let rel = _mm256_sub_epi16(idx, lo);
        let near = _mm256_cmpeq_epi16(_mm256_min_epu16(rel, two), rel);
        m = _mm256_min_epu16(m, _mm256_or_si256(v, near));
        idx = _mm256_add_epi16(idx, step);
    }
    let m8 = _mm_min_epu16(_mm256_castsi256_si128(m), _mm256_extracti128_si256(m, 1));
    _mm_extract_epi16(_mm_minpos_epu16(m8), 0) as u16
}

/// Variant for pixels near the left border, where only `0..=dmax` can be matched: the costs go
/// through `tmp` with the impossible disparities set to the maximum, which neither wins nor
/// updates the right image's best match.
#[inline(always)]
pub(crate) fn argmin_lr_partial(
    costs: &[u16],
    dmax: usize,
    tmp: &mut [u16],
    mr: &mut [u16],
    md: &mut [u16],
) -> (usize, u16) {
    argmin_lr_partial_from(costs, dmax, tmp, mr, md, 0)
}

/// `argmin_lr_partial` over a window starting at disparity `base` (see `argmin_lr_from`).
#[inline(always)]
pub(crate) fn argmin_lr_partial_from(
    costs: &[u16],
    dmax: usize,
    tmp: &mut [u16],
    mr: &mut [u16],
    md: &mut [u16],
    base: u16,
) -> (usize, u16) {
    let tmp = &mut tmp[..costs.len()];
    tmp[..=dmax].copy_from_slice(&costs[..=dmax]);
    tmp[dmax + 1..].fill(u16::MAX);
    argmin_lr_from(tmp, None, mr, md, base)
}

/// Uniqueness test (same meaning as OpenCV's `uniquenessRatio`): reject when a disparity more than
/// one step away from the winner costs at most `min * (1 + ratio/100)`.
#[inline(always)]
pub(crate) fn is_unique(costs: &[u16], dmax: usize, best: usize, min: u16, ratio: u32) -> bool {
    if ratio == 0 {
        return true;
    }
    let thresh = min as u32 + min as u32 * ratio / 100;
    second_min(costs, dmax, best) as u32 > thresh
}

/// Parabola through the costs at d-1, d, d+1; returns the fixed-point disparity. Fits a cost
/// that is smooth at its minimum (SGM's aggregated census costs).
#[inline(always)]
pub(crate) fn subpixel(costs: &[u16], dmax: usize, d: usize) -> i16 {
    subpixel_by(costs, dmax, d, |p, c, n| 2 * (p + n - 2 * c))
}

/// Two lines of equal and opposite slope through the costs at d-1, d, d+1 (the steeper side
/// sets the slope); returns the fixed-point disparity. A window SAD is V-shaped at its minimum,
/// and a parabola through a V pulls every estimate towards the whole pixel: on the Middlebury
/// Motorcycle pair 38 % of block-matching disparities lay within 1/8 px of a whole one (25 % if
/// unbiased; 23 % with this fit), and a boat closing head-on 70-80 m out read the same range for
/// a second, then jumped (services/stereo/README.md, subpixel). Block matching runs its float
/// twin (`bm::subpixel_f32`); this is the reference both its paths are tested against.
#[cfg(test)]
pub(crate) fn subpixel_equiangular(costs: &[u16], dmax: usize, d: usize) -> i16 {
    subpixel_by(costs, dmax, d, |p, c, n| 2 * (p.max(n) - c))
}

/// The fixed-point disparity `d + (p - n) / den(p, c, n)` for the costs p, c, n at d-1, d, d+1,
/// rounded to nearest; `d` itself at the ends of the range or where `den` is not positive.
#[inline(always)]
fn subpixel_by(costs: &[u16], dmax: usize, d: usize, den: impl Fn(i32, i32, i32) -> i32) -> i16 {
    let base = (d as i32) * DISP_SCALE as i32;
    if d == 0 || d >= dmax {
        return base as i16;
    }
    let (p, c, n) = (costs[d - 1] as i32, costs[d] as i32, costs[d + 1] as i32);
    let den = den(p, c, n);
    if den <= 0 {
        return base as i16;
    }
    let num = (p - n) * DISP_SCALE as i32;
    // Round to nearest; |num/den| <= DISP_SCALE/2 for both fits because c is the minimum.
    let off = if num >= 0 {
        (num + den / 2) / den
    } else {
        -((-num + den / 2) / den)
    };
    (base + off) as i16
}

/// Left-right consistency on one row. `best[x]` is the integer left disparity (u16::MAX =
/// none) and `md[w - 1 - xr]` the right disparity of right pixel `xr`.
pub(crate) fn lr_check_row(out: &mut [i16], best: &[u16], md: &[u16], max_diff: i32) {
    if max_diff < 0 {
        return;
    }
    let w = out.len();
    for x in 0..w {
        let d = best[x];
        if d == u16::MAX || out[x] < 0 {
            continue;
        }
        let dr = md[w - 1 - x + d as usize];
        if (dr as i32 - d as i32).abs() > max_diff {
            out[x] = INVALID;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The window SAD of a shifted texture grows about linearly with the disparity error: costs
    /// `slope * |d - true|` at d-1, d, d+1.
    fn v_costs(slope: f64, offset: f64) -> [u16; 3] {
        [-1.0, 0.0, 1.0].map(|k: f64| (slope * (k - offset).abs()).round() as u16)
    }

    #[test]
    fn the_equiangular_fit_finds_a_v_shaped_minimum_where_the_parabola_pulls_it_to_the_pixel() {
        for sixteenths in -7..=7 {
            let offset = sixteenths as f64 / DISP_SCALE as f64;
            let costs = v_costs(1600.0, offset);
            let want = DISP_SCALE + sixteenths;
            assert_eq!(subpixel_equiangular(&costs, 2, 1), want, "{costs:?}");
            let parabola = subpixel(&costs, 2, 1);
            // A parabola through a V reads a fraction f as f / (2 (1 - |f|)): nearer the whole
            // pixel, by up to 0.09 px (at 0.29 px).
            let pulled = (parabola - DISP_SCALE).abs();
            if (2..=6).contains(&sixteenths.abs()) {
                assert!(
                    pulled < sixteenths.abs(),
                    "{sixteenths}/16 read as {parabola}"
                );
            }
            assert!(
                pulled <= sixteenths.abs(),
                "{sixteenths}/16 read as {parabola}"
            );
        }
    }
}
