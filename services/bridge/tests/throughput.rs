//! Figures, not assertions: a 640x480 mono image stream through the real `bridge` process to a
//! WebSocket client on loopback. Prints messages/s, latency from publication to the client having
//! the whole message, and the bridge's CPU use.
//!
//! `cargo test --release -p bridge --test throughput -- --ignored --nocapture`

mod common;

use common::*;
use futures_util::SinkExt;
use serde_json::{json, Value};
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::Message;

/// CPU seconds (user + system) the process has used.
fn cpu_seconds(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or(vec![], |(_, r)| r.split_whitespace().collect());
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    // utime and stime are fields 14 and 15 (1-based), i.e. 11 and 12 after the command name.
    (ticks(11) + ticks(12)) / 100.0
}

/// The message's own stamp, read from the JSON before the (large) image data.
fn stamp_ns(payload: &[u8]) -> u64 {
    let end = payload
        .windows(8)
        .position(|w| w == b",\"data\":")
        .expect("image message");
    let mut head = payload[..end].to_vec();
    head.push(b'}');
    let v: Value = serde_json::from_slice(&head).unwrap();
    v["timestamp"]["sec"].as_u64().unwrap() * 1_000_000_000
        + v["timestamp"]["nsec"].as_u64().unwrap()
}

async fn run(label: &str, period: Duration, downscale: u32, seconds: f64) {
    let domain = format!("bridgebench{}{}", std::process::id(), period.as_millis());
    std::env::set_var(runtime::domain::DOMAIN_ENV, &domain);
    let port = free_port();
    let bridge = Bridge::start(
        &domain,
        &format!("listen = \"127.0.0.1:{port}\"\ntopics = [\"usv/sensors/stereo_frame\"]\n[image]\nmax_hz = 1000.0\ndownscale = {downscale}\n"),
    );
    let source = Source::start(period, false);
    let mut ws = connect(port).await;
    let mut image = None;
    while image.is_none() {
        let m = json(&next(&mut ws, Duration::from_secs(10)).await);
        for c in m["channels"].as_array().into_iter().flatten() {
            if c["schemaName"] == "foxglove.RawImage" {
                image = c["id"].as_u64();
            }
        }
    }
    ws.send(Message::text(
        json!({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": image}]}).to_string(),
    ))
    .await
    .unwrap();
    // Warm-up, then measure.
    let warm = Instant::now() + Duration::from_millis(500);
    while Instant::now() < warm {
        next(&mut ws, Duration::from_secs(5)).await;
    }
    let frames0 = source.frames.load(std::sync::atomic::Ordering::Relaxed);
    let cpu0 = cpu_seconds(bridge.child.id());
    let start = Instant::now();
    let mut latencies = Vec::new();
    let mut bytes = 0usize;
    while start.elapsed().as_secs_f64() < seconds {
        if let Message::Binary(b) = next(&mut ws, Duration::from_secs(5)).await {
            let now = runtime::clock::monotonic_ns();
            let (_, _, payload) = bridge::protocol::parse_data(&b).unwrap();
            latencies.push((now - stamp_ns(payload)) as f64 / 1e6);
            bytes += b.len();
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let cpu = cpu_seconds(bridge.child.id()) - cpu0;
    let published = source.frames.load(std::sync::atomic::Ordering::Relaxed) - frames0;
    latencies.sort_by(f64::total_cmp);
    let q = |p: f64| latencies[((latencies.len() - 1) as f64 * p) as usize];
    println!(
        "{label}: published {:.1}/s, received {:.1} msg/s ({:.1} MB/s), latency p50 {:.2} ms p99 {:.2} ms max {:.2} ms, bridge CPU {:.0}%",
        published as f64 / elapsed,
        latencies.len() as f64 / elapsed,
        bytes as f64 / elapsed / 1e6,
        q(0.5),
        q(0.99),
        q(1.0),
        100.0 * cpu / elapsed
    );
    drop(ws);
    drop(source);
    drop(bridge);
}

#[tokio::test(flavor = "current_thread")]
#[ignore = "benchmark: prints figures"]
async fn image_stream_through_the_bridge() {
    run("640x480 mono @30 Hz", Duration::from_millis(33), 1, 5.0).await;
    run("640x480 mono flat out", Duration::from_millis(1), 1, 5.0).await;
    run(
        "640x480 mono flat out, downscale 2",
        Duration::from_millis(1),
        2,
        5.0,
    )
    .await;
}
