//! The real `mapper` process: local maps in, a world map with the hazard at the right ENU place out;
//! a local map whose cell count does not match its grid is rejected in the heartbeat while the
//! service keeps running.

use messages::{topics, GridGeometry, Header, LocalMapHeader, MapCell, Pose};
use runtime::Ports;
use std::time::{Duration, Instant};

#[test]
fn local_maps_become_a_world_map_and_bad_input_is_rejected() {
    let domain = format!("maptest{}", std::process::id());
    let dir = std::env::temp_dir().join(&domain);
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("mapper.toml");
    std::fs::write(&config, "size_m = 100.0\nresolution_m = 0.5\n").unwrap();
    let _process = runtime::testing::ServiceProcess::run(
        env!("CARGO_BIN_EXE_mapper"),
        config.as_os_str(),
        &domain,
    );

    let node = runtime::tool_node("mapper_test").unwrap();
    let mut pub_ = topics::LOCAL_MAP.publisher(&node).unwrap();
    let maps = topics::WORLD_MAP.subscriber(&node).unwrap();
    let beats = topics::HEARTBEAT.subscriber(&node).unwrap();
    let grid = GridGeometry {
        width: 100,
        height: 100,
        resolution_m: 0.5,
        center: [100.0, 50.0],
    };
    let mut publish = |stamp: u64, bad: bool| {
        let n = grid.cell_count() - bad as usize;
        let mut s = pub_.loan_slice(n).unwrap();
        *s.user_header_mut() = LocalMapHeader {
            hdr: Header::new(pub_.next_seq(), stamp, "test"),
            frame_seq: 0,
            grid,
            vessel: Pose {
                position: [100.0, 50.0, 0.0],
                ..Default::default()
            },
        };
        let cells = s.payload_mut();
        cells.fill(MapCell {
            cost: 10,
            observed: 1,
            ..Default::default()
        });
        if !bad {
            let (c, r) = grid.cell_of(110.2, 47.3).unwrap();
            cells[(r * grid.width + c) as usize] = MapCell {
                hazard: 240,
                cost: 254,
                observed: 4,
                max_height_cm: 90,
                ..Default::default()
            };
        }
        pub_.send(s).unwrap();
    };

    // The hazard is confirmed at full strength once three local maps have seen it.
    let end = Instant::now() + Duration::from_secs(10);
    let mut stamp = 1_000_000_000u64;
    let mut strengths = Vec::new();
    let (hdr, cells) = loop {
        assert!(
            Instant::now() < end,
            "no confirmed hazard from the mapper: {strengths:?}"
        );
        stamp += 100_000_000;
        publish(stamp, false);
        std::thread::sleep(Duration::from_millis(30));
        if let Some(s) = maps.receive().unwrap() {
            let (hdr, cells) = (*s.user_header(), s.payload().to_vec());
            assert_eq!((hdr.grid.width, hdr.grid.height), (200, 200));
            assert_eq!(cells.len(), 200 * 200);
            let (c, r) = hdr.grid.cell_of(110.2, 47.3).unwrap();
            strengths.push(cells[(r * hdr.grid.width + c) as usize].hazard);
            if strengths.last() == Some(&240) {
                break (hdr, cells);
            }
        }
    };
    assert!(hdr.hdr.stamp_ns > 1_000_000_000 && hdr.hdr.stamp_ns <= stamp);
    assert!(
        strengths.iter().all(|&h| h == 80 || h == 160 || h == 240),
        "{strengths:?}"
    );
    assert_eq!(cells.iter().filter(|c| c.hazard > 0).count(), 1);

    // A short payload: rejected with the reason, and the service keeps publishing afterwards.
    let bad_stamp = stamp + 100_000_000;
    publish(bad_stamp, true);
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        assert!(Instant::now() < end, "no heartbeat reporting the rejection");
        std::thread::sleep(Duration::from_millis(20));
        let mut seen = false;
        while let Some(b) = beats.receive().unwrap() {
            let b = b.payload();
            if b.hdr.source.as_str() == "mapper" && b.rejected > 0 {
                assert!(
                    b.last_error.as_str().contains("cells for a 100x100 grid"),
                    "{}",
                    b.last_error
                );
                assert_eq!(b.last_input_stamp_ns, bad_stamp);
                seen = true;
            }
        }
        if seen {
            break;
        }
    }
    while maps.receive().unwrap().is_some() {}
    let good = bad_stamp + 100_000_000;
    publish(good, false);
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        assert!(
            Instant::now() < end,
            "mapper stopped publishing after bad input"
        );
        std::thread::sleep(Duration::from_millis(20));
        if let Some(s) = maps.receive().unwrap() {
            if s.user_header().hdr.stamp_ns == good {
                break;
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
