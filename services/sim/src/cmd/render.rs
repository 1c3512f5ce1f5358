//! `sim render`: one frame of a scenario to PNG, for inspection and documentation.

use anyhow::{bail, Context, Result};
use sim::{render::labels_to_rgb, Command, Encoding};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Scenario time of the frame, seconds. The vehicle drives on with the throttle it started with.
    #[arg(long, default_value_t = 0.0)]
    time: f64,
    /// Stereo head name (default: the scenario's first head).
    #[arg(long)]
    head: Option<String>,
    /// Output PNG for the left image.
    #[arg(long)]
    out: PathBuf,
    /// Also write the right image here.
    #[arg(long)]
    right: Option<PathBuf>,
    /// Also write ground-truth disparity (in the rectified left view), as an 8-bit PNG scaled to its
    /// maximum.
    #[arg(long)]
    truth_disparity: Option<PathBuf>,
    /// Also write ground-truth labels (in the rectified left view) as a colour PNG.
    #[arg(long)]
    labels: Option<PathBuf>,
    /// Downscale all outputs by this integer factor (box filter), e.g. for documentation thumbnails.
    #[arg(long, default_value_t = 1)]
    downscale: u32,
    /// Render every head at this fraction of its resolution (same field of view).
    #[arg(long, default_value_t = 1.0)]
    head_scale: f64,
}

pub fn run(args: Args) -> Result<()> {
    if args.downscale == 0 {
        bail!("--downscale must be at least 1");
    }
    if !(args.time.is_finite() && args.time >= 0.0) {
        bail!("--time must be a non-negative number of seconds");
    }
    let mut sim = super::load(&args.scenario, args.head_scale)?;
    let head = match &args.head {
        Some(name) => sim.world.head_index(name).with_context(|| {
            let names: Vec<_> = sim.world.heads.iter().map(|h| h.name.as_str()).collect();
            format!(
                "no head `{name}` in the scenario (heads: {})",
                names.join(", ")
            )
        })?,
        None => 0,
    };
    // Hold the starting throttle, rudder amidships, up to the requested time.
    let cmd = Command {
        rudder: 0.0,
        throttle: sim.state().throttle,
    };
    let dt: f64 = 0.05;
    while sim.time() + 1e-9 < args.time {
        sim.step(cmd, dt.min(args.time - sim.time()));
    }
    let h = sim.world.heads[head].clone();
    let (w, ht) = (h.width, h.height);
    let mut left = vec![0u8; h.image_len()];
    let mut right = vec![0u8; h.image_len()];
    sim.render_head(head, &mut left, &mut right)?;
    let color = h.encoding == Encoding::Rgb8;
    save(&args.out, &left, w, ht, color, args.downscale)?;
    if let Some(p) = &args.right {
        save(p, &right, w, ht, color, args.downscale)?;
    }
    if args.truth_disparity.is_some() || args.labels.is_some() {
        // Truth is in the rectified left view (the left image itself for an ideal head).
        let view = h.rectified()?;
        let (w, ht) = (view.width as u32, view.height as u32);
        let mut disp = vec![0f32; view.width * view.height];
        let mut labels = vec![0u8; view.width * view.height];
        sim.render_truth_view(head, &view, &mut disp, &mut labels)?;
        if let Some(p) = &args.truth_disparity {
            let max = disp
                .iter()
                .copied()
                .filter(|d| d.is_finite())
                .fold(0.0f32, f32::max);
            let scale = if max > 0.0 { 255.0 / max } else { 0.0 };
            let grey: Vec<u8> = disp
                .iter()
                .map(|d| (d * scale).clamp(0.0, 255.0) as u8)
                .collect();
            save(p, &grey, w, ht, false, args.downscale)?;
            eprintln!("truth disparity: max {max:.1} px (white)");
        }
        if let Some(p) = &args.labels {
            let mut rgb = vec![0u8; labels.len() * 3];
            labels_to_rgb(&labels, &mut rgb);
            save(p, &rgb, w, ht, true, args.downscale)?;
        }
    }
    Ok(())
}

fn save(path: &PathBuf, data: &[u8], w: u32, h: u32, color: bool, down: u32) -> Result<()> {
    let ch = if color { 3 } else { 1 };
    let (data, w, h) = if down > 1 {
        (downscale(data, w, h, ch, down), w / down, h / down)
    } else {
        (data.to_vec(), w, h)
    };
    let ct = if color {
        image::ExtendedColorType::Rgb8
    } else {
        image::ExtendedColorType::L8
    };
    image::save_buffer(path, &data, w, h, ct).with_context(|| format!("writing {}", path.display()))
}

fn downscale(data: &[u8], w: u32, h: u32, ch: usize, f: u32) -> Vec<u8> {
    let (nw, nh, f) = ((w / f) as usize, (h / f) as usize, f as usize);
    let w = w as usize;
    let mut out = vec![0u8; nw * nh * ch];
    for y in 0..nh {
        for x in 0..nw {
            for c in 0..ch {
                let mut s = 0u32;
                for dy in 0..f {
                    for dx in 0..f {
                        s += data[((y * f + dy) * w + x * f + dx) * ch + c] as u32;
                    }
                }
                out[(y * nw + x) * ch + c] = (s / (f * f) as u32) as u8;
            }
        }
    }
    out
}
