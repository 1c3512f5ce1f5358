//! Two real `bridge` processes linked over Zenoh on loopback (peer mode, explicit endpoints, no
//! multicast scouting): one in domain A sends INS and stereo frames, the other republishes them
//! into domain B, where this test receives them byte for byte.

mod common;

use common::*;
use messages::topics;
use runtime::Ports;
use std::time::{Duration, Instant};

#[test]
fn topics_cross_between_domains_over_zenoh() {
    let a = format!("bridgezA{}", std::process::id());
    let b = format!("bridgezB{}", std::process::id());
    let port = free_port();
    let topics_list = r#"["usv/sensors/ins", "usv/sensors/stereo_frame"]"#;
    let _sender = Bridge::start(
        &a,
        &format!(
            "listen = \"\"\n[zenoh]\nlisten = [\"tcp/127.0.0.1:{port}\"]\nkey_prefix = \"boat\"\npublish = {topics_list}\n"
        ),
    );
    let mut receiver = Bridge::start(
        &b,
        &format!(
            "listen = \"\"\n[zenoh]\nconnect = [\"tcp/127.0.0.1:{port}\"]\nkey_prefix = \"boat\"\nsubscribe = {topics_list}\n"
        ),
    );

    std::env::set_var(runtime::domain::DOMAIN_ENV, &a);
    let source = Source::start(Duration::from_millis(50), false);
    std::env::set_var(runtime::domain::DOMAIN_ENV, &b);
    let node = runtime::tool_node("bridge_test_remote").unwrap();
    let ins = topics::INS.subscriber(&node).unwrap();
    let frames = topics::STEREO_FRAME.subscriber(&node).unwrap();

    let end = Instant::now() + Duration::from_secs(30);
    let (mut got_ins, mut got_frame) = (0, 0);
    while got_ins < 5 || got_frame < 5 {
        assert!(
            Instant::now() < end,
            "over zenoh within 30 s: {got_ins} INS samples, {got_frame} frames"
        );
        while let Some(s) = ins.receive().unwrap() {
            let p = s.payload();
            assert_eq!(p.hdr.source.as_str(), "ins");
            assert_eq!(p.pose.position, [100.0, 50.0, 0.0]);
            assert_eq!(p.origin, ORIGIN);
            assert!(p.hdr.stamp_ns > 0);
            got_ins += 1;
        }
        while let Some(s) = frames.receive().unwrap() {
            let h = s.user_header();
            assert_eq!(h.head.as_str(), "hh_left");
            assert_eq!((h.width, h.height), (WIDTH, HEIGHT));
            let (left, right) = h.planes(s.payload()).expect("whole frame");
            assert!(left
                .iter()
                .enumerate()
                .all(|(i, &v)| v == pixel(i % WIDTH as usize, i / WIDTH as usize)));
            assert!(right.iter().all(|&v| v == 255));
            got_frame += 1;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    drop((ins, frames, node));
    drop(source);
    let status = receiver.stop();
    assert!(status.success(), "receiving bridge exited with {status}");
    drop(receiver);
    drop(_sender);
    assert!(leftovers(&a).is_empty(), "{:?}", leftovers(&a));
    assert!(leftovers(&b).is_empty(), "{:?}", leftovers(&b));
}
