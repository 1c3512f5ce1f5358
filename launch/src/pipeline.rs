//! Writes the process set of a simulated run: the simulator as the clock, one stereo service per
//! head, and (closed loop) perception, mapper, tracker and sequencer with the scenario's mission; the
//! recorder when asked. `usv demo`, `usv eval` and `usv bench pipeline` all run sets written here, so
//! what they measure is the same graph a user starts with `usv up <dir>/set.toml`.
//!
//! Per-run files (calibrations and stereo configurations for the chosen head scale, the mission) are
//! generated into the run directory; the services' own configurations are the committed files in
//! `launch/sets/`, referenced by absolute path so there is one source of truth for them.

use crate::session::checkout_file;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Water-plane search for simulated waves: the lower rows see water within ~25 m, and waves need a
/// loose inlier band.
const PLANE_SEARCH: &str =
    "[plane]\nlower_fraction = 0.35\nmax_range_m = 25.0\n\n[plane.fit]\ninlier_distance = 0.25\n";

/// What to run.
#[derive(Debug, Clone)]
pub struct PipelineSpec {
    pub name: String,
    pub scenario: PathBuf,
    /// Heads to render and match; empty: the scenario's mono heads (all heads if it has none).
    pub heads: Vec<String>,
    pub head_scale: f64,
    pub camera_rate_hz: Option<f64>,
    pub duration_s: f64,
    /// Stereo matcher: "bm" or "sgm".
    pub algo: String,
    /// Add perception, mapper, tracker and sequencer, and drive the boat with the sequencer.
    pub closed_loop: bool,
    /// Also publish per-pixel truth for this head.
    pub truth_head: Option<String>,
    /// Record every topic to this MCAP file.
    pub record: Option<PathBuf>,
    /// Longest wait for the pipeline per frame before the simulator goes on without it (ms).
    pub lockstep_timeout_ms: u64,
}

/// The files of a written set.
#[derive(Debug, Clone)]
pub struct WrittenSet {
    pub set: PathBuf,
    pub heads: Vec<String>,
    /// The mission the sequencer starts with (closed loop only).
    pub mission: Option<PathBuf>,
    /// The sequencer's configuration (closed loop only).
    pub sequencer_config: Option<PathBuf>,
}

fn sim_program(dir: &Path) -> anyhow::Result<PathBuf> {
    crate::launchfile::resolve_program("sim", dir)
        .ok_or_else(|| anyhow::anyhow!("the `sim` program was not found next to usv"))
}

fn sim_output(sim: &Path, args: &[&std::ffi::OsStr]) -> anyhow::Result<Vec<u8>> {
    let out = Command::new(sim).args(args).output()?;
    anyhow::ensure!(
        out.status.success(),
        "`sim {}` failed: {}",
        args.first().map_or("".into(), |a| a.to_string_lossy()),
        String::from_utf8_lossy(&out.stderr).trim()
    );
    Ok(out.stdout)
}

/// The scenario's heads, as `sim calib` sees them: mono heads first choice.
pub fn default_heads(scenario: &Path) -> anyhow::Result<Vec<String>> {
    let text = std::fs::read_to_string(scenario)?;
    let value: toml::Value = toml::from_str(&text)?;
    let kind = value
        .get("kind")
        .and_then(|k| k.as_str())
        .unwrap_or("maritime");
    if let Some(heads) = value.get("heads").and_then(|h| h.as_array()) {
        let names = |mono: bool| -> Vec<String> {
            heads
                .iter()
                .filter(|h| !mono || h.get("encoding").and_then(|e| e.as_str()) == Some("mono8"))
                .filter_map(|h| h.get("name")?.as_str().map(str::to_string))
                .collect()
        };
        let mono = names(true);
        return Ok(if mono.is_empty() { names(false) } else { mono });
    }
    // The simulator's built-in head sets (sim::StereoHead::{maritime,ground}_defaults).
    Ok(match kind {
        "ground" => vec!["color".into()],
        _ => vec!["hh_left".into(), "hh_right".into()],
    })
}

fn toml_list(items: &[String]) -> String {
    let quoted: Vec<String> = items.iter().map(|s| format!("\"{s}\"")).collect();
    format!("[{}]", quoted.join(", "))
}

