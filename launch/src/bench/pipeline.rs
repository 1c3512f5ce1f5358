//! `usv bench pipeline`: the whole stack on one stereo head (stereo, perception, mapper, tracker,
//! sequencer as separate processes over shared memory), closed loop on the simulator, at 640x480 and
//! 1280x960. Figures per size:
//! - camera-to-command latency (p50, p99): from the frame's arrival in shared memory to the command
//!   derived from it; lock-step keeps one frame in flight, so 1000 / p50 is the frame rate the
//!   pipeline sustains on this machine (the simulator's render time is not part of it);
//! - wall frame rate including the render (what `usv demo` sees);
//! - CPU time per frame and peak resident memory of every service, from /proc.

use super::Figure;
use crate::observe::{MissionGoal, Observation, Observer};
use crate::pipeline::{PipelineSpec, Source};
use crate::session::{checkout_file, has_stopped, percentile, Session};
use std::time::{Duration, Instant};

/// CPU seconds (user + system) and peak resident set (MiB) of a live process.
fn usage(pid: u32) -> Option<(f64, f64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name, which may contain spaces: state is field 3, utime 14, stime 15.
    let rest: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let ticks: f64 = rest.get(11)?.parse::<f64>().ok()? + rest.get(12)?.parse::<f64>().ok()?;
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let hwm_kib: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    Some((ticks / hz, hwm_kib / 1024.0))
}

pub fn run(quick: bool) -> anyhow::Result<Vec<Figure>> {
    crate::session::ensure_stack_built()?;
    let scenario =
        checkout_file("services/sim/scenarios/open_water_crossing.toml")?.canonicalize()?;
    let mut figures = Vec::new();
    for (scale, size) in [(0.5, "640x480"), (1.0, "1280x960")] {
        let dir = tempfile::tempdir()?;
        let spec = PipelineSpec {
            name: "bench-pipeline".into(),
            scenario: scenario.clone(),
            heads: vec!["hh_left".into()],
            head_scale: scale,
            source: Source::Sim {
                camera_rate_hz: Some(5.0),
                duration_s: if quick { 2.0 } else { 10.0 },
                truth_head: None,
            },
            algo: "bm".into(),
            closed_loop: true,
            perception: false,
            record: None,
            lockstep_timeout_ms: 5000,
        };
        let written = crate::pipeline::write(&spec, dir.path())?;
        let mut session = Session::start(&written.set, dir.path(), "bench")?;
        let started = Instant::now();
        let (obs, usages) = {
            let node = runtime::tool_node("usv-bench-pipeline")?;
            let observer = Observer::new(&node)?;
            let mut obs = Observation::new(MissionGoal::default());
            let mut usages = std::collections::BTreeMap::new();
            let mut last_ps = Instant::now();
            loop {
                session.check_alive()?;
                observer.poll(&mut obs, |_, _| {})?;
                if last_ps.elapsed() > Duration::from_millis(250) {
                    last_ps = Instant::now();
                    let services = session.ps()?;
                    // Read usage while the processes live; the newest reading wins.
                    for s in &services {
                        if let Some(u) = s.pid.and_then(usage) {
                            usages.insert(s.name.clone(), u);
                        }
                    }
                    if has_stopped(&services, "sim") {
                        break;
                    }
                }
                anyhow::ensure!(
                    started.elapsed() < Duration::from_secs(900),
                    "the pipeline benchmark did not finish in time"
                );
                std::thread::sleep(Duration::from_millis(2));
            }
            (obs, usages)
        };
        let wall = started.elapsed().as_secs_f64();
        session.down()?;
        let frames = obs.frames.max(1) as f64;
        let p50 = percentile(&obs.command_latency_ms, 0.5).unwrap_or(f64::NAN);
        let label = |f: Figure| f.label("size", size);
        figures.push(label(Figure::new("camera_to_command_p50", p50, "ms")));
        figures.push(label(Figure::new(
            "camera_to_command_p99",
            percentile(&obs.command_latency_ms, 0.99).unwrap_or(f64::NAN),
            "ms",
        )));
        figures.push(label(Figure::new(
            "pipeline_rate_lockstep",
            1000.0 / p50,
            "frames/s",
        )));
        figures.push(label(Figure::new(
            "wall_rate_with_render",
            obs.frames as f64 / wall,
            "frames/s",
        )));
        for (name, (cpu_s, peak_mib)) in usages {
            figures.push(label(
                Figure::new(format!("{name}_cpu_per_frame"), cpu_s * 1e3 / frames, "ms")
                    .label("service", name.clone()),
            ));
            figures.push(label(
                Figure::new(format!("{name}_peak_rss"), peak_mib, "MiB")
                    .label("service", name.clone()),
            ));
        }
    }
    Ok(figures)
}
