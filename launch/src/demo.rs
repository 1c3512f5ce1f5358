//! `usv demo`: the whole process set of `launch/sets/demo.toml` on a built-in simulated scenario, in a
//! domain of its own, until the simulator's scenario time is up; then a summary. The demo watches the
//! set like any other tool: it subscribes to topics and asks the supervisor for `ps`.

use crate::control::ServiceStatus;
use crate::session::{checkout_file, ensure_stack_built, has_stopped, percentile, Session};
use messages::topics;
use runtime::Ports;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Launch file of the demo set (default: launch/sets/demo.toml of this checkout).
    #[arg(long)]
    set: Option<PathBuf>,
    /// Directory for the log and outputs.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    /// Give up after this many seconds of wall time.
    #[arg(long, default_value_t = 900)]
    timeout_s: u64,
}

#[derive(Default)]
struct Watch {
    frames: u64,
    frame_arrival: BTreeMap<u64, Instant>,
    latencies_ms: Vec<f64>,
    densities: Vec<f64>,
    plane_heights: Vec<f64>,
    disparities: u64,
}

pub fn run(args: DemoArgs) -> anyhow::Result<()> {
    ensure_stack_built()?;
    let set = match &args.set {
        Some(p) => p.clone(),
        None => checkout_file("launch/sets/demo.toml")?,
    };
    let parsed = crate::launchfile::ProcessSet::load(&set)?;
    let mut session = Session::start(&set, &args.out, "demo")?;
    println!(
        "demo: set '{}' ({} services) from {}; logs in {}",
        parsed.name,
        parsed.services.len(),
        set.display(),
        session.log.display()
    );
    let (watch, services, wall) = watch(&mut session, &args)?;
    let log = session.log.clone();
    session.down()?;
    print_summary(&parsed.name, &watch, &services, wall);
    // The set's recorder writes here (see the demo launch file).
    let recording = set
        .parent()
        .unwrap_or(Path::new("."))
        .join("../../out/demo/demo.mcap");
    if recording.exists() {
        print_recording(&recording)?;
    }
    anyhow::ensure!(
        watch.frames > 0 && watch.disparities > 0,
        "the demo produced no frames or no disparity: see {}",
        log.display()
    );
    Ok(())
}

fn watch(
    session: &mut Session,
    args: &DemoArgs,
) -> anyhow::Result<(Watch, Vec<ServiceStatus>, Duration)> {
    let started = Instant::now();
    let deadline = started + Duration::from_secs(args.timeout_s);
    let node = runtime::tool_node("usv-demo")?;
    let frames = topics::STEREO_FRAME.subscriber(&node)?;
    let disparity = topics::DISPARITY.subscriber(&node)?;
    let shutdown = runtime::Shutdown::install()?;
    let mut w = Watch::default();
    let mut last_report = Instant::now();
    let mut services = Vec::new();
    loop {
        session.check_alive()?;
        while let Some(seq) = frames.receive()?.map(|s| s.user_header().hdr.seq) {
            w.frames += 1;
            w.frame_arrival.insert(seq, Instant::now());
        }
        while let Some(sample) = disparity.receive()? {
            let h = sample.user_header();
            w.disparities += 1;
            if let Some(t) = w.frame_arrival.remove(&h.frame_seq) {
                w.latencies_ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
            let valid = sample.payload().iter().filter(|d| d.is_finite()).count();
            w.densities
                .push(valid as f64 / sample.payload().len().max(1) as f64);
            if h.plane.valid == 1 {
                w.plane_heights.push(h.plane.camera_height_m);
            }
        }
        // Frames whose disparity never came are not latency samples.
        while w.frame_arrival.len() > 64 {
            w.frame_arrival.pop_first();
        }
        if last_report.elapsed() >= Duration::from_secs(1) {
            last_report = Instant::now();
            if let Ok(s) = session.ps() {
                services = s;
            }
            println!(
                "  {:>5.1} s  frames {:>4}  disparities {:>4}",
                started.elapsed().as_secs_f64(),
                w.frames,
                w.disparities
            );
            if has_stopped(&services, "sim") {
                break;
            }
        }
        anyhow::ensure!(!shutdown.requested(), "interrupted");
        anyhow::ensure!(Instant::now() < deadline, "the demo did not finish in time");
        std::thread::sleep(Duration::from_millis(5));
    }
    Ok((w, services, started.elapsed()))
}

fn print_summary(set: &str, w: &Watch, services: &[ServiceStatus], wall: Duration) {
    let fmt = |v: Option<f64>, unit: &str| v.map_or("-".to_string(), |v| format!("{v:.1} {unit}"));
    println!("\n== demo summary: set '{set}' ==");
    println!(
        "frames {}  disparities {}  wall time {:.1} s  throughput {:.2} frames/s",
        w.frames,
        w.disparities,
        wall.as_secs_f64(),
        w.disparities as f64 / wall.as_secs_f64()
    );
    println!(
        "camera-to-disparity latency p50 {}  p99 {}",
        fmt(percentile(&w.latencies_ms, 0.5), "ms"),
        fmt(percentile(&w.latencies_ms, 0.99), "ms")
    );
    println!(
        "disparity density median {}  water plane found in {}/{} frames, camera height median {}",
        fmt(percentile(&w.densities, 0.5).map(|d| d * 100.0), "%"),
        w.plane_heights.len(),
        w.disparities,
        fmt(percentile(&w.plane_heights, 0.5), "m")
    );
    println!(
        "{:<12} {:>9} {:>8} {:>7} {:>12} {:>12}  state",
        "service", "processed", "rejected", "errors", "last (ms)", "max (ms)"
    );
    for s in services {
        let ms = |us: Option<u32>| us.map_or("-".into(), |u| format!("{:.1}", u as f64 / 1e3));
        println!(
            "{:<12} {:>9} {:>8} {:>7} {:>12} {:>12}  {}",
            s.name,
            s.processed,
            s.rejected,
            s.errors,
            ms(s.last_processing_us),
            ms(s.max_processing_us),
            s.state
        );
    }
}

/// Reads the recording's summary section back: proves the file is complete and shows what is in it.
fn print_recording(path: &Path) -> anyhow::Result<()> {
    let bytes = std::fs::read(path)?;
    let summary = mcap::Summary::read(&bytes)?
        .ok_or_else(|| anyhow::anyhow!("{} has no summary section", path.display()))?;
    let stats = summary
        .stats
        .ok_or_else(|| anyhow::anyhow!("{} has no statistics", path.display()))?;
    println!(
        "recording {} ({:.1} MB): {} messages on {} channels, {} chunks",
        path.canonicalize()?.display(),
        bytes.len() as f64 / 1e6,
        stats.message_count,
        stats.channel_count,
        stats.chunk_count
    );
    let mut rows: Vec<_> = summary
        .channels
        .values()
        .map(|c| {
            let n = stats
                .channel_message_counts
                .get(&c.id)
                .copied()
                .unwrap_or(0);
            let schema = c
                .schema
                .as_ref()
                .map_or("", |s| s.name.as_str())
                .to_string();
            (c.topic.clone(), schema, n)
        })
        .collect();
    rows.sort();
    for (topic, schema, n) in rows {
        println!("  {topic:<40} {schema:<24} {n:>6}");
    }
    Ok(())
}
