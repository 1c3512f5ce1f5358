//! `usv eval <scenario...>`: runs each scenario lock-step through a process set (simulator -> stereo)
//! and reports metrics against the simulator's ground truth: frames, rates, per-service processing
//! time, and stereo range error on solid surfaces (objects, terrain) by range beside the theoretical
//! sigma_Z = Z^2 sigma_d / (f B).

use crate::session::{has_stopped, percentile, Session};
use messages::topics;
use runtime::Ports;
use serde_json::json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct EvalArgs {
    /// Scenario files (TOML).
    #[arg(required = true)]
    scenarios: Vec<PathBuf>,
    /// Scenario time to run each scenario for (s).
    #[arg(long, default_value_t = 10.0)]
    duration: f64,
    /// Stereo matcher: bm or sgm.
    #[arg(long, default_value = "bm")]
    algo: String,
    /// Directory for the generated sets, calibrations and logs.
    #[arg(long, default_value = "out/eval")]
    out: PathBuf,
    /// One JSON object per scenario instead of tables.
    #[arg(long)]
    json: bool,
}

/// Range bins of the stereo evaluation (m); a pixel counts for a bin within +-15 % of its centre.
const RANGE_BINS: [f64; 5] = [10.0, 25.0, 50.0, 100.0, 200.0];
/// Water-plane search for simulated waves (same as the demo's stereo configuration): the lower rows see
/// water within ~25 m, and waves need a loose inlier band.
const PLANE_SEARCH: &str =
    "[plane]\nlower_fraction = 0.35\nmax_range_m = 25.0\n\n[plane.fit]\ninlier_distance = 0.25\n";
/// Disparity noise used for the theoretical range sigma (px).
const SIGMA_D: f64 = 0.25;

#[derive(Default)]
struct RangeBin {
    errors: Vec<f64>,
    truth_pixels: u64,
}

#[derive(Default)]
struct Metrics {
    frames: u64,
    disparities: u64,
    truth_frames: u64,
    compared_frames: u64,
    bins: BTreeMap<usize, RangeBin>,
    /// f * B of the head, for the theoretical sigma.
    focal_baseline: f64,
}

pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    crate::session::ensure_stack_built()?;
    let mut reports = Vec::new();
    for scenario in &args.scenarios {
        let scenario = scenario
            .canonicalize()
            .map_err(|e| anyhow::anyhow!("scenario {}: {e}", scenario.display()))?;
        let name = scenario
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("scenario")
            .to_string();
        if !args.json {
            println!("== {name}");
        }
        let report = eval_scenario(&scenario, &name, &args)?;
        if args.json {
            println!("{report}");
        } else {
            print_report(&report);
        }
        reports.push(report);
    }
    Ok(())
}

