//! Block matching with Hammerhead's multiscale consistency filter.
//!
//! Cost: SAD over a square window of x-Sobel prefiltered images. SAD is one byte abs-diff per pixel
//! and disparity, which vectorizes to 32 lanes, and the clipped x-derivative removes the brightness
//! offsets between the two cameras that raw SAD would suffer from. Census is more robust still but
//! its Hamming distance costs several instructions per lane; it is what the SGM matcher uses.
//!
//! Aggregation is incremental in both directions: per row band, `col[x][d]` holds the column sums
//! of the window (one row added, one removed per output row) and the window sum slides along x
//! (one column added, one removed per pixel). Disparity is the innermost, contiguous axis, so every
//! step is a straight loop over `d` that LLVM turns into 16-lane u16 vector code. The right image
//! is stored mirrored so that `R(x - d)` is also contiguous and increasing in `d`.

use rayon::prelude::*;
use serde::Deserialize;

use crate::disparity::{
    argmin_lr, argmin_lr_partial, check_frame, check_ndisp, is_unique, lr_check_row, subpixel,
    DisparityMap, DisparityMatcher, MatchError, DISP_SCALE, INVALID,
};
use crate::image::{downsample2, GrayView};
use crate::simd::dispatch_avx2;

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct BmParams {
    /// Disparity search range 0..num_disparities (multiple of 16, at most 256).
    pub num_disparities: usize,
    /// Odd window side in pixels.
    pub block_size: usize,
    /// Clip of the x-Sobel prefilter; costs per pixel are in 0..=2*cap.
    pub prefilter_cap: u8,
    /// Minimum summed |prefiltered - cap| over the window; flatter windows are invalid.
    pub texture_threshold: u32,
    /// Percent margin by which the best cost must beat any disparity not adjacent to it.
    pub uniqueness_ratio: u32,
    /// Max |d_left - d_right| in pixels; negative disables the left-right check.
    pub lr_max_diff: i32,
    /// Multiscale filter: max |d_full - 2 d_half| in full-scale pixels; negative disables it.
    pub multiscale_max_diff: f32,
    /// Multiscale filter: keep a full-scale result when the half-scale matcher found nothing there.
    pub multiscale_keep_unmatched: bool,
}

impl Default for BmParams {
    fn default() -> Self {
        Self {
            num_disparities: 128,
            block_size: 9,
            prefilter_cap: 31,
            texture_threshold: 10,
            uniqueness_ratio: 10,
            lr_max_diff: 1,
            multiscale_max_diff: 2.0,
            multiscale_keep_unmatched: true,
        }
    }
}

impl BmParams {
    fn validate(&self) -> Result<(), MatchError> {
        check_ndisp(self.num_disparities)?;
        let bs = self.block_size;
        let bad = |m: String| Err(MatchError::InvalidParams(m));
        if bs < 3 || bs.is_multiple_of(2) {
            return bad(format!("block_size = {bs}: must be odd and >= 3"));
        }
        if self.prefilter_cap == 0 || self.prefilter_cap > 63 {
            return bad(format!(
                "prefilter_cap = {}: must be in 1..=63",
                self.prefilter_cap
            ));
        }
        // Window sums are u16.
        if bs * bs * 2 * self.prefilter_cap as usize > u16::MAX as usize {
            return bad(format!(
                "block_size {bs} with prefilter_cap {} overflows 16-bit costs",
                self.prefilter_cap
            ));
        }
        Ok(())
    }
}

pub struct BlockMatcher {
    params: BmParams,
    width: usize,
    height: usize,
    full: Level,
    coarse: Option<Coarse>,
}

struct Coarse {
    level: Level,
    left: Vec<u8>,
    right: Vec<u8>,
    disp: Vec<i16>,
}

impl BlockMatcher {
    pub fn new(params: BmParams, width: usize, height: usize) -> Result<Self, MatchError> {
        params.validate()?;
        let nd = params.num_disparities;
        let r = params.block_size / 2;
        if width < 2 * r + 2 || height < 2 * r + 2 {
            return Err(MatchError::InvalidParams(format!(
                "image {width}x{height} is smaller than the block"
            )));
        }
        let coarse = (params.multiscale_max_diff >= 0.0).then(|| {
            let (w2, h2) = (width / 2, height / 2);
            // Half the range, rounded up to whole vectors.
            let nd2 = (nd / 2).div_ceil(16) * 16;
            Coarse {
                level: Level::new(w2, h2, nd2),
                left: vec![0; w2 * h2],
                right: vec![0; w2 * h2],
                disp: vec![INVALID; w2 * h2],
            }
        });
        Ok(Self {
            full: Level::new(width, height, nd),
            params,
            width,
            height,
            coarse,
        })
    }

