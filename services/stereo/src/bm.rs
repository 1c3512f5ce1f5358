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
//!
//! Coarse-to-fine (`refine_margin >= 0`, the default): the half-scale match that the multiscale
//! filter needs anyway runs first, over the full range, and bounds the full-scale search: each
//! 32x16 tile is matched only over twice the range of the half-scale disparities under it plus a
//! margin (`Guide::window`), with its own column sums; tiles without a half-scale match get the
//! full range. The row kernel (`tile_row_avx2`) keeps the window's costs in registers across the
//! row. The left-right check uses the right-image minima of the costs computed in the same pass,
//! and the multiscale filter is applied as each pixel is written.

use rayon::prelude::*;
use serde::Deserialize;

#[cfg(test)]
use crate::disparity::{argmin_lr, argmin_lr_partial, subpixel_equiangular};
use crate::disparity::{
    argmin_lr_from, argmin_lr_partial_from, check_frame, check_ndisp, is_unique, lr_check_row,
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
    /// Coarse-to-fine search: the full scale searches each 32x16 tile only over twice the range of
    /// the half-scale disparities under it, widened by this many pixels each side (rounded up to
    /// whole 16-disparity vectors); tiles with no half-scale match get the full range. Negative:
    /// full range everywhere.
    pub refine_margin: i32,
    /// Uniqueness ratio (as `uniqueness_ratio`) inside a narrowed window. A window hides the
    /// distant rivals that make a full-range search reject an ambiguous pixel, so it needs a
    /// stricter margin for the same reliability.
    pub refine_uniqueness_ratio: u32,
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
            refine_margin: 4,
            refine_uniqueness_ratio: 23,
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
        let coarse_needed = params.multiscale_max_diff >= 0.0 || params.refine_margin >= 0;
        let coarse = coarse_needed.then(|| {
            let (w2, h2) = (width / 2, height / 2);
            // Half the range, rounded up to whole vectors.
            let nd2 = (nd / 2).div_ceil(16) * 16;
            Coarse {
                level: Level::new(w2, h2, nd2, r, false),
                left: vec![0; w2 * h2],
                right: vec![0; w2 * h2],
                disp: vec![INVALID; w2 * h2],
            }
        });
        Ok(Self {
            full: Level::new(width, height, nd, r, params.refine_margin >= 0),
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
        let Some(c) = &mut self.coarse else {
            self.full
                .run(left.data(), right.data(), p, &mut out.data, None);
            return Ok(());
        };
        // Half scale first: its disparities bound the full-scale search and filter its result.
        downsample2(left, &mut c.left);
        downsample2(right, &mut c.right);
        c.level.run(&c.left, &c.right, p, &mut c.disp, None);
        let guide = (p.refine_margin >= 0).then_some(Guide {
            disp: &c.disp,
            w2: c.level.w,
            h2: c.level.h,
            margin: p.refine_margin,
        });
        self.full
            .run(left.data(), right.data(), p, &mut out.data, guide.as_ref());
        // The coarse-to-fine path applies the filter as it writes each pixel.
        if guide.is_none() && p.multiscale_max_diff >= 0.0 {
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
    let w = out.width;
    out.data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let f = RowFilter::new(coarse, w2, h2, y, max_diff, keep_unmatched);
        for (x, v) in row.iter_mut().enumerate() {
            if *v >= 0 && !f.keeps(x, *v) {
                *v = INVALID;
            }
        }
    });
}

/// The multiscale filter for one full-scale row: the two half-scale rows it samples.
struct RowFilter<'a> {
    above: &'a [i16],
    below: &'a [i16],
    tol: i32,
    keep_unmatched: bool,
}

impl<'a> RowFilter<'a> {
    fn new(coarse: &'a [i16], w2: usize, h2: usize, y: usize, max_diff: f32, keep: bool) -> Self {
        let (ya, yb) = span(y, h2);
        Self {
            above: &coarse[ya * w2..][..w2],
            below: &coarse[yb * w2..][..w2],
            tol: (max_diff * DISP_SCALE as f32) as i32,
            keep_unmatched: keep,
        }
    }

    /// Whether full-scale pixel `x` may keep the valid disparity `v`.
    #[inline(always)]
    fn keeps(&self, x: usize, v: i16) -> bool {
        let (xa, xb) = span(x, self.above.len());
        let v = v as i32;
        // Branch-free: which neighbours are valid is unpredictable.
        let (mut any_valid, mut ok) = (false, false);
        for c in [
            self.above[xa],
            self.above[xb],
            self.below[xa],
            self.below[xb],
        ] {
            let valid = c >= 0;
            any_valid |= valid;
            ok |= valid & ((v - 2 * c as i32).abs() <= self.tol);
        }
        ok || (!any_valid && self.keep_unmatched)
    }
}

/// Full-scale `v` samples half-scale `(v - 0.5) / 2`: neighbours floor and floor + 1.
#[inline(always)]
fn span(v: usize, n: usize) -> (usize, usize) {
    let a = (v.saturating_sub(1) / 2).min(n - 1);
    let b = (v / 2).min(n - 1);
    (a, b)
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
    /// Scratch of the coarse-to-fine path (empty when the level always searches the full range).
    tile_bands: Vec<TileBand>,
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

/// Coarse-to-fine tiles: full-scale pixels that share one disparity window. The grid is anchored
/// at (0, 0), independent of bands and threads, so the output does not depend on them either.
const TILE_W: usize = 32;
const TILE_H: usize = 16;
/// More bands than `BANDS`: the work per tile varies with its window, so finer bands balance it.
const TILE_BANDS: usize = 20;

struct TileBand {
    /// Column sums of one tile, `(TILE_W + 2r) x window`.
    col: Vec<u16>,
    sad: Vec<u16>,
    tmp: Vec<u16>,
    /// Right-image best cost and disparity per strip row (`TILE_H x (w + nd)`), as in `Band`.
    mr: Vec<u16>,
    md: Vec<u16>,
    /// Integer left disparity per strip row (`TILE_H x w`).
    best: Vec<u16>,
}

/// The half-scale result that bounds the full-scale search.
struct Guide<'a> {
    disp: &'a [i16],
    w2: usize,
    h2: usize,
    margin: i32,
}