/// Writes calibration, stereo config and launch file for one scenario; returns the launch file.
fn write_set(scenario: &Path, name: &str, args: &EvalArgs) -> anyhow::Result<(PathBuf, String)> {
    let dir = std::path::absolute(args.out.join(name))?;
    std::fs::create_dir_all(&dir)?;
    let sim = crate::launchfile::resolve_program("sim", &dir)
        .ok_or_else(|| anyhow::anyhow!("the `sim` program was not found next to usv"))?;
    let calib = dir.join("calib.toml");
    let out = Command::new(&sim)
        .arg("calib")
        .arg(scenario)
        .arg("--out")
        .arg(&calib)
        .output()?;
    anyhow::ensure!(
        out.status.success(),
        "sim calib failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let head: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let head_name = head["head"].as_str().unwrap_or_default().to_string();
    let m = &head["mount"];
    std::fs::write(
        dir.join("stereo.toml"),
        format!(
            "head = \"{head_name}\"\ncalibration = \"calib.toml\"\n\n[matcher]\nalgo = \"{}\"\n\n[mount]\nposition = {}\nroll_deg = {}\npitch_deg = {}\nyaw_deg = {}\n\n{PLANE_SEARCH}",
            args.algo, m["position"], m["roll_deg"], m["pitch_deg"], m["yaw_deg"]
        ),
    )?;
    let set = dir.join("set.toml");
    std::fs::write(
        &set,
        format!(
            r#"name = "eval-{name}"
heartbeat_timeout_ms = 5000

[[service]]
name = "stereo"
program = "stereo"
args = ["run", "--config", "stereo.toml"]

[[service]]
name = "sim"
program = "sim"
args = ["run", "{}", "--heads", "{head_name}", "--truth-head", "{head_name}",
        "--lockstep", "stereo", "--duration", "{}"]
restart = "never"
depends_on = ["stereo"]
"#,
            scenario.display(),
            args.duration
        ),
    )?;
    Ok((set, head_name))
}

fn eval_scenario(
    scenario: &Path,
    name: &str,
    args: &EvalArgs,
) -> anyhow::Result<serde_json::Value> {
    let (set, head) = write_set(scenario, name, args)?;
    let mut session = Session::start(&set, set.parent().unwrap(), "eval")?;
    // The watcher's node must be gone before the set is taken down, so the domain is left clean.
    let (metrics, services, wall) = {
        let node = runtime::tool_node("usv-eval")?;
        let frames = topics::STEREO_FRAME.subscriber(&node)?;
        let disparity = topics::DISPARITY.subscriber(&node)?;
        let truth = topics::TRUTH_IMAGE.subscriber(&node)?;
        let shutdown = runtime::Shutdown::install()?;
        let started = Instant::now();
        let mut metrics = Metrics::default();
        // Truth images and disparities by stamp until their partner arrives (the simulator renders
        // truth after publishing the frame, so either may come first).
        let mut truths: BTreeMap<u64, Vec<f32>> = BTreeMap::new();
        let mut estimates: BTreeMap<u64, (messages::DisparityHeader, Vec<f32>)> = BTreeMap::new();
        let mut last_poll = Instant::now();
        let services = loop {
            session.check_alive()?;
            while frames.receive()?.is_some() {
                metrics.frames += 1;
            }
            while let Some(sample) = truth.receive()? {
                let stamp = sample.user_header().hdr.stamp_ns;
                metrics.truth_frames += 1;
                match estimates.remove(&stamp) {
                    Some((h, estimate)) => compare(&mut metrics, &h, &estimate, sample.payload()),
                    None => {
                        truths.insert(stamp, sample.payload().to_vec());
                    }
                }
            }
            while let Some(sample) = disparity.receive()? {
                metrics.disparities += 1;
                let h = *sample.user_header();
                match truths.remove(&h.hdr.stamp_ns) {
                    Some(truth) => compare(&mut metrics, &h, sample.payload(), &truth),
                    None => {
                        estimates.insert(h.hdr.stamp_ns, (h, sample.payload().to_vec()));
                    }
                }
            }
            while truths.len() > 16 {
                truths.pop_first();
            }
            while estimates.len() > 16 {
                estimates.pop_first();
            }
            if last_poll.elapsed() > Duration::from_millis(500) {
                last_poll = Instant::now();
                let services = session.ps()?;
                if has_stopped(&services, "sim") {
                    break services;
                }
            }
            anyhow::ensure!(!shutdown.requested(), "interrupted");
            std::thread::sleep(Duration::from_millis(2));
        };
        (metrics, services, started.elapsed().as_secs_f64())
    };
    session.down()?;

    let service_figures: Vec<_> = services
        .iter()
        .map(|s| {
            json!({"service": s.name, "processed": s.processed, "rejected": s.rejected,
                   "errors": s.errors, "restarts": s.restarts,
                   "last_processing_ms": s.last_processing_us.map(|u| u as f64 / 1e3),
                   "max_processing_ms": s.max_processing_us.map(|u| u as f64 / 1e3)})
        })
        .collect();
    let range: Vec<_> = RANGE_BINS
        .iter()
        .enumerate()
        .map(|(i, &z)| {
            let bin = metrics.bins.get(&i);
            let errors = bin.map(|b| b.errors.as_slice()).unwrap_or(&[]);
            let rms = (!errors.is_empty())
                .then(|| (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt());
            let abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
            json!({"range_m": z,
                   "pixels": errors.len(),
                   "density": bin.map(|b| errors.len() as f64 / b.truth_pixels.max(1) as f64),
                   "median_abs_error_m": percentile(&abs, 0.5),
                   "rms_error_m": rms,
                   "theoretical_sigma_m": (metrics.focal_baseline > 0.0)
                        .then(|| z * z * SIGMA_D / metrics.focal_baseline)})
        })
        .collect();
    Ok(json!({
        "bench": "eval", "scenario": name, "head": head,
        "frames": metrics.frames, "disparities": metrics.disparities,
        "frames_compared": metrics.compared_frames,
        "wall_s": wall, "frames_per_s": metrics.disparities as f64 / wall,
        "services": service_figures, "stereo_range_error": range,
    }))
}

/// Whether a pixel of this truth class is a solid surface. Water and sky are left out: on water the
/// matcher sees reflections (a virtual image below the surface), which is the water cue of perception,
/// not a range error.
fn is_solid(class: f32) -> bool {
    use messages::truth_class as c;
    ![c::NONE, c::SKY, c::WATER, c::PUDDLE].contains(&(class as u8))
}

/// Accumulates range errors of one disparity image against the truth of the same frame
/// (`truth` = disparity plane then label plane).
fn compare(m: &mut Metrics, h: &messages::DisparityHeader, estimate: &[f32], truth: &[f32]) {
    let fb = h.camera.fx * h.camera.baseline_m;
    // Only comparable when the rectified image is the raw one (ideal simulated heads).
    if truth.len() != 2 * estimate.len() || fb <= 0.0 {
        return;
    }
    let (disparity, labels) = truth.split_at(estimate.len());
    m.focal_baseline = fb;
    m.compared_frames += 1;
    for ((&d_true, &label), &d_est) in disparity.iter().zip(labels).zip(estimate) {
        if !(d_true.is_finite() && d_true > 0.0 && is_solid(label)) {
            continue;
        }
        let z_true = fb / d_true as f64;
        let Some(bin) = RANGE_BINS
            .iter()
            .position(|&z| (z_true - z).abs() <= 0.15 * z)
        else {
            continue;
        };
        let entry = m.bins.entry(bin).or_default();
        entry.truth_pixels += 1;
        if d_est.is_finite() && d_est > 0.0 {
            entry.errors.push(fb / d_est as f64 - z_true);
        }
    }
}

fn print_report(r: &serde_json::Value) {
    println!(
        "head {}  frames {}  disparities {}  compared {}  wall {:.1} s  {:.2} frames/s",
        r["head"].as_str().unwrap_or(""),
        r["frames"],
        r["disparities"],
        r["frames_compared"],
        r["wall_s"].as_f64().unwrap_or(0.0),
        r["frames_per_s"].as_f64().unwrap_or(0.0)
    );
    let f = |v: &serde_json::Value, scale: f64| {
        v.as_f64()
            .map_or("-".to_string(), |x| format!("{:.2}", x * scale))
    };
    println!(
        "{:>8} {:>9} {:>9} {:>14} {:>10} {:>14}",
        "range m", "pixels", "density%", "median |err| m", "rms m", "sigma_Z th. m"
    );
    for b in r["stereo_range_error"].as_array().into_iter().flatten() {
        println!(
            "{:>8} {:>9} {:>9} {:>14} {:>10} {:>14}",
            b["range_m"].as_f64().unwrap_or(0.0),
            b["pixels"].as_u64().unwrap_or(0),
            f(&b["density"], 100.0),
            f(&b["median_abs_error_m"], 1.0),
            f(&b["rms_error_m"], 1.0),
            f(&b["theoretical_sigma_m"], 1.0)
        );
    }
    for s in r["services"].as_array().into_iter().flatten() {
        println!(
            "  {:<10} processed {:>5}  rejected {:>3}  errors {:>3}  last {} ms  max {} ms",
            s["service"].as_str().unwrap_or(""),
            s["processed"],
            s["rejected"],
            s["errors"],
            f(&s["last_processing_ms"], 1.0),
            f(&s["max_processing_ms"], 1.0)
        );
    }
}
