//! Water detection time per frame at 512x384 on simulator frames (stereo from the stereo library,
//! computed once per frame outside the timing).
//!
//! `cargo run --release -p water --example bench -- [--frames 3] [--iterations 40]`

mod common;

use anyhow::Result;
use clap::Parser;
use std::path::PathBuf;
use std::time::Instant;
use water::{Frame, Image, WaterConfig, WaterDetector};

#[derive(Parser)]
struct Args {
    #[arg(
        long,
        default_value = "services/sim/scenarios/trail_puddles_headon.toml"
    )]
    scenario: PathBuf,
    /// Distinct frames (1.5 s apart from t = 1 s), cycled through.
    #[arg(long, default_value_t = 3)]
    frames: usize,
    /// Timed detector runs per frame.
    #[arg(long, default_value_t = 40)]
    iterations: usize,
    /// rayon threads (0 = one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

struct Input {
    rgb: Vec<u8>,
    disparity: Vec<f32>,
    vehicle: messages::Pose,
}

fn main() -> Result<()> {
    let args = Args::parse();
    if args.threads > 0 {
        rayon::ThreadPoolBuilder::new()
            .num_threads(args.threads)
            .build_global()?;
    }
    let mut src = common::SimStereo::new(&args.scenario, "color", 2, 96)?;
    let mut inputs = Vec::new();
    for k in 0..args.frames {
        src.advance_to(1.0 + 1.5 * k as f64);
        src.frame(false)?;
        inputs.push(Input {
            rgb: src.rgb.clone(),
            disparity: src.disparity.clone(),
            vehicle: src.vehicle(),
        });
    }
    let mut det = WaterDetector::new(WaterConfig::default());
    let run = |det: &mut WaterDetector, i: &Input| {
        let d = det
            .process(&Frame {
                width: src.width,
                height: src.height,
                image: Image::Rgb8(&i.rgb),
                disparity: &i.disparity,
                camera: &src.camera,
                vehicle: &i.vehicle,
            })
            .expect("valid frame");
        d.regions.len()
    };
    // Warm-up sizes every buffer.
    for i in &inputs {
        run(&mut det, i);
    }
    let mut times = Vec::with_capacity(args.iterations * inputs.len());
    let cpu_start = cpu_ms();
    let mut regions = 0;
    for _ in 0..args.iterations {
        for i in &inputs {
            let t = Instant::now();
            regions += run(&mut det, i);
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let cpu = (cpu_ms() - cpu_start) / times.len() as f64;
    times.sort_by(f64::total_cmp);
    let q = |f: f64| times[((times.len() - 1) as f64 * f).round() as usize];
    println!(
        "water detection {}x{}, {} threads, {} runs over {} frames ({} regions): median {:.2} ms, p90 {:.2} ms, min {:.2} ms, max {:.2} ms; CPU {:.2} ms per frame (all threads)",
        src.width,
        src.height,
        rayon::current_num_threads(),
        times.len(),
        inputs.len(),
        regions / args.iterations,
        q(0.5),
        q(0.9),
        q(0.0),
        q(1.0),
        cpu
    );
    Ok(())
}

/// CPU time of the whole process (ms), all threads.
fn cpu_ms() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime only writes the timespec we pass.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 * 1e3 + ts.tv_nsec as f64 * 1e-6
}
