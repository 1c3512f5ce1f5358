//! `usv bench <name>`: the one place where the project's performance figures are reproduced on the
//! user's hardware. Every benchmark prints a table, or with `--json` one JSON object per figure.

pub mod ipc;
pub mod pipeline;
pub mod sim;

use serde_json::json;

/// One named figure of a benchmark.
pub struct Figure {
    pub name: String,
    pub value: f64,
    pub unit: &'static str,
    /// Extra labels (size, mode ...), printed as JSON fields.
    pub labels: Vec<(&'static str, serde_json::Value)>,
}

impl Figure {
    pub fn new(name: impl Into<String>, value: f64, unit: &'static str) -> Self {
        Self {
            name: name.into(),
            value,
            unit,
            labels: Vec::new(),
        }
    }

    pub fn label(mut self, key: &'static str, value: impl Into<serde_json::Value>) -> Self {
        self.labels.push((key, value.into()));
        self
    }

    pub fn json_line(&self, bench: &str) -> String {
        let mut obj =
            json!({"bench": bench, "figure": self.name, "value": self.value, "unit": self.unit});
        for (k, v) in &self.labels {
            obj[*k] = v.clone();
        }
        obj.to_string()
    }
}

pub const NAMES: &[&str] = &[
    "ipc", "recorder", "sim", "pipeline", "stereo", "hazard", "water", "mapper", "tracker", "arcs",
];

/// A benchmark that lives in another program (`<program> <args...>`): `usv bench` runs it so every
/// figure has one entry point. Arguments may name checkout files (`@` + relative path) or programs
/// next to `usv` (`%` + name).
struct Delegated {
    name: &'static str,
    program: &'static str,
    args: &'static [&'static str],
    /// Added for `--quick`.
    quick: &'static [&'static str],
}

const DELEGATED: &[Delegated] = &[
    Delegated {
        name: "mapper",
        program: "mapper",
        args: &["bench"],
        quick: &["--quick"],
    },
    Delegated {
        name: "tracker",
        program: "tracker",
        args: &["bench", "--config", "@launch/sets/tracker.toml"],
        quick: &["--quick"],
    },
    Delegated {
        name: "arcs",
        program: "sequencer",
        args: &["bench"],
        quick: &["--quick"],
    },
    Delegated {
        name: "hazard",
        program: "perception",
        args: &["bench", "hazard"],
        quick: &["--quick"],
    },
    Delegated {
        name: "water",
        program: "perception",
        args: &["bench", "water"],
        quick: &["--quick"],
    },
    // Our BM and SGM beside OpenCV StereoBM and SGBM-3WAY, same inputs, same run (the script
    // pip-installs opencv-python-headless when it is missing).
    Delegated {
        name: "stereo",
        program: "python3",
        args: &[
            "@services/stereo/scripts/compare_opencv.py",
            "--bin",
            "%stereo",
        ],
        quick: &["--repeat", "2", "--rounds", "1"],
    },
];

fn program_path(program: &str) -> anyhow::Result<std::path::PathBuf> {
    crate::launchfile::resolve_program(program, std::path::Path::new("."))
        .ok_or_else(|| anyhow::anyhow!("the `{program}` program was not found next to usv"))
}

/// Runs a delegated benchmark if `name` is one; its output goes straight to the terminal.
pub fn run_service_bench(name: &str, quick: bool) -> anyhow::Result<bool> {
    let Some(bench) = DELEGATED.iter().find(|b| b.name == name) else {
        return Ok(false);
    };
    let mut cmd = std::process::Command::new(program_path(bench.program)?);
    let extra: &[&str] = if quick { bench.quick } else { &[] };
    for a in bench.args.iter().chain(extra) {
        if let Some(file) = a.strip_prefix('@') {
            cmd.arg(crate::session::checkout_file(file)?);
        } else if let Some(program) = a.strip_prefix('%') {
            cmd.arg(program_path(program)?);
        } else {
            cmd.arg(a);
        }
    }
    let status = cmd.status()?;
    anyhow::ensure!(
        status.success(),
        "`{}` bench failed: {status}",
        bench.program
    );
    Ok(true)
}

