//! Maps the disparity images of a recording again and explains the hazard of the cells around one
//! point: each cell's features and how much each one adds to the classifier's log-odds. A cell
//! the map rated wrong can so be traced to the feature that rated it.
//!
//! ```text
//! cargo run --release -p perception --example explain -- out/run/bridge_pylons/run.mcap \
//!     --at 20,200 --radius 2.5 --from 30 --to 33
//! ```
//!
//! The INS samples of the recording place the frames, as in the service. The map is placed by the
//! INS, so `--at` is in the recording's INS frame (truth moved by the INS error).

use anyhow::Context;
use clap::Parser;
use messages::recording::{read_slice, read_value, split};
use messages::{topics, DisparityHeader, Header, InsState, MapCell};
use perception::model::N_FEATURES;
use perception::service::{Perception, ServiceConfig};
use std::path::PathBuf;

/// [`perception::model::FEATURES`] in the same order, short enough for a line per cell.
const SHORT_NAMES: [&str; N_FEATURES] = [
    "max",
    "mean",
    "spread",
    "extent",
    "fraction",
    "min",
    "history",
    "neighbours",
    "margin",
    "lift",
];

#[derive(Parser)]
struct Args {
    /// A recording with disparity images and INS samples (`usv eval --record`).
    recording: PathBuf,
    /// ENU point (m) whose cells to explain: `x,y`.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    at: Vec<f64>,
    /// Cells whose centre lies this close to the point (m).
    #[arg(long, default_value_t = 2.0)]
    radius: f64,
    /// Seconds of the recording's stamps to print.
    #[arg(long, default_value_t = 0.0)]
    from: f64,
    #[arg(long, default_value_t = f64::INFINITY)]
    to: f64,
    /// Perception configuration (its model path is relative to it).
    #[arg(long, default_value = "launch/sets/perception.toml")]
    config: PathBuf,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    anyhow::ensure!(args.at.len() == 2, "--at takes x,y");
    let config: ServiceConfig = runtime::config::load(&args.config)?;
    let mut perception = Perception::new(&config, &config.model_path(&args.config))?;
    let model = perception.mapper().model().clone();
    let mut scratch = vec![MapCell::default(); perception.cell_count()];
    let rec = sensors::Recording::open(&args.recording)
        .with_context(|| format!("recording {}", args.recording.display()))?;
    let wanted = [topics::INS.name, topics::DISPARITY.name];
    let topic_of: std::collections::BTreeMap<u16, String> =
        rec.channels().map(|c| (c.id, c.topic.clone())).collect();
    println!(
        "per cell: centre, range, probability, then each feature as `name value (its log-odds \
         term)`; the terms and the bias {:+.2} sum to the log-odds",
        model.bias
    );
    for msg in rec.messages(0, |t| wanted.contains(&t)) {
        let msg = msg?;
        let (header, payload) = split(&msg.data).context("corrupt framing")?;
        if topic_of.get(&msg.channel).map(String::as_str) == Some(topics::INS.name) {
            // SAFETY: InsState is plain numbers.
            let s: InsState = unsafe { read_value(payload) }.context("short INS sample")?;
            // A rejected sample is rejected by the service too.
            let _ = perception.add_ins(s);
            continue;
        }
        // SAFETY: DisparityHeader and f32 are plain numbers.
        let h: DisparityHeader = unsafe { read_value(header) }.context("short disparity header")?;
        let disparity: Vec<f32> = unsafe { read_slice(payload) };
        if !perception.accepts(h.head.as_str()) {
            continue;
        }
        let t = h.hdr.stamp_ns as f64 * 1e-9;
        let Ok((map, summary)) =
            perception.process(&h, &disparity, &mut scratch, Header::default())
        else {
            continue;
        };
        // Frames before `--from` still build the evidence memory; none after `--to` matters.
        if t > args.to {
            break;
        }
        if t < args.from {
            continue;
        }
        let vessel = map.vessel.position;
        println!(
            "{t:.1} {} {}x{} f {:.0} px, vessel ({:.1}, {:.1}) level {:+.2} m",
            h.head.as_str(),
            h.width,
            h.height,
            h.camera.fx,
            vessel[0],
            vessel[1],
            summary.level.map_or(0.0, |l| l.offset_m)
        );
        let grid = summary.grid;
        for c in perception.mapper().scored_cells() {
            let p = grid.cell_center(c.cell % grid.width, c.cell / grid.width);
            if (p[0] - args.at[0]).hypot(p[1] - args.at[1]) > args.radius {
                continue;
            }
            let range = (p[0] - vessel[0]).hypot(p[1] - vessel[1]);
            let terms = model.terms(&c.features);
            let parts: Vec<String> = (c.features.iter().zip(terms).zip(SHORT_NAMES))
                .map(|((x, t), name)| format!("{name} {x:.2} ({t:+.2})"))
                .collect();
            println!(
                "  ({:.1}, {:.1}) {range:.1} m p {:.2}{}: {}",
                p[0],
                p[1],
                c.probability,
                if c.isolated { " isolated" } else { "" },
                parts.join(" ")
            );
        }
    }
    Ok(())
}
