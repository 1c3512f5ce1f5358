//! Writes the process set of a run: a source (the simulator as the clock, or a lock-step replay of a
//! recording), one stereo service per head, and (closed loop) perception, mapper, tracker and
//! sequencer with the scenario's mission; the recorder when asked. `usv demo`, `usv eval`,
//! `usv regress` and `usv bench pipeline` all run sets written here, so what they measure is the same
//! graph a user starts with `usv up <dir>/set.toml`.
//!
//! Per-run files (calibrations and stereo configurations for the chosen head scale, the mission) are
//! generated into the run directory; the services' own configurations are the committed files in
//! `launch/sets/`, referenced by absolute path so there is one source of truth for them.

use crate::session::checkout_file;
use anyhow::Context as _;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Water-plane search for simulated waves: the lower half of the rows sees water within ~25 m (a
/// toed head's oversized rectified view has no image in its lowest rows, so a narrower band starves
/// the fit: 0.35 gave 14-18 deg tilt errors), and waves need a loose inlier band.
const PLANE_SEARCH: &str =
    "[plane]\nlower_fraction = 0.5\nmax_range_m = 25.0\n\n[plane.fit]\ninlier_distance = 0.25\n";

/// Where the frames come from.
#[derive(Debug, Clone)]
pub enum Source {
    /// The simulator renders the scenario for this much scenario time.
    Sim {
        camera_rate_hz: Option<f64>,
        duration_s: f64,
        /// Also publish per-pixel truth for this head.
        truth_head: Option<String>,
    },
    /// `sensors replay` of a recording of the scenario (made with the same heads and head scale).
    Replay { file: PathBuf },
}

impl Source {
    /// The source's service name in the set.
    pub fn service_name(&self) -> &'static str {
        match self {
            Source::Sim { .. } => "sim",
            Source::Replay { .. } => "sensors",
        }
    }
}

/// What the recorder of a set writes.
#[derive(Debug, Clone)]
pub struct Recording {
    pub file: PathBuf,
    /// Topics to record; empty: every topic.
    pub topics: Vec<String>,
    /// lz4 for image and grid chunks (smaller files, a little CPU).
    pub lz4: bool,
}

