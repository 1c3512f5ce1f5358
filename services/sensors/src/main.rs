//! `sensors replay FILE`: republishes a recording's messages, byte for byte, on the topics they were
//! recorded from, at real time, a rate factor, or in lock-step with the pipeline.

use anyhow::Context;
use clap::{Parser, Subcommand};
use messages::recording::{split, type_name};
use messages::topics;
use runtime::lockstep::LockStep;
use runtime::{PublishRaw, Service};
use sensors::reader::{Message, Messages, Recording};
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Parser)]
#[command(about = "Camera and INS input: replay of recordings")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Republish a recording on its topics.
    Replay(ReplayArgs),
}

#[derive(clap::Args)]
struct ReplayArgs {
    file: PathBuf,
    /// Speed factor on the recorded log times (1 = real time).
    #[arg(long, conflicts_with = "lockstep")]
    rate: Option<f64>,
    /// Publish the next stereo frame only after every --pipeline service finished the previous one.
    #[arg(long, requires = "pipeline")]
    lockstep: bool,
    /// Services to wait for in lock-step (their heartbeat names).
    #[arg(long, value_delimiter = ',')]
    pipeline: Vec<String>,
    /// Longest wait for the pipeline per frame in lock-step, seconds.
    #[arg(long, default_value_t = 5.0)]
    lockstep_timeout: f64,
    /// Start this many seconds into the recording.
    #[arg(long, default_value_t = 0.0)]
    start: f64,
    /// Start again at the end.
    #[arg(long = "loop")]
    looping: bool,
    /// Topics to republish: the sensor topics by default (stereo frames, INS, ground truth, truth
    /// images), `all` for every recorded topic but heartbeats, or a comma-separated list.
    #[arg(long, value_delimiter = ',')]
    topics: Vec<String>,
}

const SOURCE_TOPICS: [&str; 4] = [
    topics::STEREO_FRAME.name,
    topics::INS.name,
    topics::GROUND_TRUTH.name,
    topics::TRUTH_IMAGE.name,
];

/// How often the replay loop returns to the service loop (heartbeats, shutdown).
const SLICE: Duration = Duration::from_millis(5);

fn main() -> anyhow::Result<()> {
    let Command::Replay(args) = Cli::parse().command;
    replay(args)
}

fn wanted(args: &ReplayArgs, topic: &str) -> bool {
    match args.topics.as_slice() {
        [] => SOURCE_TOPICS.contains(&topic),
        [all] if all == "all" => topic != topics::HEARTBEAT.name,
        list => list.iter().any(|t| t == topic),
    }
}

/// Publishers by channel id, checked against this build's types.
fn publishers(
    service: &Service,
    rec: &Recording,
    args: &ReplayArgs,
) -> anyhow::Result<BTreeMap<u16, Box<dyn PublishRaw>>> {
    for t in &args.topics {
        anyhow::ensure!(
            t == "all" || topics::ALL.iter().any(|k| k.name == t),
            "unknown topic '{t}'"
        );
    }
    let mut out = BTreeMap::new();
    for ch in rec.channels().filter(|c| wanted(args, &c.topic)) {
        let made = messages::with_topic!(&ch.topic, t => {
            let expected = expected_type(t);
            anyhow::ensure!(
                ch.type_name == expected,
                "{}: recorded as {}, this build publishes {expected}",
                ch.topic,
                ch.type_name
            );
            service.publisher(t).map(|p| Box::new(p) as Box<dyn PublishRaw>)
        });
        match made {
            Some(p) => {
                out.insert(ch.id, p?);
            }
            None => {
                tracing::warn!(topic = %ch.topic, "recorded topic unknown to this build: skipped")
            }
        }
    }
    anyhow::ensure!(
        !out.is_empty(),
        "{}: nothing to replay on the chosen topics",
        rec.path().display()
    );
    Ok(out)
}

fn expected_type<P, H>(_: &messages::Topic<P, H>) -> &'static str
where
    P: ?Sized + messages::iceoryx2::prelude::ZeroCopySend,
    H: messages::iceoryx2::prelude::ZeroCopySend,
{
    type_name::<P, H>()
}

/// Replay position and pacing.
struct Player {
    messages: Messages,
    next: Option<Message>,
    /// Log time and wall time the pacing is anchored at (reset on loop).
    anchor: Option<(u64, Instant)>,
    rate: Option<f64>,
    published: BTreeMap<u16, u64>,
}

impl Player {
    /// Wall time at which `log_time` is due, or `None` without pacing.
    fn due(&mut self, log_time: u64) -> Option<Instant> {
        let rate = self.rate?;
        let (t0, w0) = *self.anchor.get_or_insert((log_time, Instant::now()));
        Some(w0 + Duration::from_secs_f64(log_time.saturating_sub(t0) as f64 * 1e-9 / rate))
    }
}

