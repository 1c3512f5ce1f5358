//! `usv demo`: the whole process set (simulator, one stereo service per head, perception, mapper,
//! tracker, sequencer, recorder) on a built-in scenario, closed loop and lock-step, in a domain of its
//! own, until the scenario time is up. Then a summary, the recording's contents read back, and an
//! overview picture. The demo watches the set like any other tool: it subscribes to topics and asks
//! the supervisor for `ps`.

use crate::control::ServiceStatus;
use crate::observe::{MissionGoal, Observation, Observer};
use crate::pipeline::{PipelineSpec, Recording, Source};
use crate::session::{checkout_file, ensure_stack_built, has_stopped, percentile, Session};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Scenario (default: services/sim/scenarios/open_water_crossing.toml of this checkout).
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Scenario time to run (s). 30 s include the crossing boat's closest approach.
    #[arg(long, default_value_t = 30.0)]
    duration: f64,
    /// Resolution of the stereo heads as a fraction of the scenario's (1.0 = 1280x960 maritime heads).
    #[arg(long, default_value_t = 0.5)]
    head_scale: f64,
    /// Camera frames per second of scenario time.
    #[arg(long, default_value_t = 5.0)]
    camera_rate: f64,
    /// Directory for the set, the log, the recording and the picture.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    /// Give up after this many seconds of wall time.
    #[arg(long, default_value_t = 900)]
    timeout_s: u64,
}

pub fn run(args: DemoArgs) -> anyhow::Result<()> {
    ensure_stack_built()?;
    let scenario = match &args.scenario {
        Some(p) => p.clone(),
        None => checkout_file("services/sim/scenarios/open_water_crossing.toml")?,
    }
    .canonicalize()?;
    let recording = std::path::absolute(args.out.join("demo.mcap"))?;
    let spec = PipelineSpec {
        name: "demo".into(),
        scenario: scenario.clone(),
        heads: Vec::new(),
        head_scale: args.head_scale,
        source: Source::Sim {
            camera_rate_hz: Some(args.camera_rate),
            duration_s: args.duration,
            truth_head: None,
        },
        algo: "bm".into(),
        closed_loop: true,
        perception: false,
        record: Some(Recording {
            file: recording.clone(),
            topics: Vec::new(),
            lz4: true,
        }),
        lockstep_timeout_ms: 5000,
    };
    let written = crate::pipeline::write(&spec, &args.out)?;
    let goal = match &written.mission {
        Some(m) => MissionGoal::from_mission_text(&std::fs::read_to_string(m)?)?,
        None => MissionGoal::default(),
    };
    let parsed = crate::launchfile::ProcessSet::load(&written.set)?;
    let mut session = Session::start(&written.set, &args.out, "demo")?;
    println!(
        "demo: {} s of {} through {} services (heads {}), closed loop, lock-step\n  set {}\n  log {}",
        args.duration,
        scenario.file_stem().unwrap_or_default().to_string_lossy(),
        parsed.services.len(),
        written.heads.join(", "),
        written.set.display(),
        session.log.display()
    );
    let (obs, services, wall) = watch(&mut session, &args, goal)?;
    let log = session.log.clone();
    session.down()?;
    print_summary(&obs, &services, wall);
    if recording.exists() {
        print_recording(&recording)?;
    }
    let picture = args.out.join("overview.png");
    let arcs = crate::overview::arc_geometry(written.sequencer_config.as_deref())?;
    match crate::overview::write(&obs, &arcs, &picture) {
        Ok(()) => println!(
            "overview picture: {}",
            std::path::absolute(&picture)?.display()
        ),
        Err(e) => println!("no overview picture: {e:#}"),
    }
    anyhow::ensure!(
        obs.frames > 0 && obs.disparities > 0,
        "the demo produced no frames or no disparity: see {}",
        log.display()
    );
    anyhow::ensure!(
        obs.commands > 0,
        "the sequencer commanded nothing: see {}",
        log.display()
    );
    Ok(())
}

fn watch(
    session: &mut Session,
    args: &DemoArgs,
    goal: MissionGoal,
) -> anyhow::Result<(Observation, Vec<ServiceStatus>, Duration)> {
    let started = Instant::now();
    let deadline = started + Duration::from_secs(args.timeout_s);
    let node = runtime::tool_node("usv-demo")?;
    let observer = Observer::new(&node)?;
    let shutdown = runtime::Shutdown::install()?;
    let mut obs = Observation::new(goal);
    let mut last_report = Instant::now();
    let mut services = Vec::new();
    loop {
        session.check_alive()?;
        observer.poll(&mut obs, |_, _| {})?;
        if last_report.elapsed() >= Duration::from_secs(2) {
            last_report = Instant::now();
            if let Ok(s) = session.ps() {
                services = s;
            }
            println!(
                "  {:>5.1} s wall  {:>5.1} s scenario  frames {:>4}  maps {:>4}  commands {:>4}  contacts {:>2}",
                started.elapsed().as_secs_f64(),
                obs.scenario_time_s(),
                obs.frames,
                obs.world_maps,
                obs.commands,
                obs.contacts.len()
            );
            if has_stopped(&services, "sim") {
                // What is still in flight arrives within a moment.
                std::thread::sleep(Duration::from_millis(300));
                observer.poll(&mut obs, |_, _| {})?;
                break;
            }
        }
        anyhow::ensure!(!shutdown.requested(), "interrupted");
        anyhow::ensure!(Instant::now() < deadline, "the demo did not finish in time");
        std::thread::sleep(Duration::from_millis(2));
    }
    Ok((obs, services, started.elapsed()))
}