/// What to run.
#[derive(Debug, Clone)]
pub struct PipelineSpec {
    pub name: String,
    pub scenario: PathBuf,
    /// Heads to render and match; empty: the scenario's mono heads (all heads if it has none).
    pub heads: Vec<String>,
    pub head_scale: f64,
    pub source: Source,
    /// Stereo matcher: "bm" or "sgm".
    pub algo: String,
    /// Add perception, mapper, tracker and sequencer (driving the boat when the source is the sim).
    pub closed_loop: bool,
    /// Add perception alone to an open-loop run (hazard-map and water scoring); implied by
    /// `closed_loop`.
    pub perception: bool,
    pub record: Option<Recording>,
    /// Longest wait for the pipeline per frame before the source goes on without it (ms).
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

/// The scenario's heads as the simulator builds them (its own or the built-in head set of its
/// kind): the mono heads, or every head when it has none.
pub fn default_heads(scenario: &Path) -> anyhow::Result<Vec<String>> {
    let text = std::fs::read_to_string(scenario)
        .map_err(|e| anyhow::anyhow!("scenario {}: {e}", scenario.display()))?;
    let parsed = sim::Scenario::parse(&text, &scenario.display().to_string())?;
    let world = parsed.build()?;
    let names = |mono: bool| -> Vec<String> {
        world
            .heads
            .iter()
            .filter(|h| !mono || h.encoding == sim::Encoding::Mono8)
            .map(|h| h.name.clone())
            .collect()
    };
    let mono = names(true);
    Ok(if mono.is_empty() { names(false) } else { mono })
}

fn toml_list(items: &[String]) -> String {
    let quoted: Vec<String> = items.iter().map(|s| format!("\"{s}\"")).collect();
    format!("[{}]", quoted.join(", "))
}

/// Writes `set.toml` and its per-run files into `dir`.
pub fn write(spec: &PipelineSpec, dir: &Path) -> anyhow::Result<WrittenSet> {
    let dir = std::path::absolute(dir)?;
    std::fs::create_dir_all(&dir)?;
    if let Some(rec) = &spec.record {
        recorder::output::remove_with_parts(&rec.file)
            .with_context(|| format!("cannot replace {}", rec.file.display()))?;
    }
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
    if spec.perception && !spec.closed_loop {
        writeln!(
            services,
            "[[service]]\nname = \"perception\"\nprogram = \"perception\"\nargs = [\"run\", \"--config\", \"{}\", \"--heads\", \"{}\"]\n",
            checkout_file("launch/sets/perception.toml")?.canonicalize()?.display(),
            heads.join(",")
        )?;
        pipeline.push("perception".into());
    }
    if spec.closed_loop {
        let config = |file: &str| -> anyhow::Result<PathBuf> {
            Ok(checkout_file(&format!("launch/sets/{file}"))?.canonicalize()?)
        };
        let mission_file = dir.join("mission.toml");
        // A replayed boat does not obey, but the sequencer still plans what it would command.
        let text = sim_output(&sim, &["mission".as_ref(), spec.scenario.as_os_str()])?;
        std::fs::write(&mission_file, text)?;
        let seq_config = config("sequencer.toml")?;
        for (name, extra) in [
            // Perception merges exactly the heads of this run into one map per frame.
            (
                "perception",
                format!(", \"--heads\", \"{}\"", heads.join(",")),
            ),
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
    if let Some(rec) = &spec.record {
        let mut args = vec![
            "--out".to_string(),
            std::path::absolute(&rec.file)?.display().to_string(),
            "--image-view-every".into(),
            "5".into(),
        ];
        if !rec.topics.is_empty() {
            args.extend(["--topics".into(), rec.topics.join(",")]);
        }
        if rec.lz4 {
            args.extend(["--image-compression".into(), "lz4".into()]);
        }
        writeln!(
            services,
            "[[service]]\nname = \"recorder\"\nprogram = \"recorder\"\nargs = {}\n# Not in the lock-step pipeline: it records what flows, including the source's INS and truth.\n",
            toml_list(&args)
        )?;
        depends.push("recorder".into());
    }
    let source_args = match &spec.source {
        Source::Sim {
            camera_rate_hz,
            duration_s,
            truth_head,
        } => {
            let mut args = vec![
                "run".to_string(),
                spec.scenario.display().to_string(),
                "--heads".into(),
                heads.join(","),
                "--head-scale".into(),
                scale.clone(),
                "--duration".into(),
                duration_s.to_string(),
            ];
            if !pipeline.is_empty() {
                args.extend([
                    "--lockstep".into(),
                    pipeline.join(","),
                    "--lockstep-timeout-ms".into(),
                    spec.lockstep_timeout_ms.to_string(),
                ]);
            }
            if let Some(rate) = camera_rate_hz {
                args.extend(["--camera-rate".into(), rate.to_string()]);
            }
            if let Some(head) = truth_head {
                args.extend(["--truth-head".into(), head.clone()]);
            }
            args
        }
        Source::Replay { file } => vec![
            "replay".to_string(),
            std::path::absolute(file)?.display().to_string(),
            "--lockstep".into(),
            "--pipeline".into(),
            pipeline.join(","),
            "--lockstep-timeout".into(),
            (spec.lockstep_timeout_ms as f64 / 1e3).to_string(),
        ],
    };
    let source = spec.source.service_name();
    writeln!(
        services,
        "[[service]]\nname = \"{source}\"\nprogram = \"{source}\"\nargs = {}\n# The source of a run that ends when its scenario time or its recording is over.\nrestart = \"never\"\ndepends_on = {}",
        toml_list(&source_args),
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

/// `usv set`: writes the process set of a simulated run for `usv up`, without running it.
#[derive(clap::Args)]
pub struct SetArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Directory for set.toml and its generated files.
    #[arg(long)]
    out: PathBuf,
    /// Add perception, mapper, tracker and sequencer and let the sequencer drive.
    #[arg(long)]
    closed_loop: bool,
    /// Heads to run (default: the scenario's mono heads).
    #[arg(long, value_delimiter = ',')]
    heads: Vec<String>,
    /// Resolution of the stereo heads as a fraction of the scenario's.
    #[arg(long, default_value_t = 1.0)]
    head_scale: f64,
    /// Camera frames per second of scenario time (default: the scenario's).
    #[arg(long)]
    camera_rate: Option<f64>,
    /// Scenario time to run (s).
    #[arg(long, default_value_t = 30.0)]
    duration: f64,
    /// Stereo matcher: bm or sgm.
    #[arg(long, default_value = "bm")]
    algo: String,
    /// Record every topic to this MCAP file.
    #[arg(long)]
    record: Option<PathBuf>,
    /// Longest wait for the pipeline per frame before the simulator goes on (ms).
    #[arg(long, default_value_t = 5000)]
    lockstep_timeout_ms: u64,
}

pub fn run_set(args: SetArgs) -> anyhow::Result<()> {
    let spec = PipelineSpec {
        name: args
            .scenario
            .file_stem()
            .map_or("set".into(), |s| s.to_string_lossy().into_owned()),
        scenario: args.scenario.canonicalize()?,
        heads: args.heads,
        head_scale: args.head_scale,
        source: Source::Sim {
            camera_rate_hz: args.camera_rate,
            duration_s: args.duration,
            truth_head: None,
        },
        algo: args.algo,
        closed_loop: args.closed_loop,
        perception: false,
        record: args.record.map(|file| Recording {
            file,
            topics: Vec::new(),
            lz4: true,
        }),
        lockstep_timeout_ms: args.lockstep_timeout_ms,
    };
    let written = write(&spec, &args.out)?;
    println!("{}", written.set.display());
    Ok(())
}