impl Guide<'_> {
    /// Disparity window `(first, len)` for full-scale columns `x0..x1`, rows `y0..y1`: twice the
    /// min..max of the valid half-scale disparities under them (the pixels the multiscale filter
    /// compares with) plus the margin, rounded up to whole vectors and centred; the whole range
    /// where the half scale has nothing.
    fn window(&self, x0: usize, x1: usize, y0: usize, y1: usize, nd: usize) -> (usize, usize) {
        let (cx0, cx1) = (
            (x0.saturating_sub(1) / 2).min(self.w2 - 1),
            ((x1 - 1) / 2).min(self.w2 - 1),
        );
        let (cy0, cy1) = (
            (y0.saturating_sub(1) / 2).min(self.h2 - 1),
            ((y1 - 1) / 2).min(self.h2 - 1),
        );
        let (mut lo, mut hi) = (i16::MAX, -1i16);
        for cy in cy0..=cy1 {
            for &c in &self.disp[cy * self.w2 + cx0..=cy * self.w2 + cx1] {
                if c >= 0 {
                    lo = lo.min(c);
                    hi = hi.max(c);
                }
            }
        }
        if hi < 0 {
            return (0, nd);
        }
        // Half-scale values are in 1/16 half-scale pixels: full-scale pixels are 2 c / 16.
        let s = DISP_SCALE as i32;
        let lo = (2 * lo as i32 / s - self.margin).clamp(0, nd as i32 - 1) as usize;
        let hi =
            ((2 * hi as i32 + s - 1) / s + self.margin).clamp(lo as i32, nd as i32 - 1) as usize;
        let span = hi + 1 - lo;
        let len = span.div_ceil(16) * 16;
        let first = lo.saturating_sub((len - span) / 2).min(nd - len);
        (first, len)
    }
}

impl Level {
    fn new(w: usize, h: usize, nd: usize, r: usize, tiled: bool) -> Self {
        let rs = w + nd;
        let tile_bands = (0..if tiled { TILE_BANDS } else { 0 })
            .map(|_| TileBand {
                col: vec![0; (TILE_W + 2 * r) * nd],
                sad: vec![0; nd],
                tmp: vec![0; nd],
                mr: vec![0; TILE_H * rs],
                md: vec![0; TILE_H * rs],
                best: vec![0; TILE_H * w],
            })
            .collect();
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
            tex_col: vec![0; BANDS * w],
            bands,
            tile_bands,
        }
    }

    fn run(
        &mut self,
        left: &[u8],
        right: &[u8],
        p: &BmParams,
        out: &mut [i16],
        guide: Option<&Guide<'_>>,
    ) {
        let (w, h, nd) = (self.w, self.h, self.nd);
        let cap = p.prefilter_cap;
        let rs = w + nd;
        self.lp
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, row)| prefilter_row_fast(left, w, h, y, cap, row));
        self.rp.par_chunks_mut(rs).enumerate().for_each(|(y, row)| {
            let (img, pad) = row.split_at_mut(w);
            prefilter_row_fast(right, w, h, y, cap, img);
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

        let input = LevelInput {
            w,
            h,
            nd,
            lp: &self.lp,
            rp: &self.rp,
            tex: &self.tex,
        };
        if let Some(g) = guide {
            assert!(
                !self.tile_bands.is_empty(),
                "level built without tile scratch"
            );
            let band_rows = h.div_ceil(TILE_H).div_ceil(TILE_BANDS) * TILE_H;
            out.par_chunks_mut(band_rows * w)
                .zip(self.tile_bands.par_iter_mut())
                .enumerate()
                .for_each(|(b, (out, band))| {
                    match_band_tiled(&input, p, g, b * band_rows, out, band);
                });
            return;
        }
        let band_rows = h.div_ceil(BANDS);
        out.par_chunks_mut(band_rows * w)
            .zip(self.bands.par_iter_mut())
            .enumerate()
            .for_each(|(b, (out, band))| {
                let y0 = b * band_rows;
                match_band(&input, p, y0, out, band);
            });
    }
}

dispatch_avx2!(fn prefilter_row_fast<'a, 'b>(img: &'a [u8], w: usize, h: usize, y: usize, cap: u8, out: &'b mut [u8]) => prefilter_row);

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

/// Window sums of |prefiltered - cap| in row bands (each with its own column sums in `col`, one
/// row of it per band), so that this pass runs in parallel too.
fn texture_sums(
    lp: &[u8],
    w: usize,
    h: usize,
    r: usize,
    cap: u8,
    tex: &mut [u16],
    col: &mut [u16],
) {
    let band_rows = h.div_ceil(col.len() / w);
    tex.par_chunks_mut(band_rows * w)
        .zip(col.par_chunks_mut(w))
        .enumerate()
        .for_each(|(b, (tex, col))| texture_band(lp, w, h, r, cap, b * band_rows, tex, col));
}

