//! The real `perception` process with water detection on: a simulator colour frame of a trail with a
//! puddle ahead (rendered, matched by the stereo library as the stereo service does) goes in with its
//! INS sample; a `WaterMask` with water pixels on the puddle and a local map with water cells at the
//! puddle, at its elevation, come out. A disparity of another frame or another size is not fused and
//! is reported in the heartbeat, while the maps go on.

use messages::{topics, truth_class, water_cue, Header, Heartbeat, InsState};
use perception::water_bench::{render_colour_frame, ColourFrame};
use runtime::Ports;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The colour head of the head-on trail scenario at 512x384 (the paper's size), `t` s in.
fn render(t: f64) -> ColourFrame {
    let scenario =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../sim/scenarios/trail_puddles_headon.toml");
    render_colour_frame(&scenario, "color", 0.5, t).unwrap()
}

fn write_config(dir: &Path) -> PathBuf {
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/hazard.json");
    let config = dir.join("perception.toml");
    std::fs::write(
        &config,
        format!(
            "model = {:?}\nheads = [\"color\"]\nframe_deadline_ms = 5000\n[grid]\nwidth = 200\nheight = 200\nresolution_m = 0.5\n[water]\nheads = [\"color\"]\n",
            model.display().to_string()
        ),
    )
    .unwrap();
    config
}

#[test]
fn water_mask_and_water_cells_from_a_puddle_ahead() {
    // 3 s in: the first puddle (18 m east, radius 1.8 m) is 8-9 m ahead.
    let f = render(3.0);
    let n = (f.width * f.height) as usize;
    let domain = format!("percwater{}", std::process::id());
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path());
    let _process = runtime::testing::ServiceProcess::run(
        env!("CARGO_BIN_EXE_perception"),
        config.as_os_str(),
        &domain,
    );
    let node = runtime::tool_node("perception_water_test").unwrap();
    let mut frames = topics::STEREO_FRAME.publisher(&node).unwrap();
    let mut disparity_pub = topics::DISPARITY.publisher(&node).unwrap();
    let mut ins = topics::INS.publisher(&node).unwrap();
    let masks = topics::WATER_MASK.subscriber(&node).unwrap();
    let maps = topics::LOCAL_MAP.subscriber(&node).unwrap();
    let beats = topics::HEARTBEAT.subscriber(&node).unwrap();

    // One frame: INS, the pair, then its disparity (`disparity` may be of another size or seq).
    let mut send = |stamp: u64, frame_seq_offset: u64, disparity: &[f32], size: (u32, u32)| {
        let s = InsState {
            hdr: Header::new(ins.next_seq(), stamp, "test"),
            pose: f.vehicle,
            ..InsState::default()
        };
        ins.publish(&s).unwrap();
        let seq = frames.next_seq();
        let mut sample = frames.loan_slice(f.pair.len()).unwrap();
        sample.payload_mut().copy_from_slice(&f.pair);
        *sample.user_header_mut() = f.frame_header("color", seq, stamp);
        frames.send(sample).unwrap();
        std::thread::sleep(Duration::from_millis(20));
        let mut sample = disparity_pub.loan_slice(disparity.len()).unwrap();
        sample.payload_mut().copy_from_slice(disparity);
        let mut camera = f.camera;
        let scale = size.0 as f64 / f.width as f64;
        camera.fx *= scale;
        camera.fy *= scale;
        camera.cx *= scale;
        camera.cy *= scale;
        let mut header = f.disparity_header("color", seq + frame_seq_offset, stamp);
        header.hdr.seq = disparity_pub.next_seq();
        (header.width, header.height, header.camera) = (size.0, size.1, camera);
        *sample.user_header_mut() = header;
        disparity_pub.send(sample).unwrap();
    };

    let mut stamp = 7_000_000_000u64;
    let end = Instant::now() + Duration::from_secs(30);
    // The first frames may meet a service still connecting (a disparity without its colour frame
    // gives a map without a mask), so the mask is paired with the map of its own stamp.
    let mut mask: Option<(messages::WaterMaskHeader, Vec<u8>)> = None;
    let mut maps_by_stamp = HashMap::new();
    let paired = |mask: &Option<(messages::WaterMaskHeader, Vec<u8>)>, maps: &HashMap<u64, _>| {
        mask.as_ref()
            .is_some_and(|(h, _)| maps.contains_key(&h.hdr.stamp_ns))
    };
    while !paired(&mask, &maps_by_stamp) && Instant::now() < end {
        stamp += 200_000_000;
        send(stamp, 0, &f.disparity, (f.width, f.height));
        let wait = Instant::now() + Duration::from_secs(3);
        while !paired(&mask, &maps_by_stamp) && Instant::now() < wait {
            std::thread::sleep(Duration::from_millis(20));
            while let Some(s) = masks.receive().unwrap() {
                mask = Some((*s.user_header(), s.payload().to_vec()));
            }
            while let Some(s) = maps.receive().unwrap() {
                let h = *s.user_header();
                maps_by_stamp.insert(h.hdr.stamp_ns, (h, s.payload().to_vec()));
            }
        }
    }
    let (mh, mask) = mask.expect("no water mask");
    let (lh, cells) = maps_by_stamp
        .remove(&mh.hdr.stamp_ns)
        .expect("no local map of the water mask's frame");
    assert_eq!((mh.width, mh.height, mask.len()), (f.width, f.height, n));
    assert_eq!(mh.head.as_str(), "color");
    assert!(mh.regions >= 1, "{mh:?}");

    // Water pixels lie on the puddle, and cover a good part of the puddles in view.
    let water: Vec<usize> = (0..n)
        .filter(|&i| mask[i] & water_cue::WATER != 0)
        .collect();
    let on_puddle = water
        .iter()
        .filter(|&&i| f.labels[i] == truth_class::PUDDLE)
        .count();
    let puddle_pixels = f
        .labels
        .iter()
        .filter(|&&l| l == truth_class::PUDDLE)
        .count();
    assert!(water.len() >= 200, "{} water pixels", water.len());
    assert!(
        on_puddle as f64 >= 0.8 * water.len() as f64,
        "{on_puddle} of {} water pixels on a puddle",
        water.len()
    );
    assert!(
        on_puddle as f64 >= 0.3 * puddle_pixels as f64,
        "{on_puddle} of {puddle_pixels} puddle pixels found"
    );
    // Cue bits are there too, not only the fused one.
    assert!(water.iter().any(|&i| mask[i] & water_cue::COLOR != 0));

    // Water cells sit on the near puddle at its elevation.
    let g = &lh.grid;
    let (near_c, near_r, near_e) = f.puddles[0];
    let mut count = 0;
    for (i, c) in cells.iter().enumerate().filter(|(_, c)| c.water > 0) {
        count += 1;
        let p = g.cell_center(i as u32 % g.width, i as u32 / g.width);
        let d = f
            .puddles
            .iter()
            .map(|(c, r, _)| (p[0] - c[0]).hypot(p[1] - c[1]) - r)
            .fold(f64::INFINITY, f64::min);
        assert!(
            d <= 1.0,
            "water cell at {p:?} is {d:.2} m outside every puddle"
        );
        if (p[0] - near_c[0]).hypot(p[1] - near_c[1]) <= near_r {
            assert!(
                (c.elevation_cm as f64 / 100.0 - near_e).abs() <= 0.15,
                "water elevation {} cm, puddle at {near_e:.2} m",
                c.elevation_cm
            );
        }
    }
    assert!(count >= 4, "{count} water cells");
    eprintln!(
        "{} water pixels, {on_puddle} on a puddle of {puddle_pixels} puddle pixels; {count} water cells",
        water.len()
    );

    // Disparity of a frame that was never sent, then one of another size: not fused, reported.
    for (offset, size, expect) in [
        (5, (f.width, f.height), "no colour frame"),
        (0, (f.width / 2, f.height / 2), "not fused"),
    ] {
        stamp += 200_000_000;
        let small: Vec<f32>;
        let disparity = if size.0 == f.width {
            &f.disparity[..]
        } else {
            small = (0..(size.0 * size.1) as usize)
                .map(|i| {
                    let (x, y) = (i % size.0 as usize, i / size.0 as usize);
                    f.disparity[2 * y * f.width as usize + 2 * x] / 2.0
                })
                .collect();
            &small[..]
        };
        send(stamp, offset, disparity, size);
        let end = Instant::now() + Duration::from_secs(10);
        let mut seen: Option<Heartbeat> = None;
        while seen.is_none() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(20));
            while let Some(b) = beats.receive().unwrap() {
                let b = *b.payload();
                if b.hdr.source.as_str() == "perception" && b.last_error.as_str().contains(expect) {
                    seen = Some(b);
                }
            }
        }
        let beat = seen.unwrap_or_else(|| panic!("no heartbeat reporting '{expect}'"));
        assert!(beat.rejected >= 1);
        // The frame's local map still comes out, without a water mask.
        let end = Instant::now() + Duration::from_secs(10);
        let mut mapped = false;
        while !mapped && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(20));
            while let Some(s) = maps.receive().unwrap() {
                mapped |= s.user_header().hdr.stamp_ns == stamp;
            }
        }
        assert!(
            mapped,
            "no local map for the frame whose water was not fused"
        );
        while let Some(s) = masks.receive().unwrap() {
            assert_ne!(s.user_header().hdr.stamp_ns, stamp);
        }
    }
}
