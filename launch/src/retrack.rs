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
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use tracker::Tracker;

/// Disparity images read for the heads' fields of view: the first frames carry every head.
const DISPARITIES_FOR_VIEWS: usize = 16;
/// Replayed contact lists kept to meet the recorded list of the same stamp, which is logged after
/// the map it came from.
const REPLAYED_KEPT: usize = 8;

#[derive(clap::Args)]
pub struct RetrackArgs {
    /// Recordings with world maps, ground truth and contacts (`usv eval --closed-loop --record`),
    /// e.g. one scenario's runs with several seeds.
    #[arg(required = true)]
    recordings: Vec<PathBuf>,
    /// Tracker settings: the `[tracking]` table and model of this config file.
    #[arg(long, default_value = "launch/sets/tracker.toml")]
    config: PathBuf,
    /// The recorded scenario, for its shore: tracks on land are shore contacts, not false tracks.
    /// Default: the `scenario.toml` beside a recording, which `usv eval --seed` writes.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// One JSON object per recording (recorded and replayed reports) instead of lines.
    #[arg(long)]
    json: bool,
}

pub fn run(args: RetrackArgs) -> anyhow::Result<()> {
    let mut reports = Vec::new();
    for recording in &args.recordings {
        let beside = recording.with_file_name("scenario.toml");
        let scenario = args
            .scenario
            .as_deref()
            .or_else(|| beside.is_file().then_some(beside.as_path()));
        let report = retrack(recording, &args.config, scenario)?;
        if args.json {
            println!("{report}");
        } else {
            println!(
                "{}: {} maps over {:.1} s, {} with contacts that differ from the recording",
                recording.display(),
                report["maps"],
                report["minutes"].as_f64().unwrap_or(0.0) * 60.0,
                report["maps_differing"]
            );
            for which in ["recorded", "replayed"] {
                println!("  {which}: {}", crate::eval::tracking_line(&report[which]));
                for line in crate::eval::tracking_detail_lines(&report[which]) {
                    println!("  {line}");
                }
            }
        }
        reports.push(report);
    }
    if !args.json && reports.len() > 1 {
        println!("all {} recordings:", reports.len());
        for which in ["recorded", "replayed"] {
            println!("  {which}: {}", totals_line(&reports, which));
        }
    }
    Ok(())
}

