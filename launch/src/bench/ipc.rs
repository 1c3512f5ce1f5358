//! One-way latency between two processes: iceoryx2 shared memory (busy-polling subscriber and
//! WaitSet-woken subscriber) for 64 B, 2.4 MB (one 1280x960 mono stereo pair) and 10 MB, and the same
//! 2.4 MB frame over a Unix domain socket in the same run as the reference.
//!
//! The publisher stamps each sample with the shared monotonic clock just before `send` (after the
//! payload was written), the subscriber takes the difference when the sample is in its hands. For the
//! socket the stamp is taken before `write` and read after the whole frame has arrived.

use super::Figure;
use iceoryx2::prelude::*;
use messages::{iceoryx2, Qos, Topic};
use runtime::clock::monotonic_ns;
use runtime::Ports;
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[repr(C)]
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[type_name("usv.bench.IpcProbe.v1")]
pub struct Probe {
    stamp_ns: u64,
    seq: u64,
    /// 1 on the final sample: the peer reports and exits.
    last: u32,
}

const PROBE_TOPIC: Topic<[u8], Probe> = Topic::new(
    "usv/bench/ipc_probe",
    Qos {
        max_publishers: 1,
        max_subscribers: 1,
        history: 0,
        subscriber_buffer: 4,
        subscriber_borrowed: 2,
        safe_overflow: true,
        initial_slice_len: 64,
    },
);

pub const SIZES: [(usize, &str); 3] = [(64, "64 B"), (2_457_600, "2.4 MB"), (10_485_760, "10 MB")];
const WARMUP: usize = 20;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
pub enum Wake {
    /// The subscriber spins on `receive()`.
    Busy,
    /// The subscriber sleeps in a WaitSet until the publisher's event wakes it.
    Waitset,
    /// Reference: a Unix domain stream socket.
    Uds,
}

#[derive(Serialize, Deserialize)]
struct PeerReport {
    latencies_ns: Vec<u64>,
    corrupt: u64,
}

struct Plan {
    size: usize,
    label: &'static str,
    wake: Wake,
    count: usize,
    period: Duration,
}

pub fn run(quick: bool) -> anyhow::Result<Vec<Figure>> {
    let mut plans = Vec::new();
    for (size, label) in SIZES {
        for wake in [Wake::Busy, Wake::Waitset] {
            let (count, period) = match (size, quick) {
                (64, false) => (2000, Duration::from_millis(1)),
                (_, false) => (400, Duration::from_millis(10)),
                (_, true) => (100, Duration::from_millis(5)),
            };
            plans.push(Plan {
                size,
                label,
                wake,
                count,
                period,
            });
        }
    }
    let uds_count = if quick { 100 } else { 400 };
    plans.push(Plan {
        size: SIZES[1].0,
        label: SIZES[1].1,
        wake: Wake::Uds,
        count: uds_count,
        period: Duration::from_millis(10),
    });

    let mut figures = Vec::new();
    let mut p50 = std::collections::HashMap::new();
    for plan in &plans {
        let report = match plan.wake {
            Wake::Uds => run_uds(plan)?,
            _ => run_shm(plan)?,
        };
        anyhow::ensure!(
            report.corrupt == 0,
            "{} samples arrived corrupted",
            report.corrupt
        );
        let mut lat = report.latencies_ns;
        anyhow::ensure!(
            !lat.is_empty(),
            "peer received nothing for {} {:?}",
            plan.label,
            plan.wake
        );
        lat.sort_unstable();
        let pct = |q: f64| lat[((lat.len() - 1) as f64 * q).round() as usize] as f64 / 1000.0;
        let transport = if plan.wake == Wake::Uds { "uds" } else { "shm" };
        let wake = format!("{:?}", plan.wake).to_lowercase();
        p50.insert((plan.size, plan.wake), pct(0.5));
        for (name, value) in [("latency_p50_us", pct(0.5)), ("latency_p99_us", pct(0.99))] {
            figures.push(
                Figure::new(name, value, "us")
                    .label("transport", transport)
                    .label("wake", wake.clone())
                    .label("size_bytes", plan.size)
                    .label("size", plan.label)
                    .label("samples", lat.len()),
            );
        }
    }
    let frame = SIZES[1].0;
    if let (Some(uds), Some(shm)) = (p50.get(&(frame, Wake::Uds)), p50.get(&(frame, Wake::Busy))) {
        figures.push(
            Figure::new("uds_over_shm_busy_p50_ratio", uds / shm, "x").label("size_bytes", frame),
        );
    }
    if let (Some(uds), Some(shm)) = (
        p50.get(&(frame, Wake::Uds)),
        p50.get(&(frame, Wake::Waitset)),
    ) {
        figures.push(
            Figure::new("uds_over_shm_waitset_p50_ratio", uds / shm, "x")
                .label("size_bytes", frame),
        );
    }
    Ok(figures)
}

fn spawn_peer(plan: &Plan, extra: &[String]) -> anyhow::Result<std::process::Child> {
    let exe = crate::session::usv_program()?;
    let mut cmd = Command::new(exe);
    cmd.args(["bench-peer", "--wake"])
        .arg(format!("{:?}", plan.wake).to_lowercase())
        .args(["--size", &plan.size.to_string()])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
    Ok(cmd.spawn()?)
}

fn collect(child: std::process::Child) -> anyhow::Result<PeerReport> {
    let out = child.wait_with_output()?;
    anyhow::ensure!(
        out.status.success(),
        "benchmark peer failed: {}",
        out.status
    );
    Ok(serde_json::from_slice(&out.stdout)?)
}

