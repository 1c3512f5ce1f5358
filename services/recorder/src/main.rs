//! `recorder`: subscribes to every topic (or a chosen list) and writes them to an MCAP file until
//! SIGINT/SIGTERM or `--duration`; then finishes the file and reports per-topic counts and drops.

use anyhow::Context;
use clap::Parser;
use messages::summary::Inspect;
use messages::topics;
use recorder::foxglove::View;
use recorder::{Compression, Recording, RecordingOptions, WriterOptions};
use runtime::{Input, Ports, Receive, Service, Subscriber, Wake};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(Parser)]
#[command(about = "Record topics to MCAP (replay channels + Foxglove views)")]
struct Args {
    /// Output file.
    #[arg(long)]
    out: PathBuf,
    /// Comma-separated topic names (default: every topic).
    #[arg(long, value_delimiter = ',')]
    topics: Vec<String>,
    /// Compression of image and grid chunks: none or lz4.
    #[arg(long, default_value = "none", value_parser = parse_image_compression)]
    image_compression: Compression,
    /// Compression of small-message chunks: zstd, lz4 or none.
    #[arg(long, default_value = "zstd")]
    small_compression: Compression,
    /// Foxglove image view of every n-th stereo frame (0: none).
    #[arg(long, default_value_t = 1)]
    image_view_every: u32,
    /// Replay channels only, no Foxglove channels.
    #[arg(long)]
    no_foxglove: bool,
    /// Stop after this many seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Longest log time a chunk spans (what a crash can lose), seconds.
    #[arg(long, default_value_t = 0.5)]
    chunk_seconds: f64,
    /// Print the exit report as JSON on stdout.
    #[arg(long)]
    json: bool,
}

fn parse_image_compression(s: &str) -> Result<Compression, String> {
    match s.parse()? {
        Compression::Zstd => Err("zstd is too slow for images here; use none or lz4".into()),
        c => Ok(c),
    }
}

/// One subscribed topic: drains its subscriber into the recording.
trait Tap {
    fn input(&self) -> Input<'_>;
    /// Writes every waiting sample; returns how many.
    fn drain(&self, rec: &mut Recording<File>) -> anyhow::Result<usize>;
}

struct TopicTap<
    P: ?Sized + messages::iceoryx2::prelude::IceoryxSend + std::fmt::Debug + 'static,
    H: messages::iceoryx2::prelude::ZeroCopySend + std::fmt::Debug + 'static,
> {
    sub: Subscriber<P, H>,
    id: recorder::recording::TopicId,
}

impl<T, H> Tap for TopicTap<T, H>
where
    T: ?Sized + messages::iceoryx2::prelude::IceoryxSend + std::fmt::Debug + 'static,
    H: messages::iceoryx2::prelude::ZeroCopySend + std::fmt::Debug + Inspect<T> + View<T> + 'static,
    Subscriber<T, H>: Receive<T, H>,
{
    fn input(&self) -> Input<'_> {
        self.sub.input(None)
    }

    fn drain(&self, rec: &mut Recording<File>) -> anyhow::Result<usize> {
        let mut written = 0;
        while let Some(result) = self
            .sub
            .receive_with(|h, p| rec.write(self.id, runtime::clock::monotonic_ns(), h, p))?
        {
            result.with_context(|| format!("writing {}", self.sub.topic()))?;
            written += 1;
        }
        Ok(written)
    }
}

fn tap<T: Ports>(
    service: &Service,
    topic: &T,
    name: &str,
    element_size: usize,
    rec: &mut Recording<File>,
) -> anyhow::Result<Box<dyn Tap>>
where
    T::Payload: messages::iceoryx2::prelude::ZeroCopySend,
    T::UserHeader: Inspect<T::Payload> + View<T::Payload>,
    Subscriber<T::Payload, T::UserHeader>: Receive<T::Payload, T::UserHeader>,
{
    let id = rec.add_topic::<T::Payload, T::UserHeader>(name, element_size)?;
    Ok(Box::new(TopicTap {
        sub: service.subscriber(topic)?,
        id,
    }))
}

/// Size of one payload element: the payload itself for fixed-size topics.
trait ElementSize {
    const SIZE: usize;
}
impl<T> ElementSize for [T] {
    const SIZE: usize = std::mem::size_of::<T>();
}
macro_rules! fixed_size {
    ($($t:ty),*) => { $(impl ElementSize for $t { const SIZE: usize = std::mem::size_of::<$t>(); })* };
}
fixed_size!(
    messages::InsState,
    messages::GroundTruth,
    messages::ContactList,
    messages::ActuatorCommand,
    messages::SequencerStatus,
    messages::Heartbeat
);

