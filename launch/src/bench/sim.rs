//! `usv bench sim`: time to ray-trace one stereo pair at 640x480 and 1280x960, on a sparse scene
//! (open water) and a busy one (cluttered river), with the time advancing between frames as in the
//! service loop (scene and sky cache rebuilt each frame).

use super::Figure;
use crate::session::{checkout_file, percentile};
use std::time::Instant;

const SCENARIOS: [&str; 2] = ["open_water_crossing", "cluttered_river"];
const SIZES: [(u32, u32); 2] = [(640, 480), (1280, 960)];

pub fn run(quick: bool) -> anyhow::Result<Vec<Figure>> {
    let frames = if quick { 2 } else { 8 };
    let mut figures = Vec::new();
    for scenario in SCENARIOS {
        let path = checkout_file(&format!("services/sim/scenarios/{scenario}.toml"))?;
        for (width, height) in SIZES {
            let mut world = sim::scenario::load_world(&path)?;
            world.heads.truncate(1);
            world.heads[0].width = width;
            world.heads[0].height = height;
            let mut sim = sim::Simulator::new(world);
            let len = sim.world.heads[0].image_len();
            let (mut left, mut right) = (vec![0u8; len], vec![0u8; len]);
            sim.render_head(0, &mut left, &mut right)?;
            let mut times = Vec::with_capacity(frames);
            for _ in 0..frames {
                sim.step(sim::Command::default(), 0.1);
                let t = Instant::now();
                sim.render_head(0, &mut left, &mut right)?;
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            let median = percentile(&times, 0.5).unwrap_or(f64::NAN);
            let size = format!("{width}x{height}");
            figures.push(
                Figure::new(format!("render_pair_ms {scenario} {size}"), median, "ms")
                    .label("scenario", scenario)
                    .label("size", size.clone())
                    .label("frames", frames),
            );
            figures.push(
                Figure::new(
                    format!("render_pairs_per_s {scenario} {size}"),
                    1e3 / median,
                    "1/s",
                )
                .label("scenario", scenario)
                .label("size", size),
            );
        }
    }
    Ok(figures)
}