    pub fn params(&self) -> &BmParams {
        &self.params
    }
}

impl DisparityMatcher for BlockMatcher {
    fn compute(
        &mut self,
        left: GrayView<'_>,
        right: GrayView<'_>,
        out: &mut DisparityMap,
    ) -> Result<(), MatchError> {
        let want = (self.width, self.height);
        check_frame(want, &left, &right, out)?;
        let p = &self.params;
        self.full.run(left.data(), right.data(), p, &mut out.data);
        if let Some(c) = &mut self.coarse {
            downsample2(left, &mut c.left);
            downsample2(right, &mut c.right);
            c.level.run(&c.left, &c.right, p, &mut c.disp);
            multiscale_filter(
                out,
                &c.disp,
                c.level.w,
                c.level.h,
                p.multiscale_max_diff,
                p.multiscale_keep_unmatched,
            );
        }
        Ok(())
    }
    fn num_disparities(&self) -> usize {
        self.params.num_disparities
    }
    fn name(&self) -> &'static str {
        "bm"
    }
}

/// Drop full-scale disparities that no coarse pixel of their bilinear footprint supports: at a depth
/// edge the two coarse neighbours straddle the edge, so checking each of them (rather than an
/// interpolated value that belongs to neither surface) keeps correct pixels on both sides.
fn multiscale_filter(
    out: &mut DisparityMap,
    coarse: &[i16],
    w2: usize,
    h2: usize,
    max_diff: f32,
    keep_unmatched: bool,
) {
    let tol = (max_diff * DISP_SCALE as f32) as i32;
    let w = out.width;
    let span = |v: usize, n: usize| {
        // Full-scale v samples coarse (v - 0.5) / 2: neighbours floor and floor + 1.
        let a = (v.saturating_sub(1) / 2).min(n - 1);
        let b = (v / 2).min(n - 1);
        (a, b)
    };
    out.data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let (ya, yb) = span(y, h2);
        for (x, v) in row.iter_mut().enumerate() {
            if *v < 0 {
                continue;
            }
            let (xa, xb) = span(x, w2);
            let mut any_valid = false;
            let mut ok = false;
            for cy in [ya, yb] {
                for cx in [xa, xb] {
                    let c = coarse[cy * w2 + cx];
                    if c >= 0 {
                        any_valid = true;
                        ok |= (*v as i32 - 2 * c as i32).abs() <= tol;
                    }
                }
            }
            if !(ok || (!any_valid && keep_unmatched)) {
                *v = INVALID;
            }
        }
    });
}

/// One pyramid level: prefiltered inputs and per-band scratch, sized once.
struct Level {
    w: usize,
    h: usize,
    nd: usize,
    lp: Vec<u8>,
    /// Mirrored prefiltered right rows, `w + nd` wide: `rp[y][w - 1 - xr]`, padded past xr < 0.
    rp: Vec<u8>,
    /// Window sums of the texture measure |prefiltered - cap|.
    tex: Vec<u16>,
    tex_col: Vec<u16>,
    bands: Vec<Band>,
}

/// Fixed band count: enough to balance a few cores, few enough that the per-band warm-up
/// (summing the first window) stays small. Output does not depend on it.
const BANDS: usize = 8;

struct Band {
    col: Vec<u16>,
    sad: Vec<u16>,
    tmp: Vec<u16>,
    mr: Vec<u16>,
    md: Vec<u16>,
    best: Vec<u16>,
}

impl Level {
    fn new(w: usize, h: usize, nd: usize) -> Self {
        let bands = (0..BANDS)
            .map(|_| Band {
                col: vec![0; w * nd],
                sad: vec![0; nd],
                tmp: vec![0; nd],
                mr: vec![0; w + nd],
                md: vec![0; w + nd],
                best: vec![0; w],
            })
            .collect();
        Self {
            w,
            h,
            nd,
            lp: vec![0; w * h],
            rp: vec![0; (w + nd) * h],
            tex: vec![0; w * h],
            tex_col: vec![0; w],
            bands,
        }
    }