fn element_size<P: ?Sized + ElementSize, H>(_: &messages::Topic<P, H>) -> usize {
    P::SIZE
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let names: Vec<String> = if args.topics.is_empty() {
        topics::ALL.iter().map(|t| t.name.to_string()).collect()
    } else {
        args.topics.clone()
    };
    let mut service = Service::start("recorder")?;
    let (file, out) = recorder::output::create_unused(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    if out != args.out {
        tracing::warn!(
            kept = %args.out.display(),
            out = %out.display(),
            "a recording is there already (a restart?); recording to the next part"
        );
    }
    let opts = RecordingOptions {
        writer: WriterOptions {
            bulk_compression: args.image_compression,
            small_compression: args.small_compression,
            chunk_duration_ns: (args.chunk_seconds * 1e9) as u64,
            ..Default::default()
        },
        image_view_every: args.image_view_every,
        foxglove: !args.no_foxglove,
    };
    let mut rec = Recording::new(file, opts).context("cannot start the recording")?;
    let mut taps = Vec::new();
    for name in &names {
        let t =
            messages::with_topic!(name, t => tap(&service, t, t.name, element_size(t), &mut rec))
                .ok_or_else(|| {
                    let known: Vec<_> = topics::ALL.iter().map(|t| t.name).collect();
                    anyhow::anyhow!("unknown topic '{name}'; known topics: {}", known.join(", "))
                })??;
        taps.push(t);
    }
    tracing::info!(out = %out.display(), topics = names.len(), "recording");

    let inputs: Vec<Input<'_>> = taps.iter().map(|t| t.input()).collect();
    let shutdown = service.shutdown().clone();
    let end = args
        .duration
        .map(|d| Instant::now() + Duration::from_secs_f64(d));
    let mut failure = None;
    // Samples written since the last tick, reported as one processed input per tick: reporting every
    // batch would feed back (each heartbeat is itself a recorded sample that triggers a heartbeat).
    let mut written_since_tick = 0;
    service.run(&inputs, Some(Duration::from_millis(100)), |health, wake| {
        if failure.is_some() {
            return Ok(());
        }
        let started = Instant::now();
        // Any wake drains every topic: cheap when empty, and keeps log times in arrival order.
        let result = (|| {
            for t in &taps {
                written_since_tick += t.drain(&mut rec)?;
            }
            // Not in a lock-step pipeline, so no frame stamp is reported.
            if wake == Wake::Tick && written_since_tick > 0 {
                health.record(0, started);
                written_since_tick = 0;
            }
            if wake == Wake::Tick {
                rec.flush_stale(runtime::clock::monotonic_ns())?;
            }
            anyhow::Ok(())
        })();
        if let Err(e) = result {
            // A write error (disk full ...) ends the recording; the file keeps its complete chunks.
            failure = Some(e);
            shutdown.request();
        }
        if end.is_some_and(|e| Instant::now() >= e) {
            shutdown.request();
        }
        Ok(())
    })?;
    drop(inputs);
    // Whatever arrived before the signal is still written.
    if failure.is_none() {
        for t in &taps {
            if let Err(e) = t.drain(&mut rec) {
                failure = Some(e);
                break;
            }
        }
    }
    let finished = match &failure {
        None => rec
            .finish()
            .map(Some)
            .context("cannot finish the recording")?,
        Some(_) => None,
    };
    report(&rec, finished.as_ref(), &out, args.json);
    match failure {
        Some(e) => Err(e.context(format!("recording to {} stopped", out.display()))),
        None => Ok(()),
    }
}

fn report(rec: &Recording<File>, finished: Option<&recorder::mcap::Stats>, out: &Path, json: bool) {
    let stats: Vec<_> = rec.stats().cloned().collect();
    for s in &stats {
        let warn = if s.dropped > 0 { "  <-- DROPS" } else { "" };
        eprintln!(
            "{:<34} messages={:<7} dropped={:<5} restarts={:<3} foxglove={}{warn}",
            s.topic, s.messages, s.dropped, s.restarts, s.foxglove_messages
        );
    }
    let bytes = finished.map_or(rec.position(), |f| f.bytes);
    eprintln!(
        "{}: {} bytes, {}",
        out.display(),
        bytes,
        if finished.is_some() {
            "finished"
        } else {
            "NOT finished"
        }
    );
    if json {
        let topics: Vec<_> = stats
            .iter()
            .map(|s| {
                serde_json::json!({"topic": s.topic, "messages": s.messages, "dropped": s.dropped,
                "restarts": s.restarts, "foxglove_messages": s.foxglove_messages})
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({"file": out, "bytes": bytes, "finished": finished.is_some(), "topics": topics})
        );
    }
}