fn replay(args: ReplayArgs) -> anyhow::Result<()> {
    let rec = Recording::open(&args.file)?;
    if let Some(t) = rec.truncation() {
        eprintln!(
            "warning: {} has no proper end ({}); replaying the complete chunks before offset {} of {} bytes",
            args.file.display(),
            t.reason,
            t.offset,
            t.file_len
        );
    }
    let (first, last) = rec
        .time_range()
        .context("the recording holds no complete chunk")?;
    let from = first + (args.start.max(0.0) * 1e9) as u64;
    let mut service = Service::start("sensors")?;
    let mut pubs = publishers(&service, &rec, &args)?;
    let topic_of: BTreeMap<u16, String> = rec.channels().map(|c| (c.id, c.topic.clone())).collect();
    let mut lockstep = args
        .lockstep
        .then(|| {
            anyhow::Ok((
                service.subscriber(&topics::HEARTBEAT)?,
                LockStep::new(&args.pipeline),
            ))
        })
        .transpose()?;
    let lockstep_timeout = Duration::from_secs_f64(args.lockstep_timeout);
    let rate = match (args.lockstep, args.rate) {
        (true, _) => None,
        (false, r) => Some(r.unwrap_or(1.0)),
    };
    anyhow::ensure!(rate.is_none_or(|r| r > 0.0), "--rate must be positive");
    let want = |t: &str| wanted(&args, t);
    let mut player = Player {
        messages: rec.messages(from, want),
        next: None,
        anchor: None,
        rate,
        published: BTreeMap::new(),
    };
    let progress = (std::io::stderr().is_terminal() && last - from > 10_000_000_000).then(|| {
        let bar = indicatif::ProgressBar::new((last - from) / 1_000_000);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {msg} [{elapsed_precise} / ~{duration_precise}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let shutdown = service.shutdown().clone();
    let mut failure: Option<anyhow::Error> = None;
    tracing::info!(file = %args.file.display(), topics = pubs.len(), "replaying");

    // Lock-step: the heads of one frame share a stamp and go out together; before anything after
    // them the replay waits (without blocking its loop, so heartbeats keep going) until the
    // pipeline reported the previous stamp done. At the end it waits for the last frame too.
    let mut last_frame: Option<u64> = None;
    let mut waiting: Option<(u64, Instant)> = None;
    let mut finishing = false;
    service.run(&[], Some(SLICE), |health, _| {
        if failure.is_some() {
            return Ok(());
        }
        if let (Some((stamp, since)), Some((beats, ls))) = (waiting, lockstep.as_mut()) {
            ls.update(beats)?;
            if !ls.done(stamp) && !shutdown.requested() {
                if since.elapsed() < lockstep_timeout {
                    return Ok(());
                }
                ls.timeouts += 1;
                tracing::warn!(
                    stamp,
                    "lock-step: no answer from {}",
                    ls.missing(stamp).join(", ")
                );
            }
            waiting = None;
            if finishing {
                shutdown.request();
                return Ok(());
            }
        }
        let slice_end = Instant::now() + SLICE;
        while Instant::now() < slice_end && !shutdown.requested() {
            let msg = match player.next.take() {
                Some(m) => m,
                None => match player.messages.next() {
                    Some(Ok(m)) => m,
                    Some(Err(e)) => {
                        failure = Some(e.into());
                        shutdown.request();
                        return Ok(());
                    }
                    None if args.looping => {
                        player.messages.rewind();
                        player.anchor = None;
                        continue;
                    }
                    None => {
                        match (lockstep.is_some(), last_frame.take()) {
                            (true, Some(stamp)) => {
                                finishing = true;
                                waiting = Some((stamp, Instant::now()));
                            }
                            _ => shutdown.request(),
                        }
                        return Ok(());
                    }
                },
            };
            let is_frame = pubs
                .get(&msg.channel)
                .is_some_and(|p| p.topic() == topics::STEREO_FRAME.name);
            if lockstep.is_some() {
                // Anything after a frame but that frame's other heads (the INS samples leading to
                // the next frame, the next frame) waits until the frame is through the pipeline, as
                // with the simulator as the source.
                if let Some(previous) = last_frame.filter(|&s| !(is_frame && s == msg.publish_time))
                {
                    last_frame = None;
                    waiting = Some((previous, Instant::now()));
                    player.next = Some(msg);
                    return Ok(());
                }
            }
            if let Some(due) = player.due(msg.log_time) {
                let now = Instant::now();
                if due > slice_end {
                    player.next = Some(msg);
                    return Ok(());
                }
                std::thread::sleep(due.saturating_duration_since(now));
            }
            let started = Instant::now();
            let (header, payload) = split(&msg.data).context("recorded message without framing")?;
            let publisher = pubs
                .get_mut(&msg.channel)
                .expect("only wanted channels are read");
            if let Err(e) = publisher.publish_raw(header, payload) {
                failure = Some(e);
                shutdown.request();
                return Ok(());
            }
            *player.published.entry(msg.channel).or_default() += 1;
            if let Some(bar) = &progress {
                bar.set_position(msg.log_time.saturating_sub(from) / 1_000_000);
            }
            if is_frame {
                health.record(msg.publish_time, started);
                last_frame = Some(msg.publish_time);
            }
        }
        Ok(())
    })?;
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    for (channel, n) in &player.published {
        eprintln!("{:<34} published={n}", topic_of[channel]);
    }
    if let Some((_, ls)) = &lockstep {
        eprintln!("lock-step timeouts: {}", ls.timeouts);
    }
    match failure {
        Some(e) => Err(e.context(format!("replay of {} stopped", args.file.display()))),
        None => Ok(()),
    }
}
