//! `sim calib`: writes a simulated head's true calibration in the stereo service's format (OpenCV
//! conventions: `X_r = R X_l + T`, radial distortion, `oversize` of the rectified view), and prints
//! the real left camera's mounting on the body as JSON for the stereo service's `[mount]`. The
//! service turns that mount by its rectification (for a toed head the rectified camera is rotated
//! with respect to the real one) before publishing it; the rectified mount is printed too, for
//! reference.

use anyhow::{Context, Result};
use nalgebra::{Rotation3, Vector3};
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

/// A body-frame pose as `{"position": [..], "roll_deg": .., "pitch_deg": .., "yaw_deg": ..}`.
fn pose_json(p: &Vector3<f64>, rpy: [f64; 3]) -> String {
    format!(
        "{{\"position\": [{}, {}, {}], \"roll_deg\": {}, \"pitch_deg\": {}, \"yaw_deg\": {}}}",
        p.x,
        p.y,
        p.z,
        rpy[0].to_degrees(),
        rpy[1].to_degrees(),
        rpy[2].to_degrees()
    )
}

fn rpy(r: &Rotation3<f64>) -> [f64; 3] {
    let (roll, pitch, yaw) = r.euler_angles();
    [roll, pitch, yaw]
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
    let calib = h.calibration();
    let view = calib
        .rectify()
        .with_context(|| format!("rectifying head `{}`", h.name))?;
    let (left, left_rot) = h.left_camera_mount();
    // An untoed camera has the bar's attitude: keep the configured angles exactly.
    let left_rpy = if h.toe == 0.0 {
        [h.mount.rpy[0], h.mount.rpy[1], h.mount.rpy[2]]
    } else {
        rpy(&left_rot)
    };
    let (_, rect_rot) = h.rectified_mount(&view);
    let mount = pose_json(&left, left_rpy);
    let rectified = pose_json(&left, rpy(&rect_rot));
    let text = format!(
        "# Calibration of simulated head `{}` ({}), written by `sim calib`.\n\
         # Baseline {} m, cameras toed {} deg on the bar, k1 {} k2 {}.\n\
         # Real left camera on the body (the stereo service's [mount]): {mount}\n\
         # Rectified left camera on the body ({}x{}, f {:.3} px): {rectified}\n{}",
        h.name,
        sim.world.name,
        h.baseline,
        h.toe.to_degrees(),
        h.k1,
        h.k2,
        view.width,
        view.height,
        view.f,
        calib.to_toml()
    );
    std::fs::write(&args.out, text).with_context(|| format!("writing {}", args.out.display()))?;
    // For tools that generate the stereo service's configuration.
    println!(
        "{{\"head\": \"{}\", \"mount\": {mount}, \"rectified_mount\": {rectified}, \"rectified\": {{\"width\": {}, \"height\": {}, \"f\": {}, \"cx\": {}, \"cy\": {}}}}}",
        h.name, view.width, view.height, view.f, view.cx, view.cy
    );
    Ok(())
}
