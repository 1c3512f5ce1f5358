//! `usv eval <scenario...>`: runs each scenario lock-step through a process set and reports metrics
//! against the simulator's ground truth: frames, rates, per-service processing time, and stereo range
//! error on solid surfaces (objects, terrain) by range beside the theoretical
//! sigma_Z = Z^2 sigma_d / (f B). With `--closed-loop` the whole pipeline drives the boat through the
//! scenario's mission and the behaviour is scored too (minimum distance to every obstacle, waypoints
//! reached, following error, rudder reversals), with an overview picture per scenario.

use crate::chaos::Chaos;
use crate::control::ServiceStatus;
use crate::eval_tracking::TrackingScore;
use crate::observe::{MissionGoal, Observation, Observer};
use crate::pipeline::{PipelineSpec, Source};
use crate::session::{has_stopped, percentile, Session};
use messages::topics;
use runtime::Ports;
use serde_json::json;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
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
    /// Run the whole pipeline and let the sequencer drive the scenario's mission.
    #[arg(long)]
    closed_loop: bool,
    /// Resolution of the stereo heads as a fraction of the scenario's.
    #[arg(long, default_value_t = 1.0)]
    head_scale: f64,
    /// Camera frames per second of scenario time (default: the scenario's).
    #[arg(long)]
    camera_rate: Option<f64>,
    /// Heads to run (default: the scenario's mono heads); range error is scored on the first.
    #[arg(long, value_delimiter = ',')]
    heads: Vec<String>,
    /// Chaos with this seed: kill -9 random pipeline services at random times, hang perception once.
    #[arg(long, requires = "closed_loop")]
    chaos: Option<u64>,
    /// Record every topic to <out>/<scenario>/run.mcap and check that nothing the source published
    /// is missing from it.
    #[arg(long)]
    record: bool,
    /// Longest wait for the pipeline per frame before the simulator goes on without it (ms).
    #[arg(long, default_value_t = 5000)]
    lockstep_timeout_ms: u64,
    /// Run each scenario once per seed (comma-separated), its `seed` replaced: other wave, INS
    /// and traffic noise, other scenery, the same layout and mission. A run goes to
    /// <out>/<scenario>-<seed>, with the seeded scenario beside its log (`scenario.toml`).
    #[arg(long, value_delimiter = ',')]
    seed: Vec<u64>,
}

/// Range bins of the stereo evaluation (m); a pixel counts for a bin within +-15 % of its centre.
const RANGE_BINS: [f64; 5] = [10.0, 25.0, 50.0, 100.0, 200.0];
/// Disparity noise used for the theoretical range sigma (px).
const SIGMA_D: f64 = 0.25;

#[derive(Default)]
struct RangeBin {
    errors: Vec<f64>,
    /// The errors of pixels on boats alone: small objects over water, whose bias the bin's banks
    /// and trees would hide.
    boat_errors: Vec<f64>,
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
    /// Water-plane fit against the true water surface, per frame with a valid fit.
    plane_tilt_deg: Vec<f64>,
    plane_height_error_m: Vec<f64>,
    /// Frames whose fit the stereo service marked invalid.
    plane_invalid: u64,
}

pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    crate::session::ensure_stack_built()?;
    let mut reports = Vec::new();
    let seeds: Vec<Option<u64>> = if args.seed.is_empty() {
        vec![None]
    } else {
        args.seed.iter().copied().map(Some).collect()
    };
    for scenario in &args.scenarios {
        let scenario = scenario
            .canonicalize()
            .map_err(|e| anyhow::anyhow!("scenario {}: {e}", scenario.display()))?;
        let stem = scenario
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("scenario")
            .to_string();
        for &seed in &seeds {
            let (name, scenario) = match seed {
                None => (stem.clone(), scenario.clone()),
                Some(seed) => {
                    let name = format!("{stem}-{seed}");
                    let dir = args.out.join(&name);
                    (name, seeded_scenario(&scenario, seed, &dir)?)
                }
            };
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
    }
    if args.closed_loop && !args.json && reports.len() > 1 {
        println!("== all {} runs", reports.len());
        println!("{}", totals_line(&reports));
    }
    Ok(())
}