dispatch_avx2!(#[allow(clippy::too_many_arguments)] fn texture_band<'a, 'b>(lp: &'a [u8], w: usize, h: usize, r: usize, cap: u8, y0: usize, tex: &'b mut [u16], col: &'b mut [u16]) => texture_band_impl);

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn texture_band_impl(
    lp: &[u8],
    w: usize,
    h: usize,
    r: usize,
    cap: u8,
    y0: usize,
    tex: &mut [u16],
    col: &mut [u16],
) {
    let t = |v: u8| (v as i16 - cap as i16).unsigned_abs();
    tex.fill(0);
    let (ys, ye) = (y0.max(r), (y0 + tex.len() / w).min(h - r));
    if ys >= ye {
        return;
    }
    col.fill(0);
    for y in ys - r..=ys + r {
        for (c, &v) in col.iter_mut().zip(&lp[y * w..(y + 1) * w]) {
            *c += t(v);
        }
    }
    for y in ys..ye {
        if y > ys {
            let (add, sub) = (&lp[(y + r) * w..][..w], &lp[(y - r - 1) * w..][..w]);
            for x in 0..w {
                col[x] = col[x] + t(add[x]) - t(sub[x]);
            }
        }
        let row = &mut tex[(y - y0) * w..][..w];
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
        let tex = &inp.tex[y * w..(y + 1) * w];
        #[cfg(test)]
        if crate::simd::REFERENCE_ROWS.load(std::sync::atomic::Ordering::Relaxed) {
            let scratch = (
                &mut sad[..],
                &mut tmp[..],
                &mut mr[..],
                &mut md[..],
                &mut best[..],
            );
            match_row(col, tex, p, w, nd, r, orow, scratch);
            continue;
        }
        // The whole row is one window 0..nd: the coarse-to-fine tiles' row kernel applies as is.
        let ctx = RowCtx {
            w,
            nd,
            r,
            first: 0,
            len: nd,
            xa: r,
            xb: w - r,
            cx0: 0,
            filter: None,
            tex,
            texture_threshold: p.texture_threshold,
            uniqueness_ratio: p.uniqueness_ratio,
        };
        mr.fill(u16::MAX);
        md.fill(0);
        best.fill(u16::MAX);
        let mut o = RowOut {
            out: orow,
            best,
            mr,
            md,
        };
        tile_row(col, &ctx, &mut o, sad, tmp);
        lr_check_row(orow, best, md, p.lr_max_diff);
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

#[cfg(test)]
type RowScratch<'a> = (
    &'a mut [u16],
    &'a mut [u16],
    &'a mut [u16],
    &'a mut [u16],
    &'a mut [u16],
);

/// The row step before the register-resident kernel, kept as the reference it is tested against.
#[cfg(test)]
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
        out[xc] = subpixel_equiangular(sad, dmax, d);
    }
    lr_check_row(out, best, md, p.lr_max_diff);
}

dispatch_avx2!(fn match_band_tiled<'a, 'b, 'c, 'd>(inp: &'a LevelInput<'a>, p: &'b BmParams, g: &'c Guide<'c>, y0: usize, out: &'d mut [i16], s: &'d mut TileBand) => match_band_tiled_impl);

/// Coarse-to-fine band: strips of `TILE_H` rows, each cut into `TILE_W`-column tiles matched over
/// their own disparity window; the left-right check runs per row once the strip is done, on the
/// right-image minima gathered from every tile's costs.
#[inline(always)]
fn match_band_tiled_impl(
    inp: &LevelInput<'_>,
    p: &BmParams,
    g: &Guide<'_>,
    y0: usize,
    out: &mut [i16],
    s: &mut TileBand,
) {
    let (w, h, nd) = (inp.w, inp.h, inp.nd);
    let rs = w + nd;
    let r = p.block_size / 2;
    let y1 = y0 + out.len() / w;
    out.fill(INVALID);
    for sy in (y0..y1).step_by(TILE_H) {
        let (ya, yb) = (sy.max(r), (sy + TILE_H).min(y1).min(h - r));
        if ya >= yb {
            continue;
        }
        let rows = yb - ya;
        s.mr[..rows * rs].fill(u16::MAX);
        s.md[..rows * rs].fill(0);
        s.best[..rows * w].fill(u16::MAX);
        for sx in (0..w).step_by(TILE_W) {
            let (xa, xb) = (sx.max(r), (sx + TILE_W).min(w - r));
            if xa >= xb {
                continue;
            }
            let window = g.window(xa, xb, ya, yb, nd);
            // A wide window usually means a depth edge crosses the tile: its quarters, each on
            // one side of the edge more often than not, are searched over their own windows
            // when that saves enough lanes to pay for their extra column sums. Left before right
            // within each row keeps the right-image minima in the full search's order.
            let (xm, ym) = ((xa + xb) / 2, (ya + yb) / 2);
            let quarters = [
                (ya, ym, xa, xm),
                (ya, ym, xm, xb),
                (ym, yb, xa, xm),
                (ym, yb, xm, xb),
            ];
            let split = window.1 > 32 && xm > xa && ym > ya && {
                let lanes: usize = quarters
                    .iter()
                    .map(|&(y0, y1, x0, x1)| g.window(x0, x1, y0, y1, nd).1)
                    .sum();
                2 * lanes < 4 * window.1
            };
            let parts: &[(usize, usize, usize, usize)] = if split {
                &quarters
            } else {
                &[(ya, yb, xa, xb)]
            };
            for &(ty0, ty1, tx0, tx1) in parts {
                let (first, len) = if split {
                    g.window(tx0, tx1, ty0, ty1, nd)
                } else {
                    window
                };
                let uniqueness_ratio = if len == nd {
                    p.uniqueness_ratio
                } else {
                    p.refine_uniqueness_ratio
                };
                let tile = Tile {
                    strip: ya,
                    ya: ty0,
                    yb: ty1,
                    xa: tx0,
                    xb: tx1,
                    first,
                    uniqueness_ratio,
                };
                match_tile(inp, p, g, &tile, len, y0, out, s);
            }
        }
        for y in ya..yb {
            let i = y - ya;
            lr_check_row(
                &mut out[(y - y0) * w..][..w],
                &s.best[i * w..][..w],
                &s.md[i * rs..][..rs],
                p.lr_max_diff,
            );
        }
    }
}

/// Full-scale pixels `xa..xb` x `ya..yb` searched over disparities `first..first + len`.
struct Tile {
    /// First row of the strip (the rows of `TileBand::best`, `mr`, `md`).
    strip: usize,
    ya: usize,
    yb: usize,
    xa: usize,
    xb: usize,
    first: usize,
    uniqueness_ratio: u32,
}

/// What the per-pixel steps of one tile row read.
struct RowCtx<'a> {
    w: usize,
    nd: usize,
    r: usize,
    first: usize,
    len: usize,
    xa: usize,
    xb: usize,
    /// Full-scale column of the tile's first column sum (`xa - r`).
    cx0: usize,
    /// The multiscale filter, applied to each pixel that passed the other checks.
    filter: Option<RowFilter<'a>>,
    tex: &'a [u16],
    texture_threshold: u32,
    uniqueness_ratio: u32,
}

/// What one tile row writes: output row, integer disparities and the right-image minima.
struct RowOut<'a> {
    out: &'a mut [i16],
    best: &'a mut [u16],
    mr: &'a mut [u16],
    md: &'a mut [u16],
}

