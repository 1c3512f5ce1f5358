//! `bridge run --config FILE`: the live view and the cross-host link.
//!
//! Subscribes the configured topics and serves them to Foxglove over the Foxglove WebSocket
//! protocol (`ws://<listen>`, subprotocol `foxglove.websocket.v1`), encoded with the recorder's
//! views: the left image of each stereo head (`foxglove.RawImage`, rate-limited and optionally
//! downscaled), maps (`foxglove.Grid`), contacts and ground truth (`foxglove.SceneUpdate`), the INS
//! pose (`foxglove.FrameTransform`, `foxglove.LocationFix`) and service problems from heartbeats
//! (`foxglove.Log`). With a `[zenoh]` section (feature `zenoh`) it also sends chosen topics to
//! other hosts and republishes topics received from them.
//!
//! Threads: the wait loop (all shared-memory work and JSON encoding) and one WebSocket thread.
//! The loop hands messages over through bounded per-client queues that drop the oldest message;
//! drops are reported in the heartbeat as rejected input with the count in the reason.

mod live;
mod server;
#[cfg(feature = "zenoh")]
mod zenoh_link;

use anyhow::Context;
use bridge::config::has_view;
use bridge::{Config, Hub};
use runtime::{Input, Service, Wake};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(clap::Parser)]
#[command(
    name = "bridge",
    version,
    about = "Live view (Foxglove WebSocket) and cross-host link"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Run as the bridge service of a process set.
    Run {
        /// Service configuration (TOML); see `bridge::config`.
        #[arg(long)]
        config: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = <Cli as clap::Parser>::parse();
    let result = match cli.command {
        Command::Run { config } => run(&config),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Tick of the wait loop: drop reports, and polling the link's received messages.
const TICK: Duration = Duration::from_millis(100);
#[cfg(feature = "zenoh")]
const LINK_TICK: Duration = Duration::from_millis(5);

fn run(path: &Path) -> anyhow::Result<()> {
    let config: Config = runtime::config::load(path)?;
    config
        .validate(has_view)
        .with_context(|| format!("invalid config file {}", path.display()))?;
    #[cfg(not(feature = "zenoh"))]
    anyhow::ensure!(
        config.zenoh.is_none(),
        "{}: this bridge was built without the `zenoh` feature (cargo build --release -p bridge --features zenoh)",
        path.display()
    );

    let mut service = Service::start("bridge")?;
    let session = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis());
    let hub = Arc::new(Hub::new(
        service.name(),
        &session.to_string(),
        config.client_backlog,
    ));
    let live_topics = config.live_topics(has_view);
    if !config.listen.is_empty() {
        let listener = std::net::TcpListener::bind(&config.listen)
            .with_context(|| format!("cannot listen on {}", config.listen))?;
        tracing::info!(address = %listener.local_addr()?, topics = live_topics.len(), "Foxglove WebSocket server");
        server::spawn(listener, hub.clone())?;
    }
    let mut taps = Vec::new();
    for name in &live_topics {
        let tap = messages::with_topic!(name, t => live::tap(&service, t, t.name, config.rate_of(t.name), &hub))
            .context("topic dispatch")??;
        taps.push(tap);
    }
    #[cfg(feature = "zenoh")]
    let link = match &config.zenoh {
        Some(z) => Some(zenoh_link::Link::start(&service, z)?),
        None => None,
    };
    #[cfg(feature = "zenoh")]
    let tick = if link.as_ref().is_some_and(|l| l.receives()) {
        LINK_TICK
    } else {
        TICK
    };
    #[cfg(not(feature = "zenoh"))]
    let tick = TICK;

    #[cfg_attr(not(feature = "zenoh"), allow(unused_mut))]
    let mut inputs: Vec<Input<'_>> = taps.iter().map(|t| t.input()).collect();
    let live_inputs = inputs.len();
    #[cfg(feature = "zenoh")]
    if let Some(l) = &link {
        inputs.extend(l.inputs());
    }
    let mut cx = live::Cx {
        hub: &hub,
        state: Default::default(),
        scratch: Vec::new(),
        downscale: config.image.downscale,
    };
    let mut reported_drops = 0;
    let mut handled_since_tick = 0;
    let mut last_tick = Instant::now();
    service.run(&inputs, Some(tick), |health, wake| {
        let started = Instant::now();
        match wake {
            Wake::Input(i) if i < live_inputs => {
                handled_since_tick += taps[i].drain(&mut cx, health)?;
            }
            #[cfg(feature = "zenoh")]
            Wake::Input(i) => {
                if let Some(l) = &link {
                    handled_since_tick += l.forward(i - live_inputs, health)?;
                }
            }
            Wake::Tick => {
                #[cfg(feature = "zenoh")]
                if let Some(l) = &link {
                    handled_since_tick += l.receive(health)?;
                }
                // Once per heartbeat period, not per batch: each heartbeat is itself a sample this
                // service may be subscribed to, and reporting per batch would feed back.
                if last_tick.elapsed() < TICK {
                    return Ok(());
                }
                last_tick = Instant::now();
                if handled_since_tick > 0 {
                    health.record(0, started);
                    handled_since_tick = 0;
                }
                let drops = hub.dropped();
                if drops > reported_drops {
                    health.reject(
                        0,
                        &format!(
                            "live view: {} messages dropped for slow clients ({drops} since start)",
                            drops - reported_drops
                        ),
                    );
                    reported_drops = drops;
                }
            }
            _ => {}
        }
        Ok(())
    })?;
    tracing::info!(
        queued = hub.queued_total(),
        dropped = hub.dropped(),
        "bridge stopped"
    );
    Ok(())
}