/// `usv bench recorder`: the recorder's MCAP writer against a plain file write of the same bytes,
/// then the recorder process live: 2 heads x 1280x960 mono pairs at 10 Hz over shared memory.
pub fn recorder(quick: bool) -> anyhow::Result<Vec<Figure>> {
    let mut figures: Vec<Figure> = recorder::bench::run(quick)
        .into_iter()
        .map(|(name, value, unit)| Figure::new(name, value, unit))
        .collect();
    figures.extend(recorder_live(if quick { 2.0 } else { 10.0 })?);
    Ok(figures)
}

fn recorder_live(seconds: f64) -> anyhow::Result<Vec<Figure>> {
    use messages::{topics, Header, Name, PixelEncoding, StereoFrameHeader};
    use runtime::Ports;
    use std::time::{Duration, Instant};
    let (width, height) = (1280u32, 960u32);
    let dir = tempfile::tempdir()?;
    let file = dir.path().join("live.mcap");
    let program = program_path("recorder")?;
    let node = runtime::tool_node("usv-bench-rec")?;
    let mut frames = topics::STEREO_FRAME.publisher(&node)?;
    let recorder = std::process::Command::new(program)
        .args([
            "--topics",
            topics::STEREO_FRAME.name,
            "--no-foxglove",
            "--json",
            "--out",
        ])
        .arg(&file)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()?;
    let connect = Instant::now() + Duration::from_secs(10);
    while frames.subscriber_count() == 0 {
        anyhow::ensure!(Instant::now() < connect, "the recorder did not subscribe");
        std::thread::sleep(Duration::from_millis(5));
    }
    let plane = (width * height) as usize;
    let periods = (seconds * 10.0) as u64;
    let start = Instant::now();
    for k in 0..periods {
        for head in ["port", "starboard"] {
            let mut sample = frames.loan_slice(2 * plane)?;
            sample.payload_mut().fill(k as u8);
            *sample.user_header_mut() = StereoFrameHeader {
                hdr: Header::new(frames.next_seq(), k * 100_000_000 + 1, "bench"),
                head: Name::new(head),
                width,
                height,
                stride: width,
                encoding: PixelEncoding::Mono8 as u32,
            };
            frames.send(sample)?;
        }
        let next = start + Duration::from_millis(100 * (k + 1));
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    // SAFETY: plain syscall on our own child.
    unsafe { libc::kill(recorder.id() as libc::pid_t, libc::SIGTERM) };
    let out = recorder.wait_with_output()?;
    anyhow::ensure!(out.status.success(), "recorder failed: {}", out.status);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let topic = report["topics"]
        .as_array()
        .and_then(|t| t.iter().find(|t| t["topic"] == topics::STEREO_FRAME.name))
        .ok_or_else(|| anyhow::anyhow!("no stereo frames in the recorder's report"))?;
    let recorded = topic["messages"].as_u64().unwrap_or(0);
    let sent = 2 * periods;
    Ok(vec![
        Figure::new("live_frames_sent", sent as f64, "frames"),
        Figure::new("live_frames_recorded", recorded as f64, "frames"),
        Figure::new(
            "live_frames_dropped",
            topic["dropped"].as_f64().unwrap_or(-1.0),
            "frames",
        ),
        Figure::new(
            "live_rate_mb_per_s",
            recorded as f64 * 2.0 * plane as f64 / 1e6 / seconds,
            "MB/s",
        ),
    ])
}

/// Prints figures as `name: value unit` lines.
pub fn print_plain(figures: &[Figure]) {
    for f in figures {
        println!("{:<40} {:>12.2} {}", f.name, f.value, f.unit);
    }
}
