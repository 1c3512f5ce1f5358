//! `sim calib`: writes a simulated head's calibration in the stereo service's format (OpenCV
//! conventions: `X_r = R X_l + T`), and the left camera's mounting on the body as a `[mount]` table
//! for the stereo service's configuration. The simulated heads are ideal rectified pairs, so
//! distortion is zero and R is the identity.

use anyhow::{Context, Result};
use nalgebra::Vector3;
use std::fmt::Write;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Stereo head name (default: the first mono head, else the first head).
    #[arg(long)]
    head: Option<String>,
    /// Output calibration file.
    #[arg(long)]
    out: PathBuf,
    /// Render every head at this fraction of its resolution (same field of view).
    #[arg(long, default_value_t = 1.0)]
    head_scale: f64,
}

pub fn run(args: Args) -> Result<()> {
    let sim = super::load(&args.scenario, args.head_scale)?;
    let heads = &sim.world.heads;
    let index = match &args.head {
        Some(name) => sim
            .world
            .head_index(name)
            .with_context(|| format!("no head `{name}` in the scenario"))?,
        None => heads
            .iter()
            .position(|h| h.encoding == sim::Encoding::Mono8)
            .unwrap_or(0),
    };
    let h = &heads[index];
    let f = h.focal_px();
    let (cx, cy) = ((h.width as f64 - 1.0) / 2.0, (h.height as f64 - 1.0) / 2.0);
    // The left camera sits half a baseline to the head's left (+y of the head frame).
    let rot = h.mount.rotation();
    let left = h.mount.position + rot * Vector3::new(0.0, h.baseline / 2.0, 0.0);
    let (roll, pitch, yaw) = (h.mount.rpy[0], h.mount.rpy[1], h.mount.rpy[2]);
    let mut text = String::new();
    writeln!(
        text,
        "# Calibration of simulated head `{}` ({}).",
        h.name, sim.world.name
    )?;
    writeln!(
        text,
        "# Written by `sim calib`; ideal rectified pair, baseline {} m.",
        h.baseline
    )?;
    writeln!(
        text,
        "# Left camera on the body, for the stereo service config:"
    )?;
    writeln!(
        text,
        "# [mount] position = [{:.4}, {:.4}, {:.4}], roll_deg = {:.3}, pitch_deg = {:.3}, yaw_deg = {:.3}",
        left.x,
        left.y,
        left.z,
        roll.to_degrees(),
        pitch.to_degrees(),
        yaw.to_degrees()
    )?;
    writeln!(text, "width = {}\nheight = {}", h.width, h.height)?;
    writeln!(
        text,
        "rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\ntranslation = [{}, 0.0, 0.0]",
        -h.baseline
    )?;
    for side in ["left", "right"] {
        writeln!(text, "\n[{side}]\nfx = {f}\nfy = {f}\ncx = {cx}\ncy = {cy}")?;
    }
    std::fs::write(&args.out, text).with_context(|| format!("writing {}", args.out.display()))?;
    // For tools that generate the stereo service's configuration.
    println!(
        "{{\"head\": \"{}\", \"mount\": {{\"position\": [{}, {}, {}], \"roll_deg\": {}, \"pitch_deg\": {}, \"yaw_deg\": {}}}}}",
        h.name,
        left.x,
        left.y,
        left.z,
        roll.to_degrees(),
        pitch.to_degrees(),
        yaw.to_degrees()
    );
    Ok(())
}
