//! `perception bench hazard`: time per frame of the hazard map from a 1280x960 disparity image (a
//! ray-cast sea with buoys and matcher-like noise), on the rayon pool and on one thread, in one run.

use crate::hazard::{Frame, GridConfig, HazardConfig, HazardMapper};
use crate::model::HazardModel;
use crate::synthetic::Scene;
use anyhow::Context;
use messages::{MapCell, Pose};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Frames timed per configuration.
    #[arg(long, default_value_t = 60)]
    pub frames: usize,
    /// Grid side in cells (0.5 m each).
    #[arg(long, default_value_t = 400)]
    pub grid: u32,
    /// Hazard model (default: the committed one).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// A few frames only.
    #[arg(long)]
    pub quick: bool,
    /// Map to 100 m as the simulated sets do: far segments from 50 m, the level fitted within 65 m.
    #[arg(long)]
    pub far_segments: bool,
}

pub fn default_model_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models/hazard.json")
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let path = args.model.clone().unwrap_or_else(default_model_path);
    let model = HazardModel::load(&path)?;
    let mut config = HazardConfig {
        grid: GridConfig {
            width: args.grid,
            height: args.grid,
            resolution_m: 0.5,
        },
        ..Default::default()
    };
    if args.far_segments {
        config.projection.max_range_m = 100.0;
        config.level.max_range_m = 65.0;
        config.segments.min_range_m = 50.0;
    }
    let frames = if args.quick { 5 } else { args.frames.max(1) };
    let s = Scene::buoy_row(1280, 960);
    let mut disparity = Vec::new();
    s.render(&mut disparity);
    let valid = disparity.iter().filter(|d| d.is_finite()).count();
    println!(
        "hazard map: {}x{} disparity ({:.0}% valid), {}x{} grid at 0.5 m, row/col step {}/{}, to {} m{}, {} threads",
        s.width,
        s.height,
        100.0 * valid as f64 / disparity.len() as f64,
        args.grid,
        args.grid,
        config.projection.row_step,
        config.projection.col_step,
        config.projection.max_range_m,
        if args.far_segments {
            " with far segments"
        } else {
            ""
        },
        rayon::current_num_threads()
    );
    let mut medians = Vec::new();
    for threads in [0usize, 1] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .context("thread pool")?;
        let mut mapper =
            HazardMapper::new(config.clone(), model.clone()).map_err(|e| anyhow::anyhow!("{e}"))?;
        let mut out =
            vec![MapCell::default(); config.grid.width as usize * config.grid.height as usize];
        let mut times = Vec::with_capacity(frames);
        let mut summary = None;
        for i in 0..frames + 3 {
            // The vessel creeps north so the grid scrolls and the memory is exercised.
            let mut header = s.header(1_000_000_000 + i as u64 * 100_000_000, "hh_left");
            header.stabilized_pose.position[1] = 0.4 * i as f64;
            let frame = Frame {
                header: &header,
                disparity: &disparity,
                vessel: Pose {
                    position: header.stabilized_pose.position,
                    yaw: header.stabilized_pose.yaw,
                    ..Pose::default()
                },
            };
            let t = Instant::now();
            let r = pool.install(|| mapper.process(&frame, &mut out))?;
            if i >= 3 {
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            summary = Some(r);
        }
        times.sort_by(f64::total_cmp);
        let (median, p90) = (percentile(&times, 0.5), percentile(&times, 0.9));
        medians.push(median);
        let s = summary.unwrap();
        println!(
            "  {:>9}: median {median:.2} ms, p90 {p90:.2} ms per frame ({} points, {} observed cells, {} hazard cells, {} far segments)",
            if threads == 0 { "rayon" } else { "1 thread" },
            s.points,
            s.observed_cells,
            s.hazard_cells,
            s.far_segments
        );
    }
    println!("  speed-up on the pool: {:.2}x", medians[1] / medians[0]);
    Ok(())
}