/// Incremental SAD over one tile's window (column sums down the rows, window sums along x), then
/// per pixel the same steps as the full search: argmin fused with the right-image minima,
/// texture, uniqueness, subpixel. With the window `0..nd` the result equals `match_band`'s.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn match_tile(
    inp: &LevelInput<'_>,
    p: &BmParams,
    g: &Guide<'_>,
    t: &Tile,
    len: usize,
    y0: usize,
    out: &mut [i16],
    s: &mut TileBand,
) {
    let (w, nd) = (inp.w, inp.nd);
    let rs = w + nd;
    let r = p.block_size / 2;
    let first = t.first;
    let cx0 = t.xa - r;
    let nc = t.xb - t.xa + 2 * r;
    let col = &mut s.col[..nc * len];
    let lrow = |y: usize| &inp.lp[y * w + cx0..y * w + cx0 + nc];
    // Mirrored right row from the first disparity of column cx0: column i, disparity k is at
    // `nc - 1 - i + k` (right pixel cx0 + i - first - k).
    let rrow = |y: usize| &inp.rp[y * rs + w - cx0 - nc + first..][..nc - 1 + len];
    let vectors = len / 16;
    col.fill(0);
    for y in t.ya - r..=t.ya + r {
        tile_col_add(col, lrow(y), rrow(y), vectors);
    }
    for y in t.ya..t.yb {
        if y > t.ya {
            tile_col_update(
                col,
                [lrow(y + r), lrow(y - r - 1)],
                [rrow(y + r), rrow(y - r - 1)],
                vectors,
            );
        }
        let row = y - t.strip;
        let ctx = RowCtx {
            w,
            nd,
            r,
            first,
            len,
            xa: t.xa,
            xb: t.xb,
            cx0,
            filter: (p.multiscale_max_diff >= 0.0).then(|| {
                let keep = p.multiscale_keep_unmatched;
                RowFilter::new(g.disp, g.w2, g.h2, y, p.multiscale_max_diff, keep)
            }),
            tex: &inp.tex[y * w..][..w],
            texture_threshold: p.texture_threshold,
            uniqueness_ratio: t.uniqueness_ratio,
        };
        let mut o = RowOut {
            out: &mut out[(y - y0) * w..][..w],
            best: &mut s.best[row * w..][..w],
            mr: &mut s.mr[row * rs..][..rs],
            md: &mut s.md[row * rs..][..rs],
        };
        tile_row(col, &ctx, &mut o, &mut s.sad[..len], &mut s.tmp[..len]);
    }
}

/// Calls `$f::<V>(args)` for the vector count `$v` in 1..=8 (a window of up to 128
/// disparities held in registers); `$other` otherwise.
#[cfg(target_arch = "x86_64")]
macro_rules! by_vectors {
    ($v:expr, $f:ident($($a:expr),*), $other:expr) => {
        match $v {
            1 => $f::<1>($($a),*),
            2 => $f::<2>($($a),*),
            3 => $f::<3>($($a),*),
            4 => $f::<4>($($a),*),
            5 => $f::<5>($($a),*),
            6 => $f::<6>($($a),*),
            7 => $f::<7>($($a),*),
            8 => $f::<8>($($a),*),
            _ => $other,
        }
    };
}

/// `col[i][k] += |l[i] - r[nc - 1 - i + k]|` for `vectors` x 16 disparities.
#[inline(always)]
fn tile_col_add(col: &mut [u16], l: &[u8], r: &[u8], vectors: usize) {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::has_avx2() {
        // SAFETY: AVX2 is present; the kernel checks its slice lengths.
        unsafe {
            by_vectors!(
                vectors,
                col_add_avx2(col, l, r),
                tile_col_add_scalar(col, l, r, vectors * 16)
            )
        };
        return;
    }
    tile_col_add_scalar(col, l, r, vectors * 16)
}

#[inline(always)]
fn tile_col_add_scalar(col: &mut [u16], l: &[u8], r: &[u8], len: usize) {
    let nc = l.len();
    for (i, c) in col.chunks_exact_mut(len).enumerate() {
        let a = l[i];
        for (c, &b) in c.iter_mut().zip(&r[nc - 1 - i..][..len]) {
            *c += absdiff(a, b);
        }
    }
}

/// One row down: add row `l[0]`/`r[0]`, remove row `l[1]`/`r[1]`.
#[inline(always)]
fn tile_col_update(col: &mut [u16], l: [&[u8]; 2], r: [&[u8]; 2], vectors: usize) {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::has_avx2() {
        // SAFETY: AVX2 is present; the kernel checks its slice lengths.
        unsafe {
            by_vectors!(
                vectors,
                col_update_avx2(col, l, r),
                tile_col_update_scalar(col, l, r, vectors * 16)
            )
        };
        return;
    }
    tile_col_update_scalar(col, l, r, vectors * 16)
}