    fn run(&mut self, left: &[u8], right: &[u8], p: &BmParams, out: &mut [i16]) {
        let (w, h, nd) = (self.w, self.h, self.nd);
        let cap = p.prefilter_cap;
        let rs = w + nd;
        self.lp
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, row)| prefilter_row(left, w, h, y, cap, row));
        self.rp.par_chunks_mut(rs).enumerate().for_each(|(y, row)| {
            let (img, pad) = row.split_at_mut(w);
            prefilter_row(right, w, h, y, cap, img);
            img.reverse();
            pad.fill(cap);
        });
        texture_sums(
            &self.lp,
            w,
            h,
            p.block_size / 2,
            cap,
            &mut self.tex,
            &mut self.tex_col,
        );

        let band_rows = h.div_ceil(BANDS);
        let input = LevelInput {
            w,
            h,
            nd,
            lp: &self.lp,
            rp: &self.rp,
            tex: &self.tex,
        };
        out.par_chunks_mut(band_rows * w)
            .zip(self.bands.par_iter_mut())
            .enumerate()
            .for_each(|(b, (out, band))| {
                let y0 = b * band_rows;
                match_band(&input, p, y0, out, band);
            });
    }
}

/// x-Sobel (3x3, replicated border) clipped to [-cap, cap] and shifted to [0, 2 cap].
#[inline(always)]
fn prefilter_row(img: &[u8], w: usize, h: usize, y: usize, cap: u8, out: &mut [u8]) {
    let r0 = &img[y.saturating_sub(1) * w..][..w];
    let r1 = &img[y * w..][..w];
    let r2 = &img[(y + 1).min(h - 1) * w..][..w];
    let cap = cap as i16;
    let f = |a0: u8, a2: u8, b0: u8, b2: u8, c0: u8, c2: u8| {
        let d = (a2 as i16 - a0 as i16) + 2 * (b2 as i16 - b0 as i16) + (c2 as i16 - c0 as i16);
        (d.clamp(-cap, cap) + cap) as u8
    };
    out[0] = f(r0[0], r0[1], r1[0], r1[1], r2[0], r2[1]);
    out[w - 1] = f(
        r0[w - 2],
        r0[w - 1],
        r1[w - 2],
        r1[w - 1],
        r2[w - 2],
        r2[w - 1],
    );
    let it = r0
        .iter()
        .zip(&r0[2..])
        .zip(r1.iter().zip(&r1[2..]))
        .zip(r2.iter().zip(&r2[2..]));
    for (o, (((&a0, &a2), (&b0, &b2)), (&c0, &c2))) in out[1..w - 1].iter_mut().zip(it) {
        *o = f(a0, a2, b0, b2, c0, c2);
    }
}

fn texture_sums(
    lp: &[u8],
    w: usize,
    h: usize,
    r: usize,
    cap: u8,
    tex: &mut [u16],
    col: &mut [u16],
) {
    let t = |v: u8| (v as i16 - cap as i16).unsigned_abs();
    col.fill(0);
    tex.fill(0);
    for y in 0..(2 * r + 1).min(h) {
        for (c, &v) in col.iter_mut().zip(&lp[y * w..(y + 1) * w]) {
            *c += t(v);
        }
    }
    for y in r..h.saturating_sub(r) {
        if y > r {
            let (add, sub) = (&lp[(y + r) * w..][..w], &lp[(y - r - 1) * w..][..w]);
            for x in 0..w {
                col[x] = col[x] + t(add[x]) - t(sub[x]);
            }
        }
        let row = &mut tex[y * w..(y + 1) * w];
        let mut s: u16 = col[..2 * r + 1].iter().sum();
        row[r] = s;
        for x in r + 1..w - r {
            s = s + col[x + r] - col[x - r - 1];
            row[x] = s;
        }
    }
}

struct LevelInput<'a> {
    w: usize,
    h: usize,
    nd: usize,
    lp: &'a [u8],
    rp: &'a [u8],
    tex: &'a [u16],
}

dispatch_avx2!(fn match_band<'a, 'b, 'c>(inp: &'a LevelInput<'a>, p: &'b BmParams, y0: usize, out: &'c mut [i16], s: &'c mut Band) => match_band_impl);