fn run_shm(plan: &Plan) -> anyhow::Result<PeerReport> {
    let node = runtime::tool_node("usv-bench-pub")?;
    let mut publisher = PROBE_TOPIC.publisher(&node)?;
    let peer = spawn_peer(plan, &[])?;
    let connect_deadline = Instant::now() + Duration::from_secs(10);
    while publisher.subscriber_count() == 0 {
        anyhow::ensure!(
            Instant::now() < connect_deadline,
            "benchmark peer did not connect"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    // Give the peer time to enter its receive loop before the first timed sample.
    std::thread::sleep(Duration::from_millis(200));
    let total = WARMUP + plan.count;
    for seq in 0..=total {
        let mut sample = publisher.loan_slice(plan.size)?;
        let payload = sample.payload_mut();
        payload.fill(seq as u8);
        *sample.user_header_mut() = Probe {
            stamp_ns: monotonic_ns(),
            seq: seq as u64,
            last: (seq == total) as u32,
        };
        publisher.send(sample)?;
        std::thread::sleep(plan.period);
    }
    collect(peer)
}

fn run_uds(plan: &Plan) -> anyhow::Result<PeerReport> {
    let dir = std::env::temp_dir().join(format!("usv-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let path = dir.join("ipc.sock");
    let _ = std::fs::remove_file(&path);
    let listener = UnixListener::bind(&path)?;
    let peer = spawn_peer(plan, &["--socket".into(), path.display().to_string()])?;
    let (mut stream, _) = listener.accept()?;
    let mut payload = vec![0u8; plan.size];
    let total = WARMUP + plan.count;
    for seq in 0..=total {
        payload.fill(seq as u8);
        let mut head = [0u8; 16];
        head[..8].copy_from_slice(&monotonic_ns().to_le_bytes());
        head[8..].copy_from_slice(&((seq as u64) | ((seq == total) as u64) << 63).to_le_bytes());
        stream.write_all(&head)?;
        stream.write_all(&payload)?;
        std::thread::sleep(plan.period);
    }
    let report = collect(peer);
    let _ = std::fs::remove_dir_all(&dir);
    report
}

/// The receiving process (`usv bench-peer`); prints its [`PeerReport`] as JSON on stdout.
pub fn peer(wake: Wake, size: usize, socket: Option<&str>) -> anyhow::Result<()> {
    let mut report = PeerReport {
        latencies_ns: Vec::with_capacity(4096),
        corrupt: 0,
    };
    let mut record = |stamp: u64, seq: u64, first: u8, last: u8, now: u64| {
        if first != seq as u8 || last != seq as u8 {
            report.corrupt += 1;
        }
        if seq as usize >= WARMUP {
            report.latencies_ns.push(now.saturating_sub(stamp));
        }
    };
    match wake {
        Wake::Uds => {
            let mut stream =
                UnixStream::connect(socket.ok_or_else(|| anyhow::anyhow!("--socket missing"))?)?;
            let mut payload = vec![0u8; size];
            loop {
                let mut head = [0u8; 16];
                stream.read_exact(&mut head)?;
                stream.read_exact(&mut payload)?;
                let now = monotonic_ns();
                let stamp = u64::from_le_bytes(head[..8].try_into()?);
                let word = u64::from_le_bytes(head[8..].try_into()?);
                let seq = word & !(1 << 63);
                record(stamp, seq, payload[0], payload[size - 1], now);
                if word >> 63 == 1 {
                    break;
                }
            }
        }
        Wake::Busy | Wake::Waitset => {
            let node = runtime::tool_node("usv-bench-sub")?;
            let sub = PROBE_TOPIC.subscriber(&node)?;
            let waitset = WaitSetBuilder::new()
                .signal_handling_mode(SignalHandlingMode::Disabled)
                .create::<ipc::Service>()
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            let guard = waitset
                .attach_notification(sub.listener())
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            let deadline = Instant::now() + Duration::from_secs(120);
            'outer: while Instant::now() < deadline {
                if wake == Wake::Waitset {
                    waitset
                        .wait_and_process_once_with_timeout(
                            |id| {
                                let _ = id.has_event_from(&guard);
                                CallbackProgression::Continue
                            },
                            Duration::from_millis(100),
                        )
                        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
                    let _ = sub.listener().try_wait(|_| {});
                }
                while let Some(sample) = sub.receive()? {
                    let now = monotonic_ns();
                    let probe = *sample.user_header();
                    let p = sample.payload();
                    record(probe.stamp_ns, probe.seq, p[0], p[p.len() - 1], now);
                    if probe.last == 1 {
                        break 'outer;
                    }
                }
            }
        }
    }
    println!("{}", serde_json::to_string(&report)?);
    Ok(())
}

/// Prints the figures as a table.
pub fn print_table(figures: &[Figure]) {
    println!(
        "{:<8} {:<10} {:<9} {:>12} {:>12}",
        "size", "transport", "wake", "p50 (us)", "p99 (us)"
    );
    let get = |f: &Figure, k: &str| {
        f.labels
            .iter()
            .find(|(key, _)| *key == k)
            .map(|(_, v)| v.as_str().unwrap_or_default().to_string())
            .unwrap_or_default()
    };
    for pair in figures
        .iter()
        .filter(|f| f.name.starts_with("latency"))
        .collect::<Vec<_>>()
        .chunks(2)
    {
        let [p50, p99] = pair else { continue };
        println!(
            "{:<8} {:<10} {:<9} {:>12.2} {:>12.2}",
            get(p50, "size"),
            get(p50, "transport"),
            get(p50, "wake"),
            p50.value,
            p99.value
        );
    }
    for f in figures.iter().filter(|f| f.unit == "x") {
        println!("{}: {:.0}x", f.name, f.value);
    }
}