/// False tracks and the detection targets summed over several recordings' reports.
fn totals_line(reports: &[serde_json::Value], which: &str) -> String {
    let tracking: Vec<&serde_json::Value> = reports.iter().map(|r| &r[which]).collect();
    let minutes = reports.iter().filter_map(|r| r["minutes"].as_f64()).sum();
    crate::eval::tracking_totals_line(&tracking, minutes)
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
        let world = sim::scenario::load_world(scenario)?;
        let sight = Rc::new(RefCell::new(sim::Sight::new(world.clone())));
        for score in [&mut recorded, &mut replayed] {
            score.set_sight(TrackingScore::sight_of(&sight));
            if let Some(land) = TrackingScore::land_of(world.clone()) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use messages::{truth_class, GridGeometry, Header, Pose, TruthObject};
    use recorder::recording::{Recording, RecordingOptions};

    const MAPS: u64 = 15;

    fn sets_config() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("sets/tracker.toml")
    }

    /// A recording of `MAPS` world maps at 5 a second, the own boat at the origin: a moored boat
    /// 40 m north seen in every map, and 30 m east one frame's stereo mismatch the map keeps from
    /// map 2 on without the heads seeing it again. The recorded contact lists are empty.
    fn write_recording(path: &Path) {
        let file = std::fs::File::create(path).unwrap();
        let mut rec = Recording::new(file, RecordingOptions::default()).unwrap();
        let truth_topic = rec
            .add_topic::<GroundTruth, ()>(topics::GROUND_TRUTH.name, size_of::<GroundTruth>())
            .unwrap();
        let map_topic = rec
            .add_topic::<[MapCell], WorldMapHeader>(topics::WORLD_MAP.name, size_of::<MapCell>())
            .unwrap();
        let contacts_topic = rec
            .add_topic::<ContactList, ()>(topics::CONTACTS.name, size_of::<ContactList>())
            .unwrap();
        let grid = GridGeometry {
            width: 200,
            height: 200,
            resolution_m: 0.5,
            center: [0.0, 0.0],
        };
        for k in 0..MAPS {
            let stamp = 1_000_000_000 + k * 200_000_000;
            let mut truth = Box::<GroundTruth>::default();
            truth.hdr = Header::new(k, stamp, "sim");
            truth.object_count = 1;
            truth.objects[0] = TruthObject {
                id: 7,
                class: truth_class::BOAT,
                extent: [6.0, 2.5, 1.5],
                ..Default::default()
            };
            truth.objects[0].pose.position = [0.0, 40.0, 0.0];
            rec.write(truth_topic, stamp, &(), &*truth).unwrap();

            let water = MapCell {
                observed: 1,
                ..Default::default()
            };
            let mut cells = vec![water; grid.cell_count()];
            for row in 0..grid.height {
                for col in 0..grid.width {
                    let [x, y] = grid.cell_center(col, row);
                    let cell = &mut cells[(row * grid.width + col) as usize];
                    if x.abs() <= 1.25 && (y - 40.0).abs() <= 3.0 {
                        *cell = MapCell {
                            hazard: 220,
                            max_height_cm: 150,
                            observed: 6,
                            ..Default::default()
                        };
                    } else if k >= 2 && (x - 30.0).abs() <= 1.0 && y.abs() <= 0.75 {
                        *cell = MapCell {
                            hazard: 200,
                            max_height_cm: 120,
                            observed: u8::from(k == 2) * 3,
                            ..Default::default()
                        };
                    }
                }
            }
            let header = WorldMapHeader {
                hdr: Header::new(k, stamp, "mapper"),
                grid,
                vessel: Pose::default(),
                fused: k,
            };
            rec.write(map_topic, stamp + 1, &header, &cells[..])
                .unwrap();

            let mut list = Box::<ContactList>::default();
            list.hdr = Header::new(k, stamp, "tracker");
            rec.write(contacts_topic, stamp + 2, &(), &*list).unwrap();
        }
        rec.finish().unwrap();
    }

    #[test]
    fn the_tracker_run_again_finds_the_boat_the_recording_missed_and_no_held_mismatch() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run.mcap");
        write_recording(&run);
        let r = retrack(&run, &sets_config(), None).unwrap();
        assert_eq!(r["maps"], MAPS);
        assert_eq!(r["recorded"]["boats_within_100m"]["frames"], MAPS);
        assert_eq!(r["recorded"]["boats_within_100m"]["detected"], 0);
        // Confirmed on its third map, then every map.
        assert_eq!(r["replayed"]["boats_within_100m"]["detected"], MAPS - 2);
        // Its tentative track is listed from the first map on.
        assert_eq!(r["maps_differing"], MAPS);
        assert_eq!(r["replayed"]["false_tracks"], 0);

        // Counting detections the map holds from older observations confirms the mismatch.
        let text = std::fs::read_to_string(sets_config()).unwrap();
        let model = sets_config()
            .parent()
            .unwrap()
            .join("../../services/tracker/models/contact.json");
        let text = text
            .replace(
                "model = \"../../services/tracker/models/contact.json\"",
                &format!("model = {:?}", model.display().to_string()),
            )
            .replace(
                "[tracking]",
                "[tracking]\nconfirm_min_observed_cells = 0\nconfirm_peak_observed_cells = 0",
            );
        let off = dir.path().join("tracker.toml");
        std::fs::write(&off, text).unwrap();
        let r = retrack(&run, &off, None).unwrap();
        assert_eq!(r["replayed"]["false_tracks"], 1);
    }

    #[test]
    fn a_recording_without_world_maps_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("empty.mcap");
        let file = std::fs::File::create(&run).unwrap();
        let mut rec = Recording::new(file, RecordingOptions::default()).unwrap();
        rec.finish().unwrap();
        let err = retrack(&run, &sets_config(), None).unwrap_err();
        assert!(err.to_string().contains("holds no world maps"), "{err:#}");
        let err = retrack(&dir.path().join("missing.mcap"), &sets_config(), None).unwrap_err();
        assert!(format!("{err:#}").contains("missing.mcap"), "{err:#}");
    }

    #[test]
    fn several_recordings_are_summed_over_their_minutes() {
        let report = |false_tracks: u64, minutes: f64| {
            serde_json::json!({"minutes": minutes, "replayed": {
                "false_tracks": false_tracks, "false_object_tracks": 1,
                "boats_within_100m": {"detected": 9, "frames": 10},
                "markers_within_60m": {"detected": 0, "frames": 0}}})
        };
        let line = totals_line(&[report(30, 2.0), report(6, 1.0)], "replayed");
        assert!(
            line.starts_with("36 false tracks over 3.0 min (12.0/min; 2 reported as objects, 0.7/min), boats within 100 m 18 of 20 frames"),
            "{line}"
        );
    }
}