/// Collisions, false tracks and the detection targets summed over closed-loop runs.
fn totals_line(reports: &[serde_json::Value]) -> String {
    let behaviour: Vec<&serde_json::Value> = reports.iter().map(|r| &r["behaviour"]).collect();
    let tracking: Vec<&serde_json::Value> = behaviour.iter().map(|b| &b["tracking"]).collect();
    let minutes = behaviour
        .iter()
        .filter_map(|b| b["scenario_time_s"].as_f64())
        .sum::<f64>()
        / 60.0;
    let collisions = behaviour
        .iter()
        .filter(|b| b["collision"].as_bool() == Some(true))
        .count();
    format!(
        "collisions in {collisions} of {} runs; {}",
        reports.len(),
        tracking_totals_line(&tracking, minutes)
    )
}

/// Writes `scenario` with its `seed` replaced to `dir/scenario.toml` and returns that path.
fn seeded_scenario(scenario: &Path, seed: u64, dir: &Path) -> anyhow::Result<PathBuf> {
    let text = std::fs::read_to_string(scenario)
        .map_err(|e| anyhow::anyhow!("scenario {}: {e}", scenario.display()))?;
    let mut table: toml::Table = text
        .parse()
        .map_err(|e| anyhow::anyhow!("scenario {}: {e}", scenario.display()))?;
    let seed = i64::try_from(seed).map_err(|_| anyhow::anyhow!("--seed {seed} is too large"))?;
    table.insert("seed".into(), toml::Value::Integer(seed));
    std::fs::create_dir_all(dir)?;
    let copy = std::path::absolute(dir.join("scenario.toml"))?;
    std::fs::write(
        &copy,
        format!(
            "# {} with seed = {seed}, written by `usv eval --seed`.\n{}",
            scenario.display(),
            toml::to_string(&table)?
        ),
    )?;
    Ok(copy)
}