/// Writes `set.toml` and its per-run files into `dir`.
pub fn write(spec: &PipelineSpec, dir: &Path) -> anyhow::Result<WrittenSet> {
    let dir = std::path::absolute(dir)?;
    std::fs::create_dir_all(&dir)?;
    let sim = sim_program(&dir)?;
    let heads = if spec.heads.is_empty() {
        default_heads(&spec.scenario)?
    } else {
        spec.heads.clone()
    };
    let scale = format!("{}", spec.head_scale);
    let mut services = String::new();
    let mut pipeline = Vec::new();
    for head in &heads {
        let calib = dir.join(format!("calib-{head}.toml"));
        let out = sim_output(
            &sim,
            &[
                "calib".as_ref(),
                spec.scenario.as_os_str(),
                "--head".as_ref(),
                head.as_ref(),
                "--head-scale".as_ref(),
                scale.as_ref(),
                "--out".as_ref(),
                calib.as_os_str(),
            ],
        )?;
        let info: serde_json::Value = serde_json::from_slice(&out)?;
        let m = &info["mount"];
        let config = format!("stereo-{head}.toml");
        std::fs::write(
            dir.join(&config),
            format!(
                "head = \"{head}\"\ncalibration = \"calib-{head}.toml\"\n\n[matcher]\nalgo = \"{}\"\n\n[mount]\nposition = {}\nroll_deg = {}\npitch_deg = {}\nyaw_deg = {}\n\n{PLANE_SEARCH}",
                spec.algo, m["position"], m["roll_deg"], m["pitch_deg"], m["yaw_deg"]
            ),
        )?;
        let name = format!("stereo-{head}");
        writeln!(
            services,
            "[[service]]\nname = \"{name}\"\nprogram = \"stereo\"\nargs = [\"run\", \"--config\", \"{config}\"]\n"
        )?;
        pipeline.push(name);
    }
    let mut mission = None;
    let mut sequencer_config = None;
    if spec.closed_loop {
        let config = |file: &str| -> anyhow::Result<PathBuf> {
            Ok(checkout_file(&format!("launch/sets/{file}"))?.canonicalize()?)
        };
        let mission_file = dir.join("mission.toml");
        let text = sim_output(&sim, &["mission".as_ref(), spec.scenario.as_os_str()])?;
        std::fs::write(&mission_file, text)?;
        let seq_config = config("sequencer.toml")?;
        for (name, extra) in [
            ("perception", String::new()),
            ("mapper", String::new()),
            ("tracker", String::new()),
            (
                "sequencer",
                format!(", \"--mission\", \"{}\"", mission_file.display()),
            ),
        ] {
            writeln!(
                services,
                "[[service]]\nname = \"{name}\"\nprogram = \"{name}\"\nargs = [\"run\", \"--config\", \"{}\"{extra}]\n",
                config(&format!("{name}.toml"))?.display()
            )?;
            pipeline.push(name.to_string());
        }
        mission = Some(mission_file);
        sequencer_config = Some(seq_config);
    }
    let mut depends = pipeline.clone();
    if let Some(out) = &spec.record {
        writeln!(
            services,
            "[[service]]\nname = \"recorder\"\nprogram = \"recorder\"\nargs = [\"--out\", \"{}\", \"--image-view-every\", \"5\"]\n# Not in the lock-step pipeline: it records what flows, including the simulator's INS and truth.\n",
            std::path::absolute(out)?.display()
        )?;
        depends.push("recorder".into());
    }
    let mut sim_args = vec![
        "run".to_string(),
        spec.scenario.display().to_string(),
        "--heads".into(),
        heads.join(","),
        "--head-scale".into(),
        scale.clone(),
        "--lockstep".into(),
        pipeline.join(","),
        "--lockstep-timeout-ms".into(),
        spec.lockstep_timeout_ms.to_string(),
        "--duration".into(),
        spec.duration_s.to_string(),
    ];
    if let Some(rate) = spec.camera_rate_hz {
        sim_args.extend(["--camera-rate".into(), rate.to_string()]);
    }
    if let Some(head) = &spec.truth_head {
        sim_args.extend(["--truth-head".into(), head.clone()]);
    }
    writeln!(
        services,
        "[[service]]\nname = \"sim\"\nprogram = \"sim\"\nargs = {}\n# The source of a run that ends when its scenario time is up.\nrestart = \"never\"\ndepends_on = {}",
        toml_list(&sim_args),
        toml_list(&depends)
    )?;
    let set = dir.join("set.toml");
    std::fs::write(
        &set,
        format!(
            "# Written by `usv` for scenario {}; start it again with `usv up {}`.\nname = \"{}\"\nheartbeat_timeout_ms = 5000\nstop_grace_ms = 3000\n\n{services}",
            spec.scenario.display(),
            set.display(),
            spec.name
        ),
    )?;
    Ok(WrittenSet {
        set,
        heads,
        mission,
        sequencer_config,
    })
}