fn print_summary(o: &Observation, services: &[ServiceStatus], wall: Duration) {
    let fmt = |v: Option<f64>, unit: &str| v.map_or("-".to_string(), |v| format!("{v:.1} {unit}"));
    let report = o.report();
    println!("\n== demo summary ==");
    println!(
        "scenario time {:.1} s in {:.1} s wall; frames {} ({:.2}/s), disparities {}, local maps {}, world maps {}, commands {}",
        o.scenario_time_s(),
        wall.as_secs_f64(),
        o.frames,
        o.frames as f64 / wall.as_secs_f64(),
        o.disparities,
        o.local_maps,
        o.world_maps,
        o.commands
    );
    println!(
        "latency camera->disparity p50 {} p99 {};  camera->command p50 {} p99 {}",
        fmt(percentile(&o.disparity_latency_ms, 0.5), "ms"),
        fmt(percentile(&o.disparity_latency_ms, 0.99), "ms"),
        fmt(percentile(&o.command_latency_ms, 0.5), "ms"),
        fmt(percentile(&o.command_latency_ms, 0.99), "ms"),
    );
    let mut by_class = std::collections::BTreeMap::<&str, usize>::new();
    for (class, _) in o.contacts.values() {
        *by_class
            .entry(messages::contact_class::name(*class))
            .or_default() += 1;
    }
    println!(
        "hazards: up to {} world-map cells at p >= 0.5; tracks confirmed during the run: {} ({})",
        o.max_hazard_cells,
        o.contacts.len(),
        by_class
            .iter()
            .map(|(class, n)| format!("{n} {class}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!(
        "behaviour: step '{}', waypoints reached {}/{}, rudder reversals {:.1}/min, safe-stop commands {}, blocked commands {}",
        report["mission_step"].as_str().unwrap_or("-"),
        o.waypoints_reached(),
        o.goal.waypoints.len(),
        o.reversals_per_minute(),
        o.safe_stop_commands,
        o.blocked_commands
    );
    match o.min_clearance() {
        Some(a) => println!(
            "minimum obstacle distance {:.1} m ({} {} at {:.1} s){}",
            a.clearance_m,
            messages::truth_class::name(a.class),
            a.id,
            a.time_s,
            if a.clearance_m <= 0.0 {
                "  COLLISION"
            } else {
                ""
            }
        ),
        None => println!("minimum obstacle distance: no obstacles in the scenario"),
    }
    println!(
        "{:<18} {:>9} {:>8} {:>7} {:>10} {:>10}  state",
        "service", "processed", "rejected", "errors", "last (ms)", "max (ms)"
    );
    for s in services {
        let ms = |us: Option<u32>| us.map_or("-".into(), |u| format!("{:.1}", u as f64 / 1e3));
        println!(
            "{:<18} {:>9} {:>8} {:>7} {:>10} {:>10}  {}",
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

/// What a finished recording holds, read back from its summary section (which only a complete file
/// has): file size, totals, and (topic, schema, messages) per channel, sorted.
pub struct RecordingContents {
    pub bytes: u64,
    pub messages: u64,
    pub chunks: u64,
    pub channels: Vec<(String, String, u64)>,
}

impl RecordingContents {
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        let bytes = std::fs::read(path)?;
        let summary = mcap::Summary::read(&bytes)?
            .ok_or_else(|| anyhow::anyhow!("{} has no summary section", path.display()))?;
        let stats = summary
            .stats
            .ok_or_else(|| anyhow::anyhow!("{} has no statistics", path.display()))?;
        let mut channels: Vec<_> = summary
            .channels
            .values()
            .map(|c| {
                let n = stats
                    .channel_message_counts
                    .get(&c.id)
                    .copied()
                    .unwrap_or(0);
                let schema = c.schema.as_ref().map_or("", |s| s.name.as_str());
                (c.topic.clone(), schema.to_string(), n)
            })
            .collect();
        channels.sort();
        Ok(Self {
            bytes: bytes.len() as u64,
            messages: stats.message_count,
            chunks: stats.chunk_count as u64,
            channels,
        })
    }

    /// Messages recorded on `topic` (its replay channel; views are channels of their own).
    pub fn count(&self, topic: &str) -> u64 {
        self.channels
            .iter()
            .filter(|(t, _, _)| t == topic)
            .map(|(_, _, n)| n)
            .sum()
    }
}

/// Prints what the recording holds: proves the file is complete and shows what is in it.
fn print_recording(path: &Path) -> anyhow::Result<()> {
    let r = RecordingContents::read(path)?;
    println!(
        "recording {} ({:.1} MB): {} messages on {} channels, {} chunks",
        path.display(),
        r.bytes as f64 / 1e6,
        r.messages,
        r.channels.len(),
        r.chunks
    );
    for (topic, schema, n) in &r.channels {
        println!("  {topic:<40} {schema:<24} {n:>6}");
    }
    Ok(())
}