fn eval_scenario(
    scenario: &Path,
    name: &str,
    args: &EvalArgs,
) -> anyhow::Result<serde_json::Value> {
    let dir = args.out.join(name);
    let heads = if args.heads.is_empty() {
        crate::pipeline::default_heads(scenario)?
    } else {
        args.heads.clone()
    };
    let head = heads[0].clone();
    let spec = PipelineSpec {
        name: format!("eval-{name}"),
        scenario: scenario.to_path_buf(),
        heads,
        head_scale: args.head_scale,
        source: Source::Sim {
            camera_rate_hz: args.camera_rate,
            duration_s: args.duration,
            truth_head: Some(head.clone()),
        },
        algo: args.algo.clone(),
        closed_loop: args.closed_loop,
        perception: true,
        record: args.record.then(|| crate::pipeline::Recording {
            file: dir.join("run.mcap"),
            topics: Vec::new(),
            lz4: true,
        }),
        lockstep_timeout_ms: args.lockstep_timeout_ms,
    };
    let written = crate::pipeline::write(&spec, &dir)?;
    let goal = match &written.mission {
        Some(m) => MissionGoal::from_mission_text(&std::fs::read_to_string(m)?)?,
        None => MissionGoal::default(),
    };
    let mut session = Session::start(&written.set, &dir, "eval")?;
    // The watcher's node must be gone before the set is taken down, so the domain is left clean.
    let mut chaos = args.chaos.map(|seed| {
        let mut victims: Vec<String> = written
            .heads
            .iter()
            .map(|h| format!("stereo-{h}"))
            .collect();
        victims.extend(["perception", "mapper", "tracker", "sequencer"].map(String::from));
        Chaos::new(seed, victims, Some("perception".into()))
    });
    let perception_report;
    let (metrics, obs, services, wall) = {
        let node = runtime::tool_node("usv-eval")?;
        let observer = Observer::new(&node)?;
        let mut perception = crate::eval_perception::PerceptionEval::new(&node, &head)?;
        let truth = topics::TRUTH_IMAGE.subscriber(&node)?;
        let shutdown = runtime::Shutdown::install()?;
        let started = Instant::now();
        let mut metrics = Metrics::default();
        let mut obs = Observation::new(goal);
        if args.closed_loop {
            // Tracks on the scenario's shore are shore contacts, not false tracks; what is in view
            // but hidden is scored apart.
            let world = sim::scenario::load_world(scenario)?;
            let sight = Rc::new(RefCell::new(sim::Sight::new(world.clone())));
            obs.tracking.set_sight(TrackingScore::sight_of(&sight));
            if let Some(land) = TrackingScore::land_of(world) {
                obs.tracking.set_land(land);
            }
        }
        // Truth images and disparities by stamp until their partner arrives (the simulator renders
        // truth after publishing the frame, so either may come first).
        let mut truths: BTreeMap<u64, Vec<f32>> = BTreeMap::new();
        let mut estimates: BTreeMap<u64, (messages::DisparityHeader, Vec<f32>)> = BTreeMap::new();
        let mut last_poll = Instant::now();
        let services = loop {
            session.check_alive()?;
            observer.poll(&mut obs, |h, payload| {
                if h.head.as_str() != head {
                    return;
                }
                metrics.disparities += 1;
                match truths.remove(&h.hdr.stamp_ns) {
                    Some(truth) => compare(&mut metrics, h, payload, &truth),
                    None => {
                        estimates.insert(h.hdr.stamp_ns, (*h, payload.to_vec()));
                    }
                }
            })?;
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
            perception.poll()?;
            if let Some(chaos) = &mut chaos {
                chaos.step(&session, &obs)?;
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
                if !args.json && obs.frames > 0 {
                    eprint!(
                        "\r  {:>6.1} s scenario, {} frames",
                        obs.scenario_time_s(),
                        obs.frames
                    );
                }
            }
            anyhow::ensure!(!shutdown.requested(), "interrupted");
            std::thread::sleep(Duration::from_millis(2));
        };
        if !args.json {
            eprintln!();
        }
        metrics.frames = obs.frames;
        perception.poll()?;
        perception_report = perception.report();
        (metrics, obs, services, started.elapsed().as_secs_f64())
    };
    session.down()?;
    let recording = match &spec.record {
        Some(rec) => Some(check_recording(&rec.file, &services, written.heads.len())?),
        None => None,
    };
    let picture = if args.closed_loop {
        let path = dir.join("overview.png");
        let arcs = crate::overview::arc_geometry(written.sequencer_config.as_deref())?;
        crate::overview::write(&obs, &arcs, &path)?;
        Some(std::path::absolute(path)?)
    } else {
        None
    };

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
            let boat_errors = bin.map(|b| b.boat_errors.as_slice()).unwrap_or(&[]);
            json!({"range_m": z,
                   "pixels": errors.len(),
                   "density": bin.map(|b| errors.len() as f64 / b.truth_pixels.max(1) as f64),
                   "median_abs_error_m": percentile(&abs, 0.5),
                   // Signed (estimate minus truth): a bias, not noise, shows here.
                   "median_error_m": percentile(errors, 0.5),
                   "boat_pixels": boat_errors.len(),
                   "boat_median_error_m": percentile(boat_errors, 0.5),
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
        "water_plane": plane_report(&metrics),
        "behaviour": args.closed_loop.then(|| obs.report()),
        "chaos": chaos.map(|c| c.report()),
        "recording": recording,
        "overview": picture,
        "perception": perception_report,
    }))
}

