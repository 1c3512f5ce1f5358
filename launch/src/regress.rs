//! `usv regress <dir>`: the replay regression test. A short recording of a simulated run is replayed
//! lock-step through every service (stereo per head, perception, mapper, tracker, sequencer); a digest
//! of each frame's outputs is compared with the committed expectations in `<dir>/expected.json`.
//!
//! - `usv regress <dir>` compares and fails on any difference beyond the tolerances below;
//! - `usv regress <dir> --update` rewrites the expectations on purpose (after a deliberate change);
//! - `usv regress <dir> --record` renders the recording again from the scenario.
//!
//! `<dir>/regress.toml` names the scenario (for calibrations and the mission), the heads and the head
//! scale the recording was made with.

use crate::pipeline::{PipelineSpec, Recording, Source};
use crate::session::{has_stopped, Session};
use messages::{topics, MapCell};
use runtime::Ports;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

// Tolerances. Lock-step replay is deterministic on one machine; these allow for floating-point
// differences between CPUs (SIMD paths, libm) while still catching any change of behaviour.
/// Share of valid disparity pixels (absolute).
const DENSITY_TOL: f64 = 0.01;
/// Median disparity (px).
const MEDIAN_DISPARITY_TOL: f64 = 0.25;
/// Hazard cells of a map: the larger of this count and 5 % of the expected count.
const HAZARD_CELLS_TOL: f64 = 4.0;
/// Centroid of a map's hazard cells, and contact positions (m).
const POSITION_TOL_M: f64 = 1.0;
/// Rudder (rad) and throttle (percent) of the command.
const RUDDER_TOL: f64 = 0.02;
const THROTTLE_TOL: f64 = 2.0;

