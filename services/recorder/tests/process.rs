//! The `recorder` binary on real topics: counts at SIGTERM, and the official Python MCAP reader
//! opening the file (channels, schemas including the Foxglove ones, message counts).

#[path = "../../sensors/tests/common/mod.rs"]
mod common;

use common::*;
use std::process::Command;
use std::time::Duration;

/// True if `import mcap` works, installing the package with pip if needed.
fn python_mcap() -> bool {
    let works = || {
        Command::new("python3")
            .args(["-c", "from mcap.reader import make_reader"])
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if works() {
        return true;
    }
    let _ = Command::new("python3")
        .args(["-m", "pip", "install", "--quiet", "mcap"])
        .status();
    works()
}

const SCRIPT: &str = r#"
import json, sys
from collections import Counter
from mcap.reader import make_reader
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    summary = reader.get_summary()
    channels = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    encodings = {c.topic: c.message_encoding for c in summary.channels.values()}
    counts = Counter(channel.topic for _, channel, _ in reader.iter_messages(log_time_order=True))
    print(json.dumps({"channels": channels, "encodings": encodings, "counts": counts,
                      "chunks": len(summary.chunk_indexes), "total": summary.statistics.message_count}))
"#;

#[test]
fn recorded_counts_and_the_python_reader() {
    let _serial = common::serial();
    let d = Domain::new();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("py.mcap");
    let mut sender = Sender::new(&d);
    let child = start_recorder(&d, &sender, &file, &["--image-compression", "lz4"]);
    sender.send_all();
    std::thread::sleep(Duration::from_millis(200));
    let report = stop_recorder(child);
    check_report(&report);

    if !python_mcap() {
        eprintln!(
            "SKIPPED: the Python `mcap` package is not installed and pip could not install it"
        );
        return;
    }
    let out = Command::new("python3")
        .arg("-c")
        .arg(SCRIPT)
        .arg(&file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "python reader failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let expect = [
        ("usv/sensors/stereo_frame", "usv.StereoFrame.v1", 10),
        ("usv/sensors/stereo_frame/image", "foxglove.RawImage", 10),
        ("usv/sensors/ins", "usv.InsState.v1", 50),
        ("usv/sensors/ins/fix", "foxglove.LocationFix", 50),
        ("usv/sensors/ins/tf", "foxglove.FrameTransform", 50),
        ("usv/tracker/contacts", "usv.ContactList.v1", 10),
        ("usv/tracker/contacts/scene", "foxglove.SceneUpdate", 10),
        ("usv/perception/local_map", "usv.LocalMap.v1", 5),
        ("usv/perception/local_map/grid", "foxglove.Grid", 5),
    ];
    for (topic, schema, count) in expect {
        assert_eq!(v["channels"][topic], schema, "{topic}: {v}");
        assert_eq!(v["counts"][topic], count, "{topic}: {v}");
    }
    assert_eq!(v["encodings"]["usv/sensors/ins"], "usv-raw");
    assert_eq!(v["encodings"]["usv/sensors/ins/fix"], "json");
    assert_eq!(v["total"], 200);
    assert!(v["chunks"].as_u64().unwrap() >= 2, "{v}");
}

#[test]
fn a_restarted_recorder_keeps_the_recording_it_was_given_and_writes_the_next_part() {
    let _serial = common::serial();
    let d = Domain::new();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    let mut sender = Sender::new(&d);
    let first = start_recorder(&d, &sender, &file, &[]);
    sender.send_all();
    std::thread::sleep(Duration::from_millis(200));
    let report = stop_recorder(first);
    check_report(&report);
    assert_eq!(report["file"], file.display().to_string());
    let recorded = std::fs::read(&file).unwrap();

    // The same command again, as a supervisor's restart runs it.
    let second = start_recorder(&d, &sender, &file, &[]);
    sender.send_all();
    std::thread::sleep(Duration::from_millis(200));
    let report = stop_recorder(second);
    // The part holds the second batch (and each topic's last sample before it, which the
    // publishers' history hands a late subscriber).
    assert_eq!(report["finished"], true);
    for t in report["topics"].as_array().unwrap() {
        assert!(t["messages"].as_u64().unwrap() >= 5, "{report}");
    }
    let part = dir.path().join("run.1.mcap");
    assert_eq!(report["file"], part.display().to_string());
    assert!(std::fs::read(&part).unwrap().len() > 1000);
    assert!(
        std::fs::read(&file).unwrap() == recorded,
        "the first recording was changed"
    );
}