#[inline(always)]
fn tile_col_update_scalar(col: &mut [u16], l: [&[u8]; 2], r: [&[u8]; 2], len: usize) {
    let nc = l[0].len();
    for (i, c) in col.chunks_exact_mut(len).enumerate() {
        let (a, b) = (l[0][i], l[1][i]);
        let (rn, ro) = (&r[0][nc - 1 - i..][..len], &r[1][nc - 1 - i..][..len]);
        for ((c, &n), &o) in c.iter_mut().zip(rn).zip(ro) {
            *c = c.wrapping_add(absdiff(a, n)).wrapping_sub(absdiff(b, o));
        }
    }
}

/// The per-pixel steps of one tile row.
#[inline(always)]
fn tile_row(col: &[u16], c: &RowCtx<'_>, o: &mut RowOut<'_>, sad: &mut [u16], tmp: &mut [u16]) {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::has_avx2() {
        // SAFETY: AVX2 is present; the kernel checks its slice lengths.
        unsafe {
            by_vectors!(
                c.len / 16,
                tile_row_avx2(col, c, o, sad, tmp),
                tile_row_scalar(col, c, o, sad, tmp)
            )
        };
        return;
    }
    tile_row_scalar(col, c, o, sad, tmp)
}

/// Reference path (also any CPU without AVX2).
#[inline(always)]
fn tile_row_scalar(
    col: &[u16],
    c: &RowCtx<'_>,
    o: &mut RowOut<'_>,
    sad: &mut [u16],
    tmp: &mut [u16],
) {
    let (len, r) = (c.len, c.r);
    let colx = |i: usize| &col[i * len..(i + 1) * len];
    sad.fill(0);
    for i in 0..=2 * r {
        for (s, c) in sad.iter_mut().zip(colx(i)) {
            *s += c;
        }
    }
    for xc in c.xa..c.xb {
        let i = xc - c.cx0;
        if xc > c.xa {
            for ((s, &a), &b) in sad.iter_mut().zip(colx(i + r)).zip(colx(i - r - 1)) {
                *s = s.wrapping_add(a).wrapping_sub(b);
            }
        }
        let dmax = (c.nd - 1).min(xc - r);
        if dmax < c.first {
            continue;
        }
        let top = (dmax - c.first).min(len - 1);
        let j = c.w - 1 - xc + c.first;
        let base = c.first as u16;
        let (d, m) = if top == len - 1 {
            argmin_lr_from(sad, None, &mut o.mr[j..], &mut o.md[j..], base)
        } else {
            argmin_lr_partial_from(sad, top, tmp, &mut o.mr[j..], &mut o.md[j..], base)
        };
        if (c.tex[xc] as u32) < c.texture_threshold
            || !is_unique(sad, top, d, m, c.uniqueness_ratio)
        {
            continue;
        }
        finish_pixel(sad, c, o, xc, dmax, top, d);
    }
}

/// Window-edge rule, then the result: a minimum on an edge of the window that is not an edge of
/// the whole range is no local minimum (the search does not know what lies beyond it).
#[inline(always)]
fn finish_pixel(
    sad: &[u16],
    c: &RowCtx<'_>,
    o: &mut RowOut<'_>,
    xc: usize,
    dmax: usize,
    top: usize,
    d: usize,
) {
    if (d == 0 && c.first > 0) || (d == top && c.first + top < dmax) {
        return;
    }
    let v = subpixel_f32(sad, top, d) + c.first as i16 * DISP_SCALE;
    if let Some(f) = &c.filter {
        if !f.keeps(xc, v) {
            return;
        }
    }
    o.best[xc] = (c.first + d) as u16;
    o.out[xc] = v;
}