#[inline(always)]
fn match_band_impl(inp: &LevelInput<'_>, p: &BmParams, y0: usize, out: &mut [i16], s: &mut Band) {
    let (w, h, nd) = (inp.w, inp.h, inp.nd);
    let rs = w + nd;
    let r = p.block_size / 2;
    let y1 = y0 + out.len() / w;
    out.fill(INVALID);
    let (ys, ye) = (y0.max(r), y1.min(h - r));
    if ys >= ye {
        return;
    }
    let Band {
        col,
        sad,
        tmp,
        mr,
        md,
        best,
    } = s;
    let lrow = |y: usize| &inp.lp[y * w..(y + 1) * w];
    let rrow = |y: usize| &inp.rp[y * rs..(y + 1) * rs];

    col.fill(0);
    for y in ys - r..=ys + r {
        col_add_row(col, lrow(y), rrow(y), nd);
    }
    for y in ys..ye {
        if y > ys {
            col_update(
                col,
                lrow(y + r),
                rrow(y + r),
                lrow(y - r - 1),
                rrow(y - r - 1),
                nd,
            );
        }
        let orow = &mut out[(y - y0) * w..(y - y0 + 1) * w];
        let scratch = (
            &mut sad[..],
            &mut tmp[..],
            &mut mr[..],
            &mut md[..],
            &mut best[..],
        );
        match_row(
            col,
            &inp.tex[y * w..(y + 1) * w],
            p,
            w,
            nd,
            r,
            orow,
            scratch,
        );
    }
}

#[inline(always)]
fn absdiff(a: u8, b: u8) -> u16 {
    (a.max(b) - a.min(b)) as u16
}

#[inline(always)]
fn col_add_row(col: &mut [u16], l: &[u8], r: &[u8], nd: usize) {
    let w = l.len();
    for (x, c) in col.chunks_exact_mut(nd).enumerate() {
        let a = l[x];
        for (c, &b) in c.iter_mut().zip(&r[w - 1 - x..]) {
            *c += absdiff(a, b);
        }
    }
}

#[inline(always)]
fn col_update(col: &mut [u16], ln: &[u8], rn: &[u8], lo: &[u8], ro: &[u8], nd: usize) {
    let w = ln.len();
    for (x, c) in col.chunks_exact_mut(nd).enumerate() {
        let (a, b) = (ln[x], lo[x]);
        for ((c, &n), &o) in c.iter_mut().zip(&rn[w - 1 - x..]).zip(&ro[w - 1 - x..]) {
            *c = c.wrapping_add(absdiff(a, n)).wrapping_sub(absdiff(b, o));
        }
    }
}

type RowScratch<'a> = (
    &'a mut [u16],
    &'a mut [u16],
    &'a mut [u16],
    &'a mut [u16],
    &'a mut [u16],
);

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn match_row(
    col: &[u16],
    tex: &[u16],
    p: &BmParams,
    w: usize,
    nd: usize,
    r: usize,
    out: &mut [i16],
    (sad, tmp, mr, md, best): RowScratch<'_>,
) {
    let colx = |x: usize| &col[x * nd..(x + 1) * nd];
    sad.fill(0);
    for x in 0..=2 * r {
        for (s, c) in sad.iter_mut().zip(colx(x)) {
            *s += c;
        }
    }
    mr.fill(u16::MAX);
    md.fill(0);
    best.fill(u16::MAX);
    for xc in r..w - r {
        // Right window must stay inside the image: d <= xc - r.
        let dmax = (nd - 1).min(xc - r);
        let j = w - 1 - xc;
        let slide = (xc > r).then(|| (colx(xc + r), colx(xc - r - 1)));
        let (d, m) = if dmax == nd - 1 {
            argmin_lr(sad, slide, &mut mr[j..], &mut md[j..])
        } else {
            if let Some((add, sub)) = slide {
                for ((s, &a), &b) in sad.iter_mut().zip(add).zip(sub) {
                    *s = s.wrapping_add(a).wrapping_sub(b);
                }
            }
            argmin_lr_partial(sad, dmax, tmp, &mut mr[j..], &mut md[j..])
        };
        if (tex[xc] as u32) < p.texture_threshold || !is_unique(sad, dmax, d, m, p.uniqueness_ratio)
        {
            continue;
        }
        best[xc] = d as u16;
        out[xc] = subpixel(sad, dmax, d);
    }
    lr_check_row(out, best, md, p.lr_max_diff);
}
