//! The real `tracker` process: world maps in, contacts out; a map whose cell count does not match
//! its grid is rejected in the heartbeat while the service keeps running; a missing model stops it
//! at start-up with the reason.

use messages::{topics, GridGeometry, Header, MapCell, WorldMapHeader};
use runtime::Ports;
use std::process::Command;
use std::time::{Duration, Instant};

fn model_path() -> String {
    format!("{}/models/contact.json", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn a_missing_or_corrupt_model_is_a_clear_start_up_error() {
    let dir = std::env::temp_dir().join(format!("trackmodel{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("tracker.toml");
    std::fs::write(&config, "model = \"nope.json\"\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_tracker"))
        .args(["run", "--config"])
        .arg(&config)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot read contact model") && err.contains("nope.json"),
        "{err}"
    );
    std::fs::write(dir.join("bad.json"), "{\"version\": 1, \"features\": [").unwrap();
    std::fs::write(&config, "model = \"bad.json\"\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_tracker"))
        .args(["run", "--config"])
        .arg(&config)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not valid JSON"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn world_maps_become_contacts_and_bad_input_is_rejected() {
    let domain = format!("tracktest{}", std::process::id());
    let dir = std::env::temp_dir().join(&domain);
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("tracker.toml");
    std::fs::write(&config, format!("model = \"{}\"\n", model_path())).unwrap();
    let _process = runtime::testing::ServiceProcess::run(
        env!("CARGO_BIN_EXE_tracker"),
        config.as_os_str(),
        &domain,
    );
    let node = runtime::tool_node("tracker_test").unwrap();
    let mut maps = topics::WORLD_MAP.publisher(&node).unwrap();
    let contacts = topics::CONTACTS.subscriber(&node).unwrap();
    let beats = topics::HEARTBEAT.subscriber(&node).unwrap();
    let grid = GridGeometry {
        width: 100,
        height: 100,
        resolution_m: 0.5,
        center: [0.0, 0.0],
    };
    let mut publish = |k: u64, bad: bool| -> u64 {
        let stamp = 1_000_000_000 + k * 100_000_000;
        let mut s = maps.loan_slice(grid.cell_count() - bad as usize).unwrap();
        *s.user_header_mut() = WorldMapHeader {
            hdr: Header::new(maps.next_seq(), stamp, "test"),
            grid,
            ..Default::default()
        };
        let cells = s.payload_mut();
        cells.fill(MapCell::default());
        if !bad {
            for y in 60..64 {
                for x in 70..82 {
                    // Seen in this very map, as the mapper marks a cell its local map covered.
                    cells[y * 100 + x] = MapCell {
                        hazard: 230,
                        max_height_cm: 150,
                        observed: 8,
                        ..Default::default()
                    };
                }
            }
        }
        maps.send(s).unwrap();
        stamp
    };
    let end = Instant::now() + Duration::from_secs(10);
    let mut k = 0;
    let contact = loop {
        assert!(
            Instant::now() < end,
            "no confirmed contact from the tracker"
        );
        publish(k, false);
        k += 1;
        std::thread::sleep(Duration::from_millis(30));
        if let Some(s) = contacts.latest().unwrap() {
            if let Some(c) = s.payload().as_slice().iter().find(|c| c.confirmed == 1) {
                break *c;
            }
        }
    };
    // Block centre: cells 70..82 east, 60..64 north of a grid starting at -25 m.
    assert!(
        (contact.position[0] - 13.0).abs() < 0.3 && (contact.position[1] - 6.0).abs() < 0.3,
        "{contact:?}"
    );
    let bad_stamp = publish(k, true);
    k += 1;
    let end = Instant::now() + Duration::from_secs(10);
    'outer: loop {
        assert!(Instant::now() < end, "no heartbeat reporting the rejection");
        std::thread::sleep(Duration::from_millis(20));
        while let Some(b) = beats.receive().unwrap() {
            let b = b.payload();
            if b.hdr.source.as_str() == "tracker" && b.rejected > 0 {
                assert!(
                    b.last_error.as_str().contains("cells for a 100x100 grid"),
                    "{}",
                    b.last_error
                );
                assert_eq!(b.last_input_stamp_ns, bad_stamp);
                break 'outer;
            }
        }
    }
    let good = publish(k, false);
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        assert!(Instant::now() < end, "tracker stopped after bad input");
        std::thread::sleep(Duration::from_millis(20));
        if let Some(s) = contacts.receive().unwrap() {
            if s.payload().hdr.stamp_ns == good {
                break;
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
