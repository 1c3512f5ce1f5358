//! `usv retrack <recording>`: runs the tracker again over a recording's world maps with the
//! settings of a tracker config file, and scores the replayed contacts against the recorded truth
//! beside the recorded contacts, with `usv eval`'s own scoring. A tracker change is so measured on
//! the maps of closed-loop runs in seconds. The maps do not change with the tracker; the course the
//! boat would have taken does, so a change that alters the contacts the sequencer acted on still
//! needs a closed-loop run to be judged.

use crate::eval_tracking::TrackingScore;
use anyhow::Context;
use messages::recording::{read_slice, read_value, split};
use messages::{topics, ContactList, DisparityHeader, GroundTruth, MapCell, WorldMapHeader};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tracker::Tracker;

/// Disparity images read for the heads' fields of view: the first frames carry every head.
const DISPARITIES_FOR_VIEWS: usize = 16;
/// Replayed contact lists kept to meet the recorded list of the same stamp, which is logged after
/// the map it came from.
const REPLAYED_KEPT: usize = 8;

#[derive(clap::Args)]
pub struct RetrackArgs {
    /// A recording with world maps, ground truth and contacts (`usv eval --closed-loop --record`).
    recording: PathBuf,
    /// Tracker settings: the `[tracking]` table and model of this config file.
    #[arg(long, default_value = "launch/sets/tracker.toml")]
    config: PathBuf,
    /// The recorded scenario, for its shore: tracks on land are shore contacts, not false tracks.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// One JSON object (recorded and replayed reports) instead of lines.
    #[arg(long)]
    json: bool,
}

pub fn run(args: RetrackArgs) -> anyhow::Result<()> {
    let report = retrack(&args.recording, &args.config, args.scenario.as_deref())?;
    if args.json {
        println!("{report}");
        return Ok(());
    }
    println!(
        "{} maps over {:.1} s, {} with contacts that differ from the recording",
        report["maps"],
        report["minutes"].as_f64().unwrap_or(0.0) * 60.0,
        report["maps_differing"]
    );
    for which in ["recorded", "replayed"] {
        println!("{which}: {}", crate::eval::tracking_line(&report[which]));
    }
    Ok(())
}

/// The recorded and the replayed contacts' tracking reports, and how many maps' contacts differ.
pub fn retrack(
    recording: &Path,
    config: &Path,
    scenario: Option<&Path>,
) -> anyhow::Result<serde_json::Value> {
    let (cfg, model) = tracker::config::load(config)?;
    let mut tracker = Tracker::new(cfg.tracking, model)
        .with_context(|| format!("configuration {}", config.display()))?;
    let mut recorded = TrackingScore::default();
    let mut replayed = TrackingScore::default();
    if let Some(scenario) = scenario {
        for score in [&mut recorded, &mut replayed] {
            if let Some(land) = TrackingScore::land_of(sim::scenario::load_world(scenario)?) {
                score.set_land(land);
            }
        }
    }
    let open = || {
        sensors::Recording::open(recording)
            .with_context(|| format!("recording {}", recording.display()))
    };
    for msg in open()?
        .messages(0, |t| t == topics::DISPARITY.name)
        .take(DISPARITIES_FOR_VIEWS)
    {
        let msg = msg?;
        let (header, _) = split(&msg.data).context("corrupt framing")?;
        // SAFETY: DisparityHeader is plain numbers.
        let h: DisparityHeader = unsafe { read_value(header) }.context("short disparity header")?;
        for score in [&mut recorded, &mut replayed] {
            score.on_camera(h.head.as_str(), &h.camera, h.width);
        }
    }

    let wanted = [
        topics::GROUND_TRUTH.name,
        topics::CONTACTS.name,
        topics::WORLD_MAP.name,
    ];
    let mut list = Box::<ContactList>::default();
    let mut pending: BTreeMap<u64, Box<ContactList>> = BTreeMap::new();
    let (mut maps, mut differing) = (0u64, 0u64);
    // Truth stamps seen, first and last: the run's span, as `usv eval` takes it.
    let mut span: Option<(u64, u64)> = None;
    let rec = open()?;
    let topic_of: BTreeMap<u16, String> = rec.channels().map(|c| (c.id, c.topic.clone())).collect();
    for msg in rec.messages(0, |t| wanted.contains(&t)) {
        let msg = msg?;
        let topic = topic_of.get(&msg.channel).map_or("", String::as_str);
        let (header, payload) = split(&msg.data).context("corrupt framing")?;
        // SAFETY (all three): the recorded types are plain numbers.
        if topic == topics::GROUND_TRUTH.name {
            let truth: Box<GroundTruth> =
                Box::new(unsafe { read_value(payload) }.context("short ground truth")?);
            let t = truth.hdr.stamp_ns;
            span = Some(span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            recorded.on_truth(&truth);
            replayed.on_truth(&truth);
        } else if topic == topics::CONTACTS.name {
            let rec: Box<ContactList> =
                Box::new(unsafe { read_value(payload) }.context("short contact list")?);
            recorded.on_contacts(&rec);
            if let Some(ours) = pending.remove(&rec.hdr.stamp_ns) {
                differing += u64::from(!tracker::eval::same_contacts(&rec, &ours));
            }
        } else {
            let header: WorldMapHeader =
                unsafe { read_value(header) }.context("short world-map header")?;
            let cells: Vec<MapCell> = unsafe { read_slice(payload) };
            tracker
                .update(&header, &cells, "retrack", &mut list)
                .with_context(|| format!("world map at {} ns", header.hdr.stamp_ns))?;
            maps += 1;
            replayed.on_contacts(&list);
            pending.insert(header.hdr.stamp_ns, list.clone());
            while pending.len() > REPLAYED_KEPT {
                pending.pop_first();
            }
        }
    }
    anyhow::ensure!(maps > 0, "{} holds no world maps", recording.display());
    let minutes = span.map_or(0.0, |(a, b)| (b - a) as f64 * 1e-9 / 60.0);
    Ok(serde_json::json!({
        "recording": recording,
        "config": config,
        "maps": maps,
        "maps_differing": differing,
        "minutes": minutes,
        "recorded": recorded.report(minutes),
        "replayed": replayed.report(minutes),
    }))
}
