//! `stereo match`: offline matching of an image pair from files.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};

use stereo::bm::BmParams;
use stereo::calib::{Calibration, Rectifier};
use stereo::disparity::DISP_SCALE;
use stereo::sgm::SgmParams;
use stereo::{build_matcher, DisparityMap, GrayImage, MatcherConfig};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Algo {
    Bm,
    Sgm,
}

/// Match a rectified (or, with --calib, raw) image pair and write the left disparity.
#[derive(Args, Debug)]
#[command(after_help = "Output by extension of --out:\n  \
    .png  16-bit grayscale, value = disparity x 256, 0 = invalid (a valid zero disparity is \
    written as 1)\n  \
    .pfm  32-bit float, disparity in pixels, +inf = invalid\n\
    Convention: left pixel x matches right pixel x - d.")]
pub struct MatchArgs {
    /// Left image (PNG or JPEG; converted to 8-bit gray).
    #[arg(long)]
    left: PathBuf,
    /// Right image (PNG or JPEG).
    #[arg(long)]
    right: PathBuf,
    /// Calibration TOML: rectify the pair first (images must have the calibrated size).
    #[arg(long)]
    calib: Option<PathBuf>,
    /// Number of disparities searched, 0..N (multiple of 16, at most 256).
    #[arg(long)]
    ndisp: usize,
    #[arg(long, value_enum, default_value_t = Algo::Bm)]
    algo: Algo,
    /// Matching window side (BM only, odd).
    #[arg(long)]
    block_size: Option<usize>,
    /// Matcher parameters as TOML (`algo = "bm"` or `"sgm"` plus that matcher's fields);
    /// overrides --algo and --block-size, --ndisp still applies.
    #[arg(long)]
    params: Option<PathBuf>,
    /// Output disparity (.png or .pfm).
    #[arg(long)]
    out: PathBuf,
    /// Match this many times and print the median matching time (file I/O and rectification
    /// excluded).
    #[arg(long, default_value_t = 1)]
    repeat: usize,
}

pub fn run(a: MatchArgs) -> Result<()> {
    let ext = a
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("png" | "pfm")) {
        bail!("--out {}: extension must be .png or .pfm", a.out.display());
    }
    let mut left = load_gray(&a.left)?;
    let mut right = load_gray(&a.right)?;
    if let Some(path) = &a.calib {
        let calib = Calibration::load(path)?;
        let rect = Rectifier::new(&calib).context("building rectification")?;
        left = rect.rectify_left(left.view()).context("left image")?;
        right = rect.rectify_right(right.view()).context("right image")?;
    }
    if (left.width, left.height) != (right.width, right.height) {
        bail!(
            "left is {}x{} but right is {}x{}",
            left.width,
            left.height,
            right.width,
            right.height
        );
    }
    let mut config = match a.algo {
        Algo::Bm => MatcherConfig::Bm(BmParams {
            num_disparities: a.ndisp,
            block_size: a.block_size.unwrap_or(BmParams::default().block_size),
            ..Default::default()
        }),
        Algo::Sgm => MatcherConfig::Sgm(SgmParams {
            num_disparities: a.ndisp,
            ..Default::default()
        }),
    };
    if let Some(path) = &a.params {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        config = toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
        match &mut config {
            MatcherConfig::Bm(p) => p.num_disparities = a.ndisp,
            MatcherConfig::Sgm(p) => p.num_disparities = a.ndisp,
        }
    }
    let mut matcher = build_matcher(&config, left.width, left.height)?;
    let mut disp = DisparityMap::new(left.width, left.height);
    let mut times = Vec::with_capacity(a.repeat.max(1));
    for _ in 0..a.repeat.max(1) {
        let t = Instant::now();
        matcher.compute(left.view(), right.view(), &mut disp)?;
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    println!(
        "{} {}x{} ndisp {}: median matching time {:.3} ms (best {:.3} ms) over {} runs, density {:.1}%",
        matcher.name(),
        left.width,
        left.height,
        a.ndisp,
        median * 1e3,
        times[0] * 1e3,
        times.len(),
        disp.density() * 100.0
    );
    match ext.as_deref() {
        Some("png") => write_png16(&a.out, &disp),
        _ => write_pfm(&a.out, &disp),
    }
    .with_context(|| format!("writing {}", a.out.display()))
}

fn load_gray(path: &Path) -> Result<GrayImage> {
    let img = image::open(path)
        .with_context(|| format!("reading {}", path.display()))?
        .to_luma8();
    let (w, h) = img.dimensions();
    Ok(GrayImage::from_vec(w as usize, h as usize, img.into_raw())?)
}

fn write_png16(path: &Path, disp: &DisparityMap) -> Result<()> {
    let k = 256 / DISP_SCALE as i32;
    let px: Vec<u16> = disp
        .data
        .iter()
        .map(|&v| {
            if v < 0 {
                0
            } else {
                (v as i32 * k).clamp(1, 65535) as u16
            }
        })
        .collect();
    let buf = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(
        disp.width as u32,
        disp.height as u32,
        px,
    )
    .context("disparity buffer size")?;
    buf.save(path)?;
    Ok(())
}

fn write_pfm(path: &Path, disp: &DisparityMap) -> Result<()> {
    let mut f = BufWriter::new(std::fs::File::create(path)?);
    // Negative scale = little endian; rows go bottom to top.
    write!(f, "Pf\n{} {}\n-1.0\n", disp.width, disp.height)?;
    for row in disp.data.chunks_exact(disp.width).rev() {
        for &v in row {
            let d = if v < 0 {
                f32::INFINITY
            } else {
                v as f32 / DISP_SCALE as f32
            };
            f.write_all(&d.to_le_bytes())?;
        }
    }
    f.flush()?;
    Ok(())
}