#[derive(clap::Args)]
pub struct RegressArgs {
    /// Directory with regress.toml, the recording and expected.json.
    dir: PathBuf,
    /// Rewrite expected.json from this run instead of comparing.
    #[arg(long, conflicts_with = "record")]
    update: bool,
    /// Render the recording again from the scenario (then run with --update).
    #[arg(long)]
    record: bool,
    /// Give up after this many seconds of wall time.
    #[arg(long, default_value_t = 600)]
    timeout_s: u64,
    /// Keep the run directory (generated set, configurations, the set's log) for a look after.
    #[arg(long)]
    keep: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RegressConfig {
    /// Scenario file, relative to the directory.
    scenario: PathBuf,
    recording: PathBuf,
    heads: Vec<String>,
    head_scale: f64,
    /// For --record: scenario time and camera rate.
    duration_s: f64,
    camera_rate_hz: f64,
}

/// What one frame produced, reduced to figures that mean something.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
struct FrameDigest {
    /// Per head: share of valid pixels and median disparity.
    disparity: BTreeMap<String, (f64, f64)>,
    /// Hazard cells (p >= 0.5) of the newest local map of the frame.
    local_hazard_cells: Option<u64>,
    /// Hazard cells and their centroid (ENU) in the newest world map of the frame.
    world_hazard_cells: Option<u64>,
    world_hazard_centroid: Option<[f64; 2]>,
    /// Confirmed contacts (class, east, north), sorted.
    contacts: Option<Vec<(u8, f64, f64)>>,
    /// Rudder (rad), throttle (%), mode of the newest command of the frame.
    command: Option<(f64, f64, u8)>,
}

#[derive(Debug, Default, Serialize, Deserialize)]
struct Expectations {
    /// Frame stamp (ns) -> digest.
    frames: BTreeMap<u64, FrameDigest>,
}

pub fn run(args: RegressArgs) -> anyhow::Result<()> {
    crate::session::ensure_stack_built()?;
    let dir = args.dir.canonicalize()?;
    let config: RegressConfig = runtime::config::load(&dir.join("regress.toml"))?;
    let scenario = dir.join(&config.scenario).canonicalize()?;
    let work = std::env::temp_dir().join(format!("usv-regress-{}", std::process::id()));
    let result = if args.record {
        record(&config, &scenario, &dir, &work, &args)
    } else {
        replay(&config, &scenario, &dir, &work, &args)
    };
    if args.keep {
        println!("run directory kept: {}", work.display());
    } else {
        let _ = std::fs::remove_dir_all(&work);
    }
    result
}

fn spec(config: &RegressConfig, scenario: &Path, source: Source) -> PipelineSpec {
    PipelineSpec {
        name: "regress".into(),
        scenario: scenario.to_path_buf(),
        heads: config.heads.clone(),
        head_scale: config.head_scale,
        source,
        algo: "bm".into(),
        closed_loop: true,
        perception: false,
        record: None,
        lockstep_timeout_ms: 10_000,
    }
}

/// Runs the scenario closed loop and records only what a replay needs (frames and INS).
fn record(
    config: &RegressConfig,
    scenario: &Path,
    dir: &Path,
    work: &Path,
    args: &RegressArgs,
) -> anyhow::Result<()> {
    let mut spec = spec(
        config,
        scenario,
        Source::Sim {
            camera_rate_hz: Some(config.camera_rate_hz),
            duration_s: config.duration_s,
            truth_head: None,
        },
    );
    let file = dir.join(&config.recording);
    spec.record = Some(Recording {
        file: file.clone(),
        topics: vec![topics::STEREO_FRAME.name.into(), topics::INS.name.into()],
        lz4: true,
    });
    let written = crate::pipeline::write(&spec, work)?;
    let mut session = Session::start(&written.set, work, "regress")?;
    wait_for_source(&mut session, "sim", args.timeout_s, |_| Ok(()))?;
    session.down()?;
    println!(
        "recorded {} ({:.1} MB); now run `usv regress {} --update`",
        file.display(),
        std::fs::metadata(&file)?.len() as f64 / 1e6,
        args.dir.display()
    );
    Ok(())
}

/// Runs a set until its source has stopped, calling `poll` all along. The caller takes the set
/// down once its own nodes are gone (a live node's files would be left in the domain).
fn wait_for_source(
    session: &mut Session,
    source: &str,
    timeout_s: u64,
    mut poll: impl FnMut(&mut Session) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(timeout_s);
    let mut last_ps = Instant::now();
    loop {
        session.check_alive()?;
        poll(session)?;
        if last_ps.elapsed() > Duration::from_millis(300) {
            last_ps = Instant::now();
            if has_stopped(&session.ps()?, source) {
                // Outputs of the last frame are still on their way.
                std::thread::sleep(Duration::from_millis(500));
                poll(session)?;
                return Ok(());
            }
        }
        anyhow::ensure!(Instant::now() < deadline, "the run did not finish in time");
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn replay(
    config: &RegressConfig,
    scenario: &Path,
    dir: &Path,
    work: &Path,
    args: &RegressArgs,
) -> anyhow::Result<()> {
    let file = dir.join(&config.recording);
    anyhow::ensure!(
        file.exists(),
        "no recording {}: make it with `usv regress {} --record`",
        file.display(),
        args.dir.display()
    );
    let spec = spec(config, scenario, Source::Replay { file });
    let written = crate::pipeline::write(&spec, work)?;
    let mut session = Session::start(&written.set, work, "regress")?;
    let mut got = Expectations::default();
    {
        let node = runtime::tool_node("usv-regress")?;
        let disparity = topics::DISPARITY.subscriber(&node)?;
        let local_map = topics::LOCAL_MAP.subscriber(&node)?;
        let world_map = topics::WORLD_MAP.subscriber(&node)?;
        let contacts = topics::CONTACTS.subscriber(&node)?;
        let commands = topics::ACTUATOR_COMMAND.subscriber(&node)?;
        wait_for_source(&mut session, "sensors", args.timeout_s, |_| {
            let frames = &mut got.frames;
            while let Some(s) = disparity.receive()? {
                let h = s.user_header();
                frames
                    .entry(h.hdr.stamp_ns)
                    .or_default()
                    .disparity
                    .insert(h.head.as_str().to_string(), disparity_digest(s.payload()));
            }
            while let Some(s) = local_map.receive()? {
                let d = frames.entry(s.user_header().hdr.stamp_ns).or_default();
                d.local_hazard_cells = Some(hazards_at(&s.user_header().grid, s.payload()).0);
            }
            while let Some(s) = world_map.receive()? {
                let h = s.user_header();
                let d = frames.entry(h.hdr.stamp_ns).or_default();
                let (n, sum) = hazards_at(&h.grid, s.payload());
                d.world_hazard_cells = Some(n);
                d.world_hazard_centroid = (n > 0).then(|| [sum[0] / n as f64, sum[1] / n as f64]);
            }
            while let Some(s) = contacts.receive()? {
                let list = s.payload();
                let mut c: Vec<_> = list
                    .as_slice()
                    .iter()
                    .filter(|c| c.confirmed == 1)
                    .map(|c| (c.class, round(c.position[0]), round(c.position[1])))
                    .collect();
                c.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
                frames.entry(list.hdr.stamp_ns).or_default().contacts = Some(c);
            }
            while let Some(s) = commands.receive()? {
                let c = s.payload();
                frames.entry(c.hdr.stamp_ns).or_default().command = Some((
                    round(c.rudder_rad as f64),
                    round(c.throttle_pct as f64),
                    c.mode,
                ));
            }
            Ok(())
        })?;
    }
    session.down()?;
    // Commands also follow INS samples between frames; only frames with a disparity are frames.
    got.frames.retain(|_, d| !d.disparity.is_empty());
    let expected_file = dir.join("expected.json");
    if args.update {
        std::fs::write(&expected_file, serde_json::to_string_pretty(&got)? + "\n")?;
        println!(
            "wrote {} ({} frames)",
            expected_file.display(),
            got.frames.len()
        );
        return Ok(());
    }
    let expected: Expectations = serde_json::from_str(
        &std::fs::read_to_string(&expected_file)
            .map_err(|e| anyhow::anyhow!("{}: {e}", expected_file.display()))?,
    )?;
    let failures = compare(&expected, &got);
    println!(
        "replayed {} frames through {} services: {} of {} expected frames differ",
        got.frames.len(),
        written.heads.len() + 4,
        failures.len(),
        expected.frames.len()
    );
    for f in failures.iter().take(20) {
        println!("  {f}");
    }
    anyhow::ensure!(
        failures.is_empty(),
        "outputs differ from {}; if the change is deliberate, run `usv regress {} --update`",
        expected_file.display(),
        args.dir.display()
    );
    Ok(())
}

fn round(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

fn disparity_digest(d: &[f32]) -> (f64, f64) {
    let mut valid: Vec<f32> = d.iter().copied().filter(|v| v.is_finite()).collect();
    let density = valid.len() as f64 / d.len().max(1) as f64;
    let median = if valid.is_empty() {
        0.0
    } else {
        let mid = valid.len() / 2;
        *valid.select_nth_unstable_by(mid, f32::total_cmp).1 as f64
    };
    (round(density), round(median))
}

/// Hazard cells of a map and the sum of their ENU centres.
fn hazards_at(grid: &messages::GridGeometry, cells: &[MapCell]) -> (u64, [f64; 2]) {
    crate::observe::hazard_cells(grid, cells).fold((0, [0.0; 2]), |(n, sum), (c, _)| {
        (n + 1, [sum[0] + c[0], sum[1] + c[1]])
    })
}

fn close_count(expected: u64, got: u64) -> bool {
    (expected as f64 - got as f64).abs() <= HAZARD_CELLS_TOL.max(0.05 * expected as f64)
}

/// Every difference beyond tolerance, one line each.
fn compare(expected: &Expectations, got: &Expectations) -> Vec<String> {
    let mut out = Vec::new();
    for (stamp, e) in &expected.frames {
        let Some(g) = got.frames.get(stamp) else {
            out.push(format!("frame {stamp}: no outputs"));
            continue;
        };
        let mut diffs = Vec::new();
        for (head, &(ed, em)) in &e.disparity {
            match g.disparity.get(head) {
                Some(&(gd, gm)) => {
                    if (ed - gd).abs() > DENSITY_TOL || (em - gm).abs() > MEDIAN_DISPARITY_TOL {
                        diffs.push(format!(
                            "{head} disparity density/median {ed:.3}/{em:.2} -> {gd:.3}/{gm:.2}"
                        ));
                    }
                }
                None => diffs.push(format!("{head}: no disparity")),
            }
        }
        let count =
            |name: &str, e: Option<u64>, g: Option<u64>, diffs: &mut Vec<String>| match (e, g) {
                (Some(e), Some(g)) if close_count(e, g) => {}
                (None, _) => {}
                (e, g) => diffs.push(format!("{name} {e:?} -> {g:?}")),
            };
        count(
            "local-map hazard cells",
            e.local_hazard_cells,
            g.local_hazard_cells,
            &mut diffs,
        );
        count(
            "world-map hazard cells",
            e.world_hazard_cells,
            g.world_hazard_cells,
            &mut diffs,
        );
        if let (Some(ec), Some(gc)) = (e.world_hazard_centroid, g.world_hazard_centroid) {
            if (ec[0] - gc[0]).hypot(ec[1] - gc[1]) > POSITION_TOL_M {
                diffs.push(format!("world-map hazard centroid {ec:?} -> {gc:?}"));
            }
        }
        if let Some(ec) = &e.contacts {
            let same = g.contacts.as_ref().is_some_and(|gc| {
                gc.len() == ec.len()
                    && ec
                        .iter()
                        .zip(gc)
                        .all(|(a, b)| a.0 == b.0 && (a.1 - b.1).hypot(a.2 - b.2) <= POSITION_TOL_M)
            });
            if !same {
                diffs.push(format!("contacts {ec:?} -> {:?}", g.contacts));
            }
        }
        if let Some((er, et, em)) = e.command {
            let same = g.command.is_some_and(|(gr, gt, gm)| {
                (er - gr).abs() <= RUDDER_TOL && (et - gt).abs() <= THROTTLE_TOL && em == gm
            });
            if !same {
                diffs.push(format!("command {:?} -> {:?}", e.command, g.command));
            }
        }
        if !diffs.is_empty() {
            out.push(format!("frame {stamp}: {}", diffs.join("; ")));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn digest() -> FrameDigest {
        FrameDigest {
            disparity: [("hh_left".to_string(), (0.8, 12.0))].into(),
            local_hazard_cells: Some(100),
            world_hazard_cells: Some(200),
            world_hazard_centroid: Some([10.0, 50.0]),
            contacts: Some(vec![(1, 10.0, 50.0)]),
            command: Some((0.1, 40.0, 1)),
        }
    }

    fn one(d: FrameDigest) -> Expectations {
        Expectations {
            frames: [(7, d)].into(),
        }
    }

    #[test]
    fn equal_runs_pass_and_small_float_noise_is_tolerated() {
        let e = one(digest());
        assert!(compare(&e, &one(digest())).is_empty());
        let mut noisy = digest();
        noisy.disparity.insert("hh_left".into(), (0.805, 12.1));
        noisy.world_hazard_cells = Some(203);
        noisy.command = Some((0.11, 41.0, 1));
        assert!(compare(&e, &one(noisy)).is_empty());
    }

    #[test]
    fn behaviour_changes_are_caught() {
        let e = one(digest());
        type Change = Box<dyn Fn(&mut FrameDigest)>;
        let changes: Vec<Change> = vec![
            Box::new(|d| d.command = Some((-0.2, 40.0, 1))),
            Box::new(|d| d.command = Some((0.1, 40.0, 2))),
            Box::new(|d| d.contacts = Some(vec![])),
            Box::new(|d| d.contacts = Some(vec![(1, 13.0, 50.0)])),
            Box::new(|d| d.world_hazard_centroid = Some([12.0, 50.0])),
            Box::new(|d| d.local_hazard_cells = Some(80)),
            Box::new(|d| {
                d.disparity.insert("hh_left".into(), (0.7, 12.0));
            }),
        ];
        for change in changes {
            let mut g = digest();
            change(&mut g);
            assert_eq!(compare(&e, &one(g)).len(), 1);
        }
        assert_eq!(compare(&e, &Expectations::default()).len(), 1);
    }
}