fn plane_report(m: &Metrics) -> serde_json::Value {
    let abs = |v: &[f64]| v.iter().map(|x| x.abs()).collect::<Vec<_>>();
    json!({"frames": m.plane_tilt_deg.len(), "invalid_frames": m.plane_invalid,
           "tilt_error_deg": {"p50": percentile(&m.plane_tilt_deg, 0.5),
                              "p90": percentile(&m.plane_tilt_deg, 0.9)},
           "height_error_m": {"p50_abs": percentile(&abs(&m.plane_height_error_m), 0.5),
                              "p90_abs": percentile(&abs(&m.plane_height_error_m), 0.9),
                              "median": percentile(&m.plane_height_error_m, 0.5)}})
}

/// Reads the recording's statistics back and compares them with what the simulator says it
/// published: one ground truth per frame and one stereo frame per head and frame.
fn check_recording(
    file: &Path,
    services: &[ServiceStatus],
    heads: usize,
) -> anyhow::Result<serde_json::Value> {
    let contents = crate::demo::RecordingContents::read(file)?;
    let count = |topic: &str| contents.count(topic);
    let frames = services
        .iter()
        .find(|s| s.name == "sim")
        .map_or(0, |s| s.processed);
    let truth = count(topics::GROUND_TRUTH.name);
    let stereo = count(topics::STEREO_FRAME.name);
    Ok(json!({
        "file": std::path::absolute(file)?,
        "sim_frames": frames,
        "ground_truth": truth,
        "stereo_frames": stereo,
        "complete": truth == frames && stereo == frames * heads as u64,
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
    compare_plane(m, h, disparity, labels);
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
            let error = fb / d_est as f64 - z_true;
            entry.errors.push(error);
            if label as u8 == messages::truth_class::BOAT {
                entry.boat_errors.push(error);
            }
        }
    }
}

/// Scores the frame's water-plane fit against the true water surface: the true 3D points of water
/// pixels within 40 m (every 4th row and column), where the fit's own inliers lie.
fn compare_plane(
    m: &mut Metrics,
    h: &messages::DisparityHeader,
    disparity: &[f32],
    labels: &[f32],
) {
    if h.plane.valid != 1 {
        m.plane_invalid += 1;
        return;
    }
    let width = h.width as usize;
    let points: Vec<[f64; 3]> = (0..h.height as usize)
        .step_by(4)
        .flat_map(|v| (0..width).step_by(4).map(move |u| (u, v)))
        .filter(|&(u, v)| labels[v * width + u] as u8 == messages::truth_class::WATER)
        .filter_map(|(u, v)| h.camera.point(u as f64, v as f64, disparity[v * width + u]))
        .filter(|p| p[2] <= 40.0)
        .collect();
    if let Some(e) = stereo::eval::plane_error(h.plane.normal, h.plane.offset, &points) {
        m.plane_tilt_deg.push(e.tilt_deg);
        m.plane_height_error_m.push(e.height_error_m);
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
    let f = fixed2;
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
    let p = &r["water_plane"];
    println!(
        "water plane: {} frames scored, {} invalid; tilt error p50 {} / p90 {} deg; camera height error |p50| {} / |p90| {} m (median {} m)",
        p["frames"],
        p["invalid_frames"],
        f(&p["tilt_error_deg"]["p50"], 1.0),
        f(&p["tilt_error_deg"]["p90"], 1.0),
        f(&p["height_error_m"]["p50_abs"], 1.0),
        f(&p["height_error_m"]["p90_abs"], 1.0),
        f(&p["height_error_m"]["median"], 1.0),
    );
    crate::eval_perception::print(&r["perception"]);
    let b = &r["behaviour"];
    if b.is_object() {
        println!(
            "behaviour: min clearance {} m ({}), collision {}, waypoints {}/{}, follow RMS {} m{}, rudder reversals {}/min, camera->command p50 {} ms p99 {} ms, contacts {}",
            f(&b["min_clearance_m"], 1.0),
            b["min_clearance_object"].as_str().unwrap_or("-"),
            b["collision"],
            b["waypoints_reached"],
            b["waypoints"],
            f(&b["follow_rms_m"], 1.0),
            follow_held(&b["follow_held"]),
            f(&b["rudder_reversals_per_min"], 1.0),
            f(&b["camera_to_command_ms"]["p50"], 1.0),
            f(&b["camera_to_command_ms"]["p99"], 1.0),
            b["confirmed_contacts"].as_array().map_or(0, |c| c.len()),
        );
        println!("{}", tracking_line(&b["tracking"]));
        for line in tracking_detail_lines(&b["tracking"]) {
            println!("{line}");
        }
        println!(
            "overview picture: {}",
            r["overview"].as_str().unwrap_or("-")
        );
    }
    if r["chaos"].is_object() {
        for line in crate::chaos::report_lines(&r["chaos"]) {
            println!("{line}");
        }
    }
    let rec = &r["recording"];
    if rec.is_object() {
        println!(
            "recording: {} {} ({} ground truth and {} stereo messages of {} simulator frames)",
            rec["file"].as_str().unwrap_or("-"),
            if rec["complete"].as_bool() == Some(true) {
                "complete"
            } else {
                "INCOMPLETE"
            },
            rec["ground_truth"],
            rec["stereo_frames"],
            rec["sim_frames"],
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

/// False tracks and the detection targets summed over several runs' tracking scores
/// (`TrackingScore::report`), which cover `minutes` in all.
pub(crate) fn tracking_totals_line(tracking: &[&serde_json::Value], minutes: f64) -> String {
    let sum = |key: &[&str]| -> u64 {
        tracking
            .iter()
            .map(|t| key.iter().fold(*t, |v, k| &v[*k]).as_u64().unwrap_or(0))
            .sum()
    };
    let per_min = |n: u64| n as f64 / minutes.max(f64::MIN_POSITIVE);
    let (false_tracks, objects) = (sum(&["false_tracks"]), sum(&["false_object_tracks"]));
    let counts = |target: &str| {
        let of =
            |key: String| format!("{} of {}", sum(&[&key, "detected"]), sum(&[&key, "frames"]));
        let in_sight = format!("{target}_in_sight");
        let in_sight = if tracking.iter().any(|t| t[&in_sight].is_object()) {
            format!(", in sight {}", of(in_sight))
        } else {
            String::new()
        };
        format!(
            "{} frames (in a head's view {}{in_sight})",
            of(target.to_string()),
            of(format!("{target}_in_view")),
        )
    };
    format!(
        "{false_tracks} false tracks over {minutes:.1} min ({:.1}/min; {objects} reported as objects, {:.1}/min), boats within 100 m {}, markers/buoys within 60 m {}",
        per_min(false_tracks),
        per_min(objects),
        counts("boats_within_100m"),
        counts("markers_within_60m"),
    )
}

/// The one-line summary of a run's tracking score (`TrackingScore::report`).
pub(crate) fn tracking_line(t: &serde_json::Value) -> String {
    let f = fixed2;
    format!(
        "tracking: boats within 100 m detected {} of {} frames ({}), markers/buoys within 60 m {} of {} ({}), confirmed tracks {} ({} false, {}/min, of them reported as objects {}, {}/min; {} on the shore), moving-boat speed error p50 {} % ({} % while detected), heading error p50 {} deg, along/cross 3-sigma ratio {}{}",
        t["boats_within_100m"]["detected"],
        t["boats_within_100m"]["frames"],
        in_view(&t["boats_within_100m_in_view"], &t["boats_within_100m_in_sight"]),
        t["markers_within_60m"]["detected"],
        t["markers_within_60m"]["frames"],
        in_view(&t["markers_within_60m_in_view"], &t["markers_within_60m_in_sight"]),
        t["confirmed_tracks"],
        t["false_tracks"],
        f(&t["false_tracks_per_min"], 1.0),
        t["false_object_tracks"],
        f(&t["false_object_tracks_per_min"], 1.0),
        t["shore_tracks"],
        f(&t["moving_speed_error_pct"]["p50"], 1.0),
        f(&t["moving_speed_error_pct"]["detected_p50"], 1.0),
        f(&t["moving_heading_error_deg"]["p50"], 1.0),
        f(&t["along_cross_3sigma_ratio"], 1.0),
        match t["aground_frames"].as_u64() {
            Some(n) if n > 0 => format!("; {n} frames of objects aground not scored"),
            _ => String::new(),
        },
    )
}

/// "  <title>: <item>, <item>, ..." over the array `key` of a tracking report; `None` when it is
/// missing or empty.
fn listed_line(
    t: &serde_json::Value,
    key: &str,
    title: &str,
    item: impl Fn(&serde_json::Value) -> String,
) -> Option<String> {
    let items = t[key].as_array().filter(|items| !items.is_empty())?;
    let each: Vec<String> = items.iter().map(item).collect();
    Some(format!("  {title}: {}", each.join(", ")))
}

/// The boats within 100 m one by one (`TrackingScore::report`'s `boats_within_100m_by_object`):
/// which boat a run's misses are on. `None` without boats.
pub(crate) fn boats_by_object_line(t: &serde_json::Value) -> Option<String> {
    let scored_in_sight = t["boats_within_100m_in_sight"].is_object();
    let title = format!(
        "boats within 100 m by truth id, detected of frames (in a head's view{})",
        if scored_in_sight { "; in sight" } else { "" }
    );
    listed_line(t, "boats_within_100m_by_object", &title, |b| {
        let in_sight = if b["in_sight"].is_object() {
            format!("; {}", detected_of(&b["in_sight"]))
        } else {
            String::new()
        };
        format!(
            "#{}: {} ({}{in_sight})",
            b["id"],
            detected_of(&b["all"]),
            detected_of(&b["in_view"])
        )
    })
}

/// The class each true object's track was reported as (`TrackingScore::report`'s
/// `class_of_tracked_frames`): "boat 412 of 507 (false-alarm 45, marker 50)", the classes it should
/// not have been reported as in brackets. `None` before any object had a track.
pub(crate) fn class_line(t: &serde_json::Value) -> Option<String> {
    listed_line(
        t,
        "class_of_tracked_frames",
        "reported as the right class, of the frames with a track",
        class_item,
    )
}

/// [`class_line`] by true object (`class_of_tracked_frames_by_object`): "#8 boat 54 of 421
/// (extended 339)".
pub(crate) fn class_by_object_line(t: &serde_json::Value) -> Option<String> {
    listed_line(
        t,
        "class_of_tracked_frames_by_object",
        "the same by truth id",
        |c| format!("#{} {}", c["id"], class_item(c)),
    )
}

/// "boat 412 of 507 (false-alarm 45, marker 50)" for one entry of `class_of_tracked_frames`.
fn class_item(c: &serde_json::Value) -> String {
    let expected = c["expected"].as_str().unwrap_or("-");
    let others: Vec<String> = c["said"]
        .as_object()
        .into_iter()
        .flatten()
        .filter(|(said, _)| *said != expected)
        .map(|(said, n)| format!("{said} {n}"))
        .collect();
    let others = if others.is_empty() {
        String::new()
    } else {
        format!(" ({})", others.join(", "))
    };
    format!(
        "{} {} of {}{others}",
        c["truth"].as_str().unwrap_or("-"),
        c["right"],
        c["frames"]
    )
}

/// Track-frames reported a boat by tracks on no true object (`boat_reports_off_objects`); `None`
/// when not scored.
fn boat_reports_off_objects_line(t: &serde_json::Value) -> Option<String> {
    let b = t["boat_reports_off_objects"].as_object()?;
    Some(format!(
        "  track-frames reported a boat off every true object: {} on the shore, {} elsewhere",
        b.get("shore").unwrap_or(&serde_json::Value::Null),
        b.get("elsewhere").unwrap_or(&serde_json::Value::Null)
    ))
}

/// The lines printed under the tracking line: the boats one by one and the classes reported.
pub(crate) fn tracking_detail_lines(t: &serde_json::Value) -> Vec<String> {
    [
        boats_by_object_line(t),
        class_line(t),
        class_by_object_line(t),
        boat_reports_off_objects_line(t),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// A number scaled, with two decimals, or "-".
fn fixed2(v: &serde_json::Value, scale: f64) -> String {
    v.as_f64()
        .map_or("-".to_string(), |x| format!("{:.2}", x * scale))
}

/// " (held within 5 m over 40.0-72.0 s, RMS 3.40 m)" for a follow run's longest held stretch.
fn follow_held(h: &serde_json::Value) -> String {
    if !h.is_object() {
        return String::new();
    }
    let v = |k: &str| h[k].as_f64().unwrap_or(f64::NAN);
    format!(
        " (held within {} m over {:.1}-{:.1} s, RMS {:.2} m)",
        v("within_m"),
        v("from_s"),
        v("to_s"),
        v("rms_m")
    )
}

/// "in a head's view D of F, in sight D of F" for the detection counts in view and in sight (the
/// latter left out when not scored), or a note that no camera was seen.
fn in_view(view: &serde_json::Value, sight: &serde_json::Value) -> String {
    if !view.is_object() {
        return "no head's view known".to_string();
    }
    let mut s = format!("in a head's view {}", detected_of(view));
    if sight.is_object() {
        s += &format!(", in sight {}", detected_of(sight));
    }
    s
}

/// "D of F" for a detection count (`{"detected": D, "frames": F}`).
fn detected_of(c: &serde_json::Value) -> String {
    format!("{} of {}", c["detected"], c["frames"])
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn boat_pixels_read_too_close_show_as_a_negative_signed_median_of_their_own() {
        use messages::truth_class as class;
        // f B = 100 px m: disparity 1 px is 100 m. A boat pixel read at 1.25 px (80 m), two
        // terrain pixels right.
        let mut h = messages::DisparityHeader::default();
        (h.camera.fx, h.camera.baseline_m) = (100.0, 1.0);
        let estimate = [1.25, 1.0, 1.0];
        let labels = [class::BOAT, class::TERRAIN, class::TERRAIN].map(f32::from);
        let truth: Vec<f32> = [1.0; 3].into_iter().chain(labels).collect();
        let mut m = Metrics::default();
        compare(&mut m, &h, &estimate, &truth);
        let bin = &m.bins[&RANGE_BINS.iter().position(|&z| z == 100.0).unwrap()];
        assert_eq!(bin.boat_errors, [-20.0]);
        assert_eq!(bin.errors, [-20.0, 0.0, 0.0]);
        assert_eq!(percentile(&bin.errors, 0.5), Some(0.0));
    }

    #[test]
    fn the_boats_line_names_each_boat_with_its_frames() {
        let t = json!({"boats_within_100m_by_object": [
            {"id": 3, "all": {"detected": 61, "frames": 240}, "in_view": {"detected": 51, "frames": 63}},
            {"id": 7, "all": {"detected": 0, "frames": 5}, "in_view": {"detected": 0, "frames": 0}},
        ]});
        assert_eq!(
            boats_by_object_line(&t).unwrap(),
            "  boats within 100 m by truth id, detected of frames (in a head's view): \
             #3: 61 of 240 (51 of 63), #7: 0 of 5 (0 of 0)"
        );
        // Scored in sight too: each boat's in-sight frames after its in-view ones.
        let t = json!({"boats_within_100m_in_sight": {"detected": 50, "frames": 61},
            "boats_within_100m_by_object": [
            {"id": 3, "all": {"detected": 61, "frames": 240}, "in_view": {"detected": 51, "frames": 63},
             "in_sight": {"detected": 50, "frames": 61}},
        ]});
        assert_eq!(
            boats_by_object_line(&t).unwrap(),
            "  boats within 100 m by truth id, detected of frames (in a head's view; in sight): \
             #3: 61 of 240 (51 of 63; 50 of 61)"
        );
        assert!(boats_by_object_line(&json!({"boats_within_100m_by_object": []})).is_none());
        assert!(boats_by_object_line(&json!({})).is_none());
    }

    #[test]
    fn the_class_line_gives_the_right_class_and_the_wrong_ones() {
        let t = json!({"class_of_tracked_frames": [
            {"truth": "boat", "expected": "boat", "frames": 10, "right": 7,
             "said": {"boat": 7, "extended": 1, "false-alarm": 2}},
            {"truth": "buoy", "expected": "marker", "frames": 4, "right": 4, "said": {"marker": 4}},
        ]});
        assert_eq!(
            class_line(&t).unwrap(),
            "  reported as the right class, of the frames with a track: \
             boat 7 of 10 (extended 1, false-alarm 2), buoy 4 of 4"
        );
        assert!(class_line(&json!({"class_of_tracked_frames": []})).is_none());
        let t = json!({"class_of_tracked_frames_by_object": [
            {"id": 8, "truth": "boat", "expected": "boat", "frames": 421, "right": 54,
             "said": {"boat": 54, "extended": 339, "false-alarm": 28}},
        ], "boat_reports_off_objects": {"shore": 968, "elsewhere": 114}});
        assert_eq!(
            tracking_detail_lines(&t),
            [
                "  the same by truth id: #8 boat 54 of 421 (extended 339, false-alarm 28)",
                "  track-frames reported a boat off every true object: 968 on the shore, 114 elsewhere",
            ]
        );
        assert_eq!(tracking_detail_lines(&json!({})), Vec::<String>::new());
    }

    #[test]
    fn several_runs_are_summed_with_their_collisions() {
        let run = |collision: bool, boats_in_view: u64| {
            json!({"behaviour": {"collision": collision, "scenario_time_s": 90.0, "tracking": {
                "false_tracks": 3, "false_object_tracks": 1,
                "boats_within_100m": {"detected": 40, "frames": 50},
                "boats_within_100m_in_view": {"detected": boats_in_view, "frames": 20},
                "markers_within_60m": {"detected": 7, "frames": 8},
                "markers_within_60m_in_view": {"detected": 2, "frames": 2}}}})
        };
        assert_eq!(
            totals_line(&[run(false, 19), run(true, 15)]),
            "collisions in 1 of 2 runs; 6 false tracks over 3.0 min (2.0/min; 2 reported as \
             objects, 0.7/min), boats within 100 m 80 of 100 frames (in a head's view 34 of 40), \
             markers/buoys within 60 m 14 of 16 frames (in a head's view 4 of 4)"
        );
    }

    #[test]
    fn a_seeded_scenario_is_the_same_scenario_with_another_seed() {
        let original = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../services/sim/scenarios/cluttered_river.toml");
        let dir = std::env::temp_dir().join(format!("usv-seeded-{}", std::process::id()));
        let copy = seeded_scenario(&original, 54, &dir).unwrap();
        let load = |p: &Path| sim::Scenario::load(p).unwrap();
        let (a, b) = (load(&original), load(&copy));
        assert_eq!((a.seed, b.seed), (53, 54));
        assert_eq!(a.name, b.name);
        // Same layout: the objects and the mission's waypoints.
        let (wa, wb) = (a.build().unwrap(), b.build().unwrap());
        let positions = |w: &sim::world::World| {
            w.objects
                .iter()
                .filter(|o| o.in_truth)
                .map(|o| format!("{} {:?}", o.name, o.motion))
                .collect::<Vec<_>>()
        };
        assert_eq!(positions(&wa), positions(&wb));
        assert_eq!(wa.mission, wb.mission);
        std::fs::remove_dir_all(&dir).unwrap();
        // A seed TOML cannot hold is refused, not wrapped.
        assert!(seeded_scenario(&original, u64::MAX, &dir).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
