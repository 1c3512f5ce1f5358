//! The real `bridge` process seen by a real WebSocket client: a source publishes stereo frames, INS
//! and a world map over shared memory; the client reads `serverInfo` and `advertise`, subscribes to
//! the image, grid and position channels, and checks what arrives against what was published.

mod common;

use base64::Engine;
use common::*;
use futures_util::SinkExt;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::Message;

fn decode(v: &Value) -> Vec<u8> {
    base64::engine::general_purpose::STANDARD
        .decode(v.as_str().expect("data is a string"))
        .expect("data is base64")
}

#[tokio::test(flavor = "current_thread")]
async fn foxglove_client_sees_images_maps_and_pose() {
    let domain = format!("bridgetest{}", std::process::id());
    std::env::set_var(runtime::domain::DOMAIN_ENV, &domain);
    let port = free_port();
    let mut bridge = Bridge::start(
        &domain,
        &format!(
            "listen = \"127.0.0.1:{port}\"\n[image]\nmax_hz = 4.0\ndownscale = 2\n[max_hz]\n\"usv/mapper/world_map\" = 2.0\n"
        ),
    );
    let source = Source::start(Duration::from_millis(50), true);

    // A client that does not offer the Foxglove subprotocol is refused.
    let plain = tokio_tungstenite::connect_async(format!("ws://127.0.0.1:{port}/")).await;
    assert!(plain.is_err(), "connection without subprotocol accepted");

    let mut ws = connect(port).await;
    let info = json(&next(&mut ws, Duration::from_secs(5)).await);
    assert_eq!(info["op"], "serverInfo");
    assert_eq!(info["name"], "bridge");
    // Channels: the initial advertisement, then one more per stereo head as frames arrive.
    let mut channels: BTreeMap<String, (u64, String)> = BTreeMap::new();
    let image_topic = "usv/sensors/stereo_frame/hh_left/image";
    let end = Instant::now() + Duration::from_secs(10);
    while !channels.contains_key(image_topic) {
        assert!(
            Instant::now() < end,
            "image channel never advertised: {channels:?}"
        );
        let m = json(&next(&mut ws, Duration::from_secs(10)).await);
        assert_eq!(m["op"], "advertise", "{m}");
        for c in m["channels"].as_array().unwrap() {
            assert_eq!(c["encoding"], "json");
            assert_eq!(c["schemaEncoding"], "jsonschema");
            let schema: Value = serde_json::from_str(c["schema"].as_str().unwrap()).unwrap();
            assert_eq!(schema["title"], c["schemaName"]);
            channels.insert(
                c["topic"].as_str().unwrap().into(),
                (
                    c["id"].as_u64().unwrap(),
                    c["schemaName"].as_str().unwrap().into(),
                ),
            );
        }
    }
    let expect = [
        (image_topic, "foxglove.RawImage", 10),
        ("usv/mapper/world_map/grid", "foxglove.Grid", 11),
        ("usv/sensors/ins/fix", "foxglove.LocationFix", 12),
    ];
    let mut subscriptions = Vec::new();
    for (topic, schema, sub) in expect {
        let (id, name) = &channels[topic];
        assert_eq!(name, schema);
        subscriptions.push(json!({"id": sub, "channelId": id}));
    }
    for topic in [
        "usv/sensors/ins/tf",
        "usv/tracker/contacts/scene",
        "usv/health/heartbeat/log",
        "usv/perception/local_map/grid",
    ] {
        assert!(channels.contains_key(topic), "{topic} not advertised");
    }
    // Bad requests get a status answer and do not break the session.
    ws.send(Message::text(
        r#"{"op":"subscribe","subscriptions":[{"id":1,"channelId":999}]}"#,
    ))
    .await
    .unwrap();
    ws.send(Message::text(
        json!({"op": "subscribe", "subscriptions": subscriptions}).to_string(),
    ))
    .await
    .unwrap();

    let started = Instant::now();
    let mut seen: BTreeMap<u32, Vec<Value>> = BTreeMap::new();
    let mut statuses = Vec::new();
    while seen.values().map(|v| v.len()).sum::<usize>() < 12 || seen.len() < 3 {
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "missing messages: {:?}",
            seen.iter().map(|(k, v)| (k, v.len())).collect::<Vec<_>>()
        );
        match next(&mut ws, Duration::from_secs(10)).await {
            Message::Binary(b) => {
                let (sub, ts, payload) = bridge::protocol::parse_data(&b).expect("data frame");
                assert!(ts > 0);
                assert!([10, 11, 12].contains(&sub), "subscription {sub} never made");
                seen.entry(sub)
                    .or_default()
                    .push(serde_json::from_slice(payload).expect("payload is JSON"));
            }
            m @ Message::Text(_) => statuses.push(json(&m)),
            _ => {}
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    assert!(
        statuses
            .iter()
            .any(|s| s["op"] == "status" && s["message"].as_str().unwrap().contains("999")),
        "{statuses:?}"
    );

    // Image: left plane, downscaled 2x (2x2 box average), as foxglove.RawImage.
    let image = &seen[&10][0];
    assert_eq!(image["width"], WIDTH / 2);
    assert_eq!(image["height"], HEIGHT / 2);
    assert_eq!(image["step"], WIDTH / 2);
    assert_eq!(image["encoding"], "mono8");
    assert_eq!(image["frame_id"], "hh_left");
    let data = decode(&image["data"]);
    assert_eq!(data.len(), (WIDTH * HEIGHT / 4) as usize);
    for (x, y) in [(0, 0), (5, 7), (319, 239), (100, 200)] {
        let sum: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
            .iter()
            .map(|(dx, dy)| pixel(2 * x + dx, 2 * y + dy) as u32)
            .sum();
        assert_eq!(data[y * 320 + x] as u32, (sum + 2) / 4, "pixel {x},{y}");
    }
    // Grid: every cell's bytes, origin at the south-west corner.
    let grid = &seen[&11][0];
    assert_eq!(grid["column_count"], GRID.width);
    assert_eq!(grid["cell_stride"], 8);
    assert_eq!(grid["row_stride"], 8 * GRID.width);
    assert_eq!(grid["pose"]["position"]["x"], 10.0 - 50.0);
    assert_eq!(grid["pose"]["position"]["y"], 20.0 - 25.0);
    let cells = decode(&grid["data"]);
    assert_eq!(cells.len(), GRID.cell_count() * 8);
    let c = cell(1234);
    assert_eq!(
        &cells[1234 * 8..1234 * 8 + 4],
        &[c.hazard, c.cost, c.water, c.observed]
    );
    // Position: 50 m north of the origin.
    let fix = &seen[&12][0];
    let lat = fix["latitude"].as_f64().unwrap();
    assert!(
        (lat - (59.0 + (50.0f64 / 6_371_000.0).to_degrees())).abs() < 1e-9,
        "{lat}"
    );

    // Rate limits: images at most 4 Hz, maps 2 Hz, INS (20 Hz, unlimited) passes whole.
    let rate = |sub: u32| seen.get(&sub).map_or(0, |v| v.len()) as f64 / elapsed;
    assert!(
        rate(10) <= 4.0 * 1.25 + 1.0 / elapsed,
        "image rate {}",
        rate(10)
    );
    assert!(
        rate(11) <= 2.0 * 1.25 + 1.0 / elapsed,
        "map rate {}",
        rate(11)
    );
    assert!(
        rate(12) > rate(10),
        "INS {} vs image {}",
        rate(12),
        rate(10)
    );

    // After unsubscribing, images stop (whatever was in flight may still arrive).
    ws.send(Message::text(
        r#"{"op":"unsubscribe","subscriptionIds":[10]}"#,
    ))
    .await
    .unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let quiet = Instant::now() + Duration::from_millis(800);
    while let Ok(Some(Ok(m))) = tokio::time::timeout(
        quiet.saturating_duration_since(Instant::now()),
        futures_util::StreamExt::next(&mut ws),
    )
    .await
    {
        if let Message::Binary(b) = m {
            let (sub, _, _) = bridge::protocol::parse_data(&b).unwrap();
            if Instant::now() > quiet - Duration::from_millis(500) {
                assert_ne!(sub, 10, "image after unsubscribe");
            }
        }
    }
    drop(ws);
    drop(source);
    let status = bridge.stop();
    assert!(status.success(), "bridge exited with {status}");
    drop(bridge);
    assert!(leftovers(&domain).is_empty(), "{:?}", leftovers(&domain));
}
