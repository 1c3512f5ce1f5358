//! The real `sequencer` process: this test publishes INS and world maps, loads a mission over the
//! request-response service, sees the boat commanded forward, then stops the INS and sees the
//! watchdog's stop.

use messages::iceoryx2;
use messages::iceoryx2::prelude::*;
use messages::{
    command_mode, mission_action, topics, ActuatorCommand, GridGeometry, Header, InsState, MapCell,
    MissionCommand, MissionReply, Pose, WorldMapHeader, MAX_MISSION_TEXT,
};
use runtime::Ports;
use std::time::{Duration, Instant};

fn request(
    client: &iceoryx2::port::client::Client<ipc::Service, MissionCommand, (), MissionReply, ()>,
    action: u32,
    text: &str,
) -> MissionReply {
    let mut cmd = Box::new(MissionCommand {
        action,
        text_len: text.len() as u32,
        text: [0; MAX_MISSION_TEXT],
    });
    cmd.text[..text.len()].copy_from_slice(text.as_bytes());
    let end = Instant::now() + Duration::from_secs(10);
    // The server may not be up yet: resend until one is connected, then wait for its answer.
    loop {
        let pending = client.send_copy(*cmd).expect("send request");
        if pending.number_of_server_connections() > 0 {
            while Instant::now() < end {
                if let Some(reply) = pending.receive().expect("receive reply") {
                    return *reply.payload();
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            panic!("no reply from the sequencer");
        }
        assert!(Instant::now() < end, "no sequencer serving missions");
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn mission_drives_and_watchdog_stops_a_real_process() {
    let domain = format!("seqtest{}", std::process::id());
    let dir = std::env::temp_dir().join(&domain);
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("sequencer.toml");
    std::fs::write(
        &config,
        "input_deadline_ms = 2000\n[watchdog]\nins_timeout_s = 0.3\nmap_timeout_s = 0.5\n",
    )
    .unwrap();
    let _process = runtime::testing::ServiceProcess::run(
        env!("CARGO_BIN_EXE_sequencer"),
        config.as_os_str(),
        &domain,
    );

    let node = runtime::tool_node("sequencer_test").unwrap();
    let mut ins_pub = topics::INS.publisher(&node).unwrap();
    let mut map_pub = topics::WORLD_MAP.publisher(&node).unwrap();
    let commands = topics::ACTUATOR_COMMAND.subscriber(&node).unwrap();
    let name: ServiceName = topics::MISSION_SERVICE.try_into().unwrap();
    let service = node
        .service_builder(&name)
        .request_response::<MissionCommand, MissionReply>()
        .open_or_create()
        .unwrap();
    let client = service.client_builder().create().unwrap();

    // An invalid mission is refused with a message that names the field.
    let reply = request(
        &client,
        mission_action::LOAD,
        "[[step]]\ntype = \"goto\"\nwaypoints = [[100.0, 0.0]]\nsped = 4.0\n",
    );
    assert_eq!(reply.accepted, 0);
    assert!(reply.message.as_str().contains("sped"), "{}", reply.message);
    let reply = request(
        &client,
        mission_action::LOAD,
        "name = \"east\"\n[[step]]\ntype = \"goto\"\nwaypoints = [[500.0, 0.0]]\nspeed_mps = 5.0\n",
    );
    assert_eq!(reply.accepted, 1, "{}", reply.message);

    let grid = GridGeometry {
        width: 200,
        height: 200,
        resolution_m: 0.5,
        center: [0.0, 0.0],
    };
    let mut stamp = 1_000_000_000u64;
    let mut publish = |with_ins: bool, stamp: u64| {
        if with_ins {
            let ins = InsState {
                hdr: Header::new(ins_pub.next_seq(), stamp, "test"),
                pose: Pose::default(),
                velocity: [2.0, 0.0, 0.0],
                ..Default::default()
            };
            ins_pub.publish(&ins).unwrap();
        }
        let mut sample = map_pub.loan_slice(grid.cell_count()).unwrap();
        *sample.user_header_mut() = WorldMapHeader {
            hdr: Header::new(map_pub.next_seq(), stamp, "test"),
            grid,
            ..Default::default()
        };
        sample.payload_mut().fill(MapCell::default());
        map_pub.send(sample).unwrap();
    };
    // Runs the source at 20 Hz of stream time until a command satisfies `done`.
    let mut until = |with_ins: bool, done: &dyn Fn(&ActuatorCommand) -> bool| -> ActuatorCommand {
        let end = Instant::now() + Duration::from_secs(10);
        while Instant::now() < end {
            stamp += 50_000_000;
            publish(with_ins, stamp);
            std::thread::sleep(Duration::from_millis(20));
            while let Some(sample) = commands.receive().unwrap() {
                if done(sample.payload()) {
                    return *sample.payload();
                }
            }
        }
        panic!("no matching actuator command within 10 s");
    };
    let moving = until(true, &|c| {
        c.throttle_pct > 0.0 && c.mode == command_mode::NAVIGATING
    });
    assert!(moving.hdr.stamp_ns > 0);
    // INS stops, maps go on: the watchdog cuts the throttle.
    let stopped = until(false, &|c| c.mode == command_mode::SAFE_STOP);
    assert_eq!(stopped.throttle_pct, 0.0);
    let status = request(&client, mission_action::STATUS, "");
    assert!(
        status.message.as_str().contains("east"),
        "{}",
        status.message
    );
    let _ = std::fs::remove_dir_all(&dir);
}