/// `subpixel_equiangular` with a float division, which is faster than the integer one: the
/// same result, because |num / den| <= 8 with den < 2^18 keeps the quotient at least 2^-20 away
/// from a rounding boundary unless it is on one exactly, where f32 is exact (and `round` also
/// rounds halves away from zero). The tests compare the two through the reference path.
#[inline(always)]
fn subpixel_f32(costs: &[u16], dmax: usize, d: usize) -> i16 {
    let base = (d as i32) * DISP_SCALE as i32;
    if d == 0 || d >= dmax {
        return base as i16;
    }
    let (p, c, n) = (costs[d - 1] as i32, costs[d] as i32, costs[d + 1] as i32);
    let den = 2 * (p.max(n) - c);
    if den <= 0 {
        return base as i16;
    }
    let num = (p - n) * DISP_SCALE as i32;
    (base + (num as f32 / den as f32).round() as i32) as i16
}

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn col_add_avx2<const V: usize>(col: &mut [u16], l: &[u8], r: &[u8]) {
    let nc = l.len();
    assert!(col.len() >= nc * 16 * V && r.len() >= nc - 1 + 16 * V);
    let (cp, rp) = (col.as_mut_ptr(), r.as_ptr());
    for (i, &a) in l.iter().enumerate() {
        let a = _mm256_set1_epi16(a as i16);
        let (c, rb) = (cp.add(i * 16 * V), rp.add(nc - 1 - i));
        for v in 0..V {
            let b = _mm256_cvtepu8_epi16(_mm_loadu_si128(rb.add(16 * v) as *const __m128i));
            let cv = _mm256_loadu_si256(c.add(16 * v) as *const __m256i);
            let cv = _mm256_add_epi16(cv, _mm256_abs_epi16(_mm256_sub_epi16(a, b)));
            _mm256_storeu_si256(c.add(16 * v) as *mut __m256i, cv);
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn col_update_avx2<const V: usize>(col: &mut [u16], l: [&[u8]; 2], r: [&[u8]; 2]) {
    let nc = l[0].len();
    assert!(l[1].len() == nc && col.len() >= nc * 16 * V);
    assert!(r[0].len() >= nc - 1 + 16 * V && r[1].len() >= nc - 1 + 16 * V);
    let (cp, rn, ro) = (col.as_mut_ptr(), r[0].as_ptr(), r[1].as_ptr());
    for (i, (&a, &b)) in l[0].iter().zip(l[1]).enumerate() {
        let a = _mm256_set1_epi16(a as i16);
        let b = _mm256_set1_epi16(b as i16);
        let (c, rn, ro) = (cp.add(i * 16 * V), rn.add(nc - 1 - i), ro.add(nc - 1 - i));
        for v in 0..V {
            let n = _mm256_cvtepu8_epi16(_mm_loadu_si128(rn.add(16 * v) as *const __m128i));
            let o = _mm256_cvtepu8_epi16(_mm_loadu_si128(ro.add(16 * v) as *const __m128i));
            let cv = _mm256_loadu_si256(c.add(16 * v) as *const __m256i);
            let cv = _mm256_add_epi16(cv, _mm256_abs_epi16(_mm256_sub_epi16(a, n)));
            let cv = _mm256_sub_epi16(cv, _mm256_abs_epi16(_mm256_sub_epi16(b, o)));
            _mm256_storeu_si256(c.add(16 * v) as *mut __m256i, cv);
        }
    }
}

/// `NEAR[NEAR_AT + 1 - d + k]` is u16::MAX exactly for k in d-1..=d+1 (any d < 128, k < 128):
/// the lanes the uniqueness test skips.
const NEAR_AT: usize = 128;
static NEAR: [u16; 2 * NEAR_AT + 16] = {
    let mut a = [0u16; 2 * NEAR_AT + 16];
    a[NEAR_AT] = u16::MAX;
    a[NEAR_AT + 1] = u16::MAX;
    a[NEAR_AT + 2] = u16::MAX;
    a
};

/// `tile_row_scalar` with the window's costs held in `V` registers across the row: the slide,
/// argmin, right-image minima and second minimum never leave them; they are stored only for the
/// subpixel step of a pixel that passed every check (or for the rare pixel at the left border).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn tile_row_avx2<const V: usize>(
    col: &[u16],
    c: &RowCtx<'_>,
    o: &mut RowOut<'_>,
    sad: &mut [u16],
    tmp: &mut [u16],
) {
    let (len, r, w) = (16 * V, c.r, c.w);
    assert!(V <= 8 && c.len == len && sad.len() == len && tmp.len() >= len);
    assert!(col.len() >= (c.xb - c.cx0 + r) * len && c.xa >= c.cx0 + r);
    assert!(c.tex.len() >= c.xb && o.out.len() >= c.xb && o.best.len() >= c.xb);
    // Right-image minima are read at w - 1 - xc + first + k, xc >= xa, k < len.
    assert!(o.mr.len() >= w - c.xa + c.first + len - 1 && o.md.len() == o.mr.len());
    let cp = col.as_ptr();
    let load = |p: *const u16| _mm256_loadu_si256(p as *const __m256i);
    let mut s = [_mm256_setzero_si256(); V];
    for i in 0..=2 * r {
        for (v, sv) in s.iter_mut().enumerate() {
            *sv = _mm256_add_epi16(*sv, load(cp.add(i * len + 16 * v)));
        }
    }
    // Absolute disparities of each lane, recorded with the right-image minima.
    let lanes = _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let mut idxs = [_mm256_setzero_si256(); V];
    for (v, idx) in idxs.iter_mut().enumerate() {
        *idx = _mm256_add_epi16(lanes, _mm256_set1_epi16((c.first + 16 * v) as i16));
    }
    for xc in c.xa..c.xb {
        let i = xc - c.cx0;
        if xc > c.xa {
            let (add, sub) = (cp.add((i + r) * len), cp.add((i - r - 1) * len));
            for (v, sv) in s.iter_mut().enumerate() {
                let t = _mm256_add_epi16(*sv, load(add.add(16 * v)));
                *sv = _mm256_sub_epi16(t, load(sub.add(16 * v)));
            }
        }
        let dmax = (c.nd - 1).min(xc - r);
        if dmax < c.first {
            continue;
        }
        let top = (dmax - c.first).min(len - 1);
        let j = w - 1 - xc + c.first;
        if top < len - 1 {
            // Left image border: part of the window is impossible; the portable steps mask it.
            for (v, sv) in s.iter().enumerate() {
                _mm256_storeu_si256(sad.as_mut_ptr().add(16 * v) as *mut __m256i, *sv);
            }
            let base = c.first as u16;
            let (d, m) =
                argmin_lr_partial_from(sad, top, tmp, &mut o.mr[j..], &mut o.md[j..], base);
            if (c.tex[xc] as u32) >= c.texture_threshold
                && is_unique(sad, top, d, m, c.uniqueness_ratio)
            {
                finish_pixel(sad, c, o, xc, dmax, top, d);
            }
            continue;
        }
        // Right-image minima (ties keep the smaller d, as in `argmin_lr_avx2`) and the minimum.
        let (mrp, mdp) = (o.mr.as_mut_ptr().add(j), o.md.as_mut_ptr().add(j));
        let mut m = s[0];
        for (v, (&x, &idx)) in s.iter().zip(&idxs).enumerate() {
            m = _mm256_min_epu16(m, x);
            let rv = load(mrp.add(16 * v));
            let nr = _mm256_min_epu16(x, rv);
            _mm256_storeu_si256(mrp.add(16 * v) as *mut __m256i, nr);
            let mv = load(mdp.add(16 * v));
            let md = _mm256_blendv_epi8(idx, mv, _mm256_cmpeq_epi16(nr, rv));
            _mm256_storeu_si256(mdp.add(16 * v) as *mut __m256i, md);
        }
        if (c.tex[xc] as u32) < c.texture_threshold {
            continue;
        }
        let m8 = _mm_min_epu16(_mm256_castsi256_si128(m), _mm256_extracti128_si256(m, 1));
        let min = _mm_extract_epi16(_mm_minpos_epu16(m8), 0) as u16;
        // Smallest d holding the minimum: first vector with a hit, lowest lane (2 mask bits each).
        let minv = _mm256_set1_epi16(min as i16);
        let mut d = 0;
        for (v, &x) in s.iter().enumerate() {
            let hits = _mm256_movemask_epi8(_mm256_cmpeq_epi16(x, minv)) as u32;
            if hits != 0 {
                d = 16 * v + hits.trailing_zeros() as usize / 2;
                break;
            }
        }
        if c.uniqueness_ratio > 0 {
            // Second minimum over d outside d-1..=d+1: those lanes are masked to u16::MAX.
            let near = NEAR.as_ptr().add(NEAR_AT + 1 - d);
            let mut m2 = _mm256_set1_epi16(-1);
            for (v, &x) in s.iter().enumerate() {
                m2 = _mm256_min_epu16(m2, _mm256_or_si256(x, load(near.add(16 * v))));
            }
            let m8 = _mm_min_epu16(_mm256_castsi256_si128(m2), _mm256_extracti128_si256(m2, 1));
            let second = _mm_extract_epi16(_mm_minpos_epu16(m8), 0) as u32;
            let thresh = min as u32 + min as u32 * c.uniqueness_ratio / 100;
            if second <= thresh {
                continue;
            }
        }
        for (v, sv) in s.iter().enumerate() {
            _mm256_storeu_si256(sad.as_mut_ptr().add(16 * v) as *mut __m256i, *sv);
        }
        finish_pixel(sad, c, o, xc, dmax, top, d);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{FORCE_SCALAR, REFERENCE_ROWS};
    use std::sync::atomic::Ordering::Relaxed;
    use std::sync::Mutex;

    /// The path switches are process-wide: tests that flip them take turns.
    static SWITCHES: Mutex<()> = Mutex::new(());

    fn xorshift(s: &mut u64) -> u64 {
        *s ^= *s << 13;
        *s ^= *s >> 7;
        *s ^= *s << 17;
        *s
    }

    /// Random texture (smoothed a little so the x-Sobel is not saturated everywhere) seen with a
    /// disparity that steps between regions (occlusions, depth edges), noise, and a flat patch
    /// (texture check). The disparity is defined on the right image: R(x) = L(x + d(x)).
    fn pair(w: usize, h: usize, nd: usize, seed: u64) -> (Vec<u8>, Vec<u8>) {
        let mut s = seed;
        let wide = w + nd;
        let noise: Vec<u8> = (0..wide * h)
            .map(|_| (xorshift(&mut s) >> 56) as u8)
            .collect();
        let tex = |x: usize, y: usize| {
            let a = noise[y * wide + x] as u16 + noise[y * wide + (x + 1).min(wide - 1)] as u16;
            (a / 2) as u8
        };
        let disp = |x: usize, y: usize| {
            let d = 3 + (x * 7 / w) * (nd / 9) + (y * 3 / h) * 2;
            d.min(nd - 1)
        };
        let mut l = vec![0u8; w * h];
        let mut r = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let n = (xorshift(&mut s) >> 61) as u8;
                l[y * w + x] = tex(x, y).saturating_add(n);
                r[y * w + x] = tex(x + disp(x, y), y);
            }
        }
        for y in h / 3..h / 2 {
            for x in w / 3..w / 2 {
                l[y * w + x] = 120;
                r[y * w + x] = 120;
            }
        }
        (l, r)
    }

    fn params(nd: usize, block_size: usize) -> BmParams {
        BmParams {
            num_disparities: nd,
            block_size,
            ..Default::default()
        }
    }

    fn run_level(
        l: &[u8],
        r: &[u8],
        w: usize,
        h: usize,
        p: &BmParams,
        g: Option<&Guide>,
    ) -> Vec<i16> {
        let mut level = Level::new(w, h, p.num_disparities, p.block_size / 2, g.is_some());
        let mut out = vec![0; w * h];
        level.run(l, r, p, &mut out, g);
        out
    }

    fn with_switches<T>(scalar: bool, reference: bool, f: impl FnOnce() -> T) -> T {
        FORCE_SCALAR.store(scalar, Relaxed);
        REFERENCE_ROWS.store(reference, Relaxed);
        let t = f();
        FORCE_SCALAR.store(false, Relaxed);
        REFERENCE_ROWS.store(false, Relaxed);
        t
    }

    /// Sizes and ranges that hit every vector count of the row kernel (1..=8 and the fallback
    /// past 8), the left-border partial windows and bands shorter than the window.
    const CASES: [(usize, usize, usize, usize); 6] = [
        (97, 41, 16, 9),
        (130, 60, 48, 5),
        (160, 37, 64, 9),
        (203, 75, 128, 7),
        (240, 50, 144, 9),
        (64, 24, 32, 3),
    ];

    #[test]
    fn full_search_kernels_equal_reference() {
        let _g = SWITCHES.lock().unwrap_or_else(|e| e.into_inner());
        for (i, &(w, h, nd, bs)) in CASES.iter().enumerate() {
            let (l, r) = pair(w, h, nd, 7 + i as u64);
            let p = params(nd, bs);
            let reference = with_switches(true, true, || run_level(&l, &r, w, h, &p, None));
            let valid = reference.iter().filter(|&&v| v >= 0).count();
            println!("case {i}: {valid} of {} valid", w * h);
            assert!(valid > w * h / 3, "case {i}: only {valid} valid pixels");
            for (scalar, refrows) in [(false, false), (true, false), (false, true)] {
                let got = with_switches(scalar, refrows, || run_level(&l, &r, w, h, &p, None));
                assert!(
                    got == reference,
                    "case {i}, scalar {scalar}, reference rows {refrows}"
                );
            }
        }
    }

    #[test]
    fn tiles_with_full_windows_equal_full_search() {
        let _g = SWITCHES.lock().unwrap_or_else(|e| e.into_inner());
        for (i, &(w, h, nd, bs)) in CASES.iter().enumerate() {
            let (l, r) = pair(w, h, nd, 11 + i as u64);
            // No half-scale match anywhere: every tile searches 0..nd. No multiscale filter.
            let p = BmParams {
                multiscale_max_diff: -1.0,
                ..params(nd, bs)
            };
            let coarse = vec![INVALID; (w / 2) * (h / 2)];
            let g = Guide {
                disp: &coarse,
                w2: w / 2,
                h2: h / 2,
                margin: 4,
            };
            let reference = with_switches(true, true, || run_level(&l, &r, w, h, &p, None));
            for scalar in [false, true] {
                let got = with_switches(scalar, false, || run_level(&l, &r, w, h, &p, Some(&g)));
                assert!(got == reference, "case {i}, scalar {scalar}");
            }
        }
    }

    #[test]
    fn narrowed_windows_agree_between_scalar_and_avx2() {
        let _g = SWITCHES.lock().unwrap_or_else(|e| e.into_inner());
        for (i, &(w, h, nd, bs)) in CASES.iter().enumerate() {
            let (l, r) = pair(w, h, nd, 13 + i as u64);
            let p = params(nd, bs);
            let mut m = BlockMatcher::new(p, w, h).unwrap();
            let (lv, rv) = (
                GrayView::new(w, h, &l).unwrap(),
                GrayView::new(w, h, &r).unwrap(),
            );
            let mut run = |scalar| {
                let mut out = DisparityMap::new(w, h);
                with_switches(scalar, false, || m.compute(lv, rv, &mut out)).unwrap();
                out
            };
            let (fast, slow) = (run(false), run(true));
            assert!(fast.density() > 0.3, "case {i}: density {}", fast.density());
            // The half scale matched enough for many tiles to get a narrowed window.
            let coarse = &m.coarse.as_ref().unwrap().disp;
            let matched = coarse.iter().filter(|&&v| v >= 0).count();
            assert!(matched > coarse.len() / 4, "case {i}: coarse {matched}");
            assert!(fast == slow, "case {i}");
        }
    }

    #[test]
    fn windows_cover_twice_the_coarse_range() {
        let (w2, h2, nd) = (40, 20, 128);
        let mut coarse = vec![INVALID; w2 * h2];
        // Half-scale 10.5 and 13 px under full-scale columns 32..64, rows 16..32.
        coarse[8 * w2 + 16] = 168;
        coarse[15 * w2 + 31] = 208;
        let g = Guide {
            disp: &coarse,
            w2,
            h2,
            margin: 4,
        };
        let (first, len) = g.window(32, 64, 16, 32, nd);
        assert_eq!(len % 16, 0);
        assert!(first <= 21 - 4 && first + len > 26 + 4, "{first} {len}");
        assert!(len <= 32, "{len}");
        // Nothing matched under the tile: the whole range.
        assert_eq!(g.window(0, 32, 0, 16, nd), (0, nd));
        // Near the top of the range the window stays inside it.
        let mut top = coarse.clone();
        top[0] = 63 * 16;
        let g = Guide { disp: &top, ..g };
        let (first, len) = g.window(0, 32, 0, 16, nd);
        assert!(first + len == nd && first <= 126 - 4, "{first} {len}");
    }

    #[test]
    fn float_subpixel_equals_integer_subpixel() {
        let mut n = 0;
        for c in [0u16, 1, 7, 100, 1000, 9000] {
            for p in (c..c.saturating_add(3000)).step_by(7) {
                for q in (c..c.saturating_add(3000)).step_by(5) {
                    let costs = [p, c, q];
                    assert_eq!(
                        subpixel_f32(&costs, 2, 1),
                        subpixel_equiangular(&costs, 2, 1),
                        "{costs:?}"
                    );
                    n += 1;
                }
            }
        }
        for costs in [
            [65535, 0, 65534],
            [65535, 1, 65535],
            [3, 1, 2],
            [2, 1, 3],
            [5, 5, 5],
        ] {
            assert_eq!(
                subpixel_f32(&costs, 2, 1),
                subpixel_equiangular(&costs, 2, 1),
                "{costs:?}"
            );
        }
        assert!(n > 100_000);
    }

    #[test]
    fn argmin_from_offset_matches_scalar() {
        let _g = SWITCHES.lock().unwrap_or_else(|e| e.into_inner());
        let mut s = 5u64;
        for n in [16usize, 32, 64, 128] {
            for base in [0u16, 3, 40] {
                let costs: Vec<u16> = (0..n).map(|_| (xorshift(&mut s) % 50) as u16).collect();
                let mut mr: Vec<u16> = (0..n).map(|_| (xorshift(&mut s) % 60) as u16).collect();
                let mut md = vec![7u16; n];
                let (mut mr2, mut md2) = (mr.clone(), md.clone());
                let (mut c1, mut c2) = (costs.clone(), costs.clone());
                let a = argmin_lr_from(&mut c1, None, &mut mr, &mut md, base);
                let b = crate::disparity::argmin_lr_scalar(&mut c2, None, &mut mr2, &mut md2, base);
                assert_eq!((a, &mr, &md), (b, &mr2, &md2), "n {n} base {base}");
            }
        }
    }
}
