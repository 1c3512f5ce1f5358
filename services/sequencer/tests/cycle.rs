//! Whole cycles of the sequencer library: inputs in, command and status out.

use messages::{
    command_mode, contact_class, Contact, ContactList, GridGeometry, Header, InsState, MapCell,
    Pose, WorldMapHeader,
};
use sequencer::control::{KinematicBoat, OwnState};
use sequencer::{watchdog, Config, Sequencer};

const MS: u64 = 1_000_000;
const N: u32 = 200;

fn map(stamp_ns: u64, obstacles: &[(f64, f64)]) -> (WorldMapHeader, Vec<MapCell>) {
    let grid = GridGeometry {
        width: N,
        height: N,
        resolution_m: 0.5,
        center: [0.0, 0.0],
    };
    let mut cells = vec![MapCell::default(); grid.cell_count()];
    for &(e, n) in obstacles {
        if let Some((c, r)) = grid.cell_of(e, n) {
            cells[(r * N + c) as usize].cost = MapCell::LETHAL_COST;
        }
    }
    let hdr = WorldMapHeader {
        hdr: Header::new(0, stamp_ns, "test"),
        grid,
        ..Default::default()
    };
    (hdr, cells)
}

fn ins(stamp_ns: u64, yaw: f64, speed: f64) -> InsState {
    InsState {
        hdr: Header::new(0, stamp_ns, "test"),
        pose: Pose {
            yaw,
            ..Default::default()
        },
        velocity: [speed * yaw.cos(), speed * yaw.sin(), 0.0],
        ..Default::default()
    }
}

/// A wall of obstacles across the whole field of view, `range` m ahead (east).
fn wall(range: f64) -> Vec<(f64, f64)> {
    (-80..=80).map(|i| (range, i as f64 * 0.5)).collect()
}

fn feed(seq: &mut Sequencer, t: u64, obstacles: &[(f64, f64)]) {
    seq.on_ins(&ins(t, 0.0, 5.0)).unwrap();
    let (h, c) = map(t, obstacles);
    seq.on_map(&h, &c).unwrap();
}

fn started(mission: &str) -> Sequencer {
    let mut seq = Sequencer::new(Config::default()).unwrap();
    seq.load_mission(mission).unwrap();
    seq
}

const EAST: &str = "[[step]]\ntype = \"goto\"\nwaypoints = [[300.0, 0.0]]\nspeed_mps = 5.0\n";

#[test]
fn open_water_drives_to_the_goal() {
    let mut seq = started(EAST);
    let mut last = (0.0, 0.0);
    for k in 1..=50 {
        feed(&mut seq, k * 100 * MS, &[]);
        let (cmd, status) = seq.cycle("test");
        assert_eq!(cmd.mode, command_mode::NAVIGATING);
        assert_eq!(cmd.hdr.stamp_ns, k * 100 * MS);
        assert_eq!(status.blocked_arcs, [0, 0]);
        assert!(status.chosen_arc >= 0);
        last = (cmd.rudder_rad, cmd.throttle_pct);
    }
    assert!(last.0.abs() < 0.05, "straight on: rudder {}", last.0);
    assert!(last.1 > 5.0, "throttle {}", last.1);
}

#[test]
fn far_above_the_speed_asked_for_the_boat_brakes_astern_and_near_it_only_cuts_power() {
    // Asked for 5 m/s on open water: at 8 m/s the speed loop brakes astern, at 5.5 it does not.
    let throttle_at = |speed: f64| {
        let mut seq = started(EAST);
        let mut throttle = f32::NAN;
        for k in 1..=10 {
            seq.on_ins(&ins(k * 100 * MS, 0.0, speed)).unwrap();
            let (h, c) = map(k * 100 * MS, &[]);
            seq.on_map(&h, &c).unwrap();
            throttle = seq.cycle("test").0.throttle_pct;
        }
        throttle
    };
    assert!(throttle_at(8.0) < -10.0, "{}", throttle_at(8.0));
    let near = throttle_at(5.5);
    assert!((0.0..10.0).contains(&near), "{near}");
}

#[test]
fn obstacle_dead_ahead_turns_away() {
    let mut seq = started(EAST);
    let buoy = [(20.0, 0.0), (20.5, 0.0), (20.0, 0.5), (20.0, -0.5)];
    feed(&mut seq, 100 * MS, &buoy);
    let (cmd, status) = seq.cycle("test");
    let arcs = seq.arcs().arcs().to_vec();
    let straight = (0..arcs.len())
        .min_by(|&a, &b| arcs[a].curvature.abs().total_cmp(&arcs[b].curvature.abs()))
        .unwrap();
    assert!(
        status.arc_blocked(straight),
        "straight arc {straight} blocked"
    );
    assert!(status.chosen_arc >= 0);
    assert!(!status.arc_blocked(status.chosen_arc as usize));
    assert!(arcs[status.chosen_arc as usize].direction.abs() > 0.05);
    assert_eq!(cmd.mode, command_mode::NAVIGATING);
    // Steering towards the chosen side.
    for k in 2..20 {
        feed(&mut seq, k * 100 * MS, &buoy);
        seq.cycle("test");
    }
    let (cmd, status) = seq.cycle("test");
    let side = arcs[status.chosen_arc as usize].direction.signum();
    assert_eq!(
        (cmd.rudder_rad as f64).signum(),
        side,
        "rudder {}",
        cmd.rudder_rad
    );
}

/// Cruising east at 10 m/s (the INS keeps saying 5 m/s), so the throttle is well up.
fn cruising() -> (Sequencer, u64) {
    let mut seq = started(&EAST.replace("speed_mps = 5.0", "speed_mps = 10.0"));
    for k in 1..=30 {
        feed(&mut seq, k * 100 * MS, &[]);
        seq.cycle("test");
    }
    let throttle = seq.cycle("test").0.throttle_pct;
    assert!(throttle > 15.0, "{throttle}");
    (seq, 31 * 100 * MS)
}

#[test]
fn every_arc_blocked_further_out_slows_along_an_arc_free_close_in() {
    let (mut seq, t0) = cruising();
    // A wall across the whole view 25 m ahead: it cuts every arc, but none in its first 15 m.
    let obstacles = wall(25.0);
    let mut last = None;
    for k in 0..20 {
        feed(&mut seq, t0 + k * 100 * MS, &obstacles);
        let (cmd, status) = seq.cycle("test");
        assert_eq!(cmd.mode, command_mode::BLOCKED);
        assert!((0..64).all(|a| status.arc_blocked(a)), "every arc blocked");
        assert!(status.chosen_arc >= 0, "an arc free close in is taken");
        if k == 0 {
            assert!(
                cmd.throttle_pct < 5.0,
                "power cut at once: {}",
                cmd.throttle_pct
            );
        }
        last = Some(cmd);
    }
    let cmd = last.unwrap();
    assert!(
        cmd.throttle_pct < 0.0,
        "5 m/s against 2 m/s asked: braking astern, {}",
        cmd.throttle_pct
    );
    assert!(cmd.throttle_pct as f64 >= seq.config().control.brake_throttle_pct);

    // Braked down to 0.4 m/s, still blocked further out: power to get back to 2 m/s, well above
    // the throttle that merely holds 2 m/s, or the boat crawls and its rudder barely turns it.
    let holding = seq.config().control.throttle_for_speed(2.0);
    let mut cmd = cmd;
    for k in 20..50 {
        let t = t0 + k * 100 * MS;
        seq.on_ins(&ins(t, 0.0, 0.4)).unwrap();
        let (h, c) = map(t, &obstacles);
        seq.on_map(&h, &c).unwrap();
        cmd = seq.cycle("test").0;
        assert_eq!(cmd.mode, command_mode::BLOCKED);
    }
    assert!(
        cmd.throttle_pct as f64 > 3.0 * holding,
        "{} % against {holding:.1} % that holds 2 m/s",
        cmd.throttle_pct
    );
}

#[test]
fn every_arc_blocked_close_in_brakes_and_turns_away() {
    let (mut seq, t0) = cruising();
    // A wall close ahead, more of it to starboard (south) than to port.
    let mut obstacles = wall(6.0);
    obstacles.extend((0..20).map(|i| (3.0, -3.0 - i as f64 * 0.5)));
    feed(&mut seq, t0, &obstacles);
    let (cmd, status) = seq.cycle("test");
    assert_eq!(cmd.mode, command_mode::BLOCKED);
    assert_eq!(status.chosen_arc, -1);
    assert!(status.arc_blocked(0) && status.arc_blocked(63));
    let brake = seq.config().control.brake_throttle_pct;
    assert_eq!(cmd.throttle_pct as f64, brake, "full astern at once");
    let mut cmd = cmd;
    for k in 1..=40 {
        feed(&mut seq, t0 + k * 100 * MS, &obstacles);
        cmd = seq.cycle("test").0;
        assert_eq!(cmd.mode, command_mode::BLOCKED);
    }
    assert!(
        cmd.rudder_rad > 0.5,
        "hard to port, away from the starboard obstacles: {}",
        cmd.rudder_rad
    );
    // Stopped, with hazards astern too: no astern power, which would back the boat into them.
    let mut boxed_in = obstacles.clone();
    boxed_in.extend((-4..=4).map(|i| (-6.0, i as f64 * 0.5)));
    let t1 = t0 + 41 * 100 * MS;
    seq.on_ins(&ins(t1, 0.0, 0.1)).unwrap();
    let (h, c) = map(t1, &boxed_in);
    seq.on_map(&h, &c).unwrap();
    let cmd = seq.cycle("test").0;
    assert_eq!(cmd.mode, command_mode::BLOCKED);
    assert_eq!(cmd.throttle_pct, 0.0);
    // Carried astern at 0.8 m/s (by a current, or by the brake itself): no astern power either.
    // Counted over ground whatever its direction, that speed kept the brake on and backed the
    // boat up ever faster.
    let t2 = t1 + 100 * MS;
    seq.on_ins(&ins(t2, 0.0, -0.8)).unwrap();
    let (h, c) = map(t2, &boxed_in);
    seq.on_map(&h, &c).unwrap();
    let cmd = seq.cycle("test").0;
    assert_eq!(cmd.mode, command_mode::BLOCKED);
    assert_eq!(cmd.throttle_pct, 0.0);
    // The water astern clear: it backs off, under speed control (already going astern at
    // 0.8 m/s, a little power; at 2 m/s, none).
    let mut cmd = cmd;
    for k in 3..18 {
        let t = t1 + k * 100 * MS;
        seq.on_ins(&ins(t, 0.0, -0.8)).unwrap();
        let (h, c) = map(t, &obstacles);
        seq.on_map(&h, &c).unwrap();
        let status;
        (cmd, status) = seq.cycle("test");
        assert_eq!(cmd.mode, command_mode::BLOCKED);
        assert_eq!(status.chosen_arc, -1);
        assert!(cmd.throttle_pct < 0.0, "{}", cmd.throttle_pct);
    }
    assert!(
        cmd.rudder_rad < -0.5,
        "astern, the rudder hard to starboard swings the bow to port: {}",
        cmd.rudder_rad
    );
    let t = t1 + 18 * 100 * MS;
    seq.on_ins(&ins(t, 0.0, -2.0)).unwrap();
    let (h, c) = map(t, &obstacles);
    seq.on_map(&h, &c).unwrap();
    let last = seq.cycle("test").0.throttle_pct;
    assert_eq!(last, 0.0, "backing faster than asked: power off");
}

/// INS from a kinematic boat's state.
fn ins_of(stamp_ns: u64, own: &OwnState) -> InsState {
    InsState {
        hdr: Header::new(0, stamp_ns, "test"),
        pose: Pose {
            position: [own.position[0], own.position[1], 0.0],
            yaw: own.yaw,
            ..Default::default()
        },
        velocity: [
            own.speed_mps * own.yaw.cos(),
            own.speed_mps * own.yaw.sin(),
            0.0,
        ],
        angular_rate: [0.0, 0.0, own.yaw_rate],
        ..Default::default()
    }
}

#[test]
fn boxed_in_close_ahead_the_stopped_boat_backs_off_and_gets_round() {
    // Stopped 7 m short of a 12 m wall square across its course, its goal beyond: every arc meets
    // the wall within `near_m`, and the boat turns no tighter than its turning circle, however
    // slowly it goes. Ten cycles a second for 60 s against a kinematic boat like the simulator's.
    let obstacle: Vec<(f64, f64)> = (-12..=12).map(|i| (7.0, i as f64 * 0.5)).collect();
    let run = |back_off_speed_mps: f64| {
        let mut cfg = Config::default();
        cfg.control.back_off_speed_mps = back_off_speed_mps;
        let mut seq = Sequencer::new(cfg).unwrap();
        seq.load_mission(EAST).unwrap();
        let mut boat = KinematicBoat::new([0.0, 0.0], 0.0, seq.config().control.max_speed_mps);
        let (mut slowest, mut clearance) = (0.0f64, f64::INFINITY);
        for k in 1..=600u64 {
            let t = k * 100 * MS;
            seq.on_ins(&ins_of(t, &boat.state)).unwrap();
            let (h, c) = map(t, &obstacle);
            seq.on_map(&h, &c).unwrap();
            let cmd = seq.cycle("test").0;
            boat.step(cmd.rudder_rad as f64, cmd.throttle_pct as f64, 0.1);
            slowest = slowest.min(boat.state.speed_mps);
            let p = boat.state.position;
            clearance = obstacle
                .iter()
                .map(|o| (o.0 - p[0]).hypot(o.1 - p[1]))
                .fold(clearance, f64::min);
        }
        (boat.state.position, slowest, clearance)
    };
    let (position, slowest, clearance) = run(1.0);
    assert!(slowest < -0.5, "it backed off: slowest {slowest:.2} m/s");
    assert!(
        position[0] > 30.0,
        "round the wall towards the goal: at {position:?}"
    );
    assert!(clearance > 2.0, "kept clear of the wall: {clearance:.2} m");
    // Without backing off it only turns its rudder, and stays where it stopped.
    let (position, slowest, _) = run(0.0);
    assert!(slowest > -0.1, "{slowest}");
    assert!(position[0] < 7.0, "still short of the wall: {position:?}");
}

#[test]
fn every_arc_blocked_close_in_with_a_boat_met_head_on_turns_to_starboard() {
    // As above (more obstacles to starboard), with a boat coming west down our lane 40 m ahead:
    // braking, the boat still runs on, so it turns to starboard, away from the boat's course.
    let hard_over = |head_on_max_course_deg: f64, boat: [f64; 2]| {
        let mut cfg = Config::default();
        cfg.arcs.head_on_max_course_deg = head_on_max_course_deg;
        let mut seq = Sequencer::new(cfg).unwrap();
        seq.load_mission(EAST).unwrap();
        let mut obstacles = wall(6.0);
        obstacles.extend((0..20).map(|i| (3.0, -3.0 - i as f64 * 0.5)));
        let mut cmd = None;
        for k in 1..=40u64 {
            let t = k * 100 * MS;
            feed(&mut seq, t, &obstacles);
            seq.on_contacts(&boat_contacts(t, boat, [-6.0, 0.0]));
            let (c, status) = seq.cycle("test");
            assert_eq!(c.mode, command_mode::BLOCKED);
            assert_eq!(status.chosen_arc, -1);
            cmd = Some(c);
        }
        cmd.unwrap().rudder_rad
    };
    let without_rule = hard_over(0.0, [40.0, 3.0]);
    assert!(
        without_rule > 0.5,
        "without the rule, to port: {without_rule}"
    );
    let with_rule = hard_over(30.0, [40.0, 3.0]);
    assert!(with_rule < -0.5, "head-on, to starboard: {with_rule}");
    // A "boat" first met 12 m off (`arcs.late_birth_m` is 20 m) is no meeting: away from the
    // obstacles, to port.
    let too_close = hard_over(30.0, [12.0, 3.0]);
    assert!(too_close > 0.5, "met 12 m off, to port: {too_close}");
}

#[test]
fn watchdog_stops_on_stale_ins_and_recovers() {
    let mut seq = started(EAST);
    for k in 1..=20 {
        feed(&mut seq, k * 100 * MS, &[]);
        seq.cycle("test");
    }
    // INS stops; maps keep coming.
    let mut t = 20 * 100 * MS;
    let mut cmd = seq.cycle("test").0;
    for _ in 0..10 {
        t += 100 * MS;
        let (h, c) = map(t, &[]);
        seq.on_map(&h, &c).unwrap();
        let (c, status) = seq.cycle("test");
        cmd = c;
        if cmd.mode == command_mode::SAFE_STOP {
            assert_eq!(status.stale_inputs, watchdog::INS);
        }
    }
    assert_eq!(cmd.mode, command_mode::SAFE_STOP);
    assert_eq!(cmd.throttle_pct, 0.0);
    // INS returns: control resumes.
    for _ in 0..20 {
        t += 100 * MS;
        feed(&mut seq, t, &[]);
        cmd = seq.cycle("test").0;
    }
    assert_eq!(cmd.mode, command_mode::NAVIGATING);
    assert!(cmd.throttle_pct > 0.0);
}

#[test]
fn nan_ins_is_refused_and_an_invalid_mission_leaves_the_running_one() {
    let mut seq = started(EAST);
    let mut bad = ins(MS, 0.0, 1.0);
    bad.pose.yaw = f64::NAN;
    assert!(seq.on_ins(&bad).unwrap_err().to_string().contains("NaN"));
    let reply = seq.request(
        messages::mission_action::LOAD,
        b"[[step]]\ntype = \"goto\"\nwaypoints = [[1.0, 2.0]]\nspeed_mps = 0\n",
    );
    assert_eq!(reply.accepted, 0);
    assert!(
        reply.message.as_str().contains("speed_mps"),
        "{}",
        reply.message
    );
    let status = seq.request(messages::mission_action::STATUS, b"");
    assert!(
        status.message.as_str().contains("running"),
        "{}",
        status.message
    );
    assert_eq!(status.step, 0);
    assert_eq!(
        seq.request(messages::mission_action::PAUSE, b"").accepted,
        1
    );
    feed(&mut seq, 100 * MS, &[]);
    let (cmd, status) = seq.cycle("test");
    assert_eq!(
        (cmd.mode, cmd.throttle_pct, status.paused),
        (command_mode::IDLE, 0.0, 1)
    );
    assert_eq!(
        seq.request(messages::mission_action::ABORT, b"").accepted,
        1
    );
    assert_eq!(
        seq.request(messages::mission_action::RESUME, b"").accepted,
        0
    );
}

/// A confirmed boat contact, tracked for 5 s, at `position` (ENU) moving at `velocity`.
fn boat_contacts(stamp_ns: u64, position: [f64; 2], velocity: [f64; 2]) -> ContactList {
    let mut list = ContactList {
        hdr: Header::new(0, stamp_ns, "test"),
        count: 1,
        ..Default::default()
    };
    list.contacts[0] = Contact {
        id: 7,
        class: contact_class::BOAT,
        confirmed: 1,
        position,
        velocity,
        extent: [6.0, 2.5, 1.5],
        age_s: 5.0,
        ..Default::default()
    };
    list
}

#[test]
fn a_boat_about_to_cross_ahead_blocks_the_course_the_empty_map_leaves_open() {
    // Heading east at 5 m/s; a boat 25 m ahead and 25 m to starboard heads north at 5 m/s: it
    // reaches our track when we do. The map is empty (it only knows where the boat is now).
    let crossing = boat_contacts(100 * MS, [25.0, -25.0], [0.0, 5.0]);
    let mut seq = started(EAST);
    feed(&mut seq, 100 * MS, &[]);
    seq.on_contacts(&crossing);
    let (cmd, status) = seq.cycle("test");
    let straight = seq.arcs().nearest(0.0);
    assert!(status.arc_blocked(straight), "straight arc {straight} free");
    assert!(status.chosen_arc >= 0, "some arc stays free");
    assert_ne!(status.chosen_arc as usize, straight);
    assert!(!status.arc_blocked(status.chosen_arc as usize));
    assert_eq!(cmd.mode, command_mode::NAVIGATING);

    // The same boat heading away south is no threat: straight on.
    let mut seq = started(EAST);
    feed(&mut seq, 100 * MS, &[]);
    seq.on_contacts(&boat_contacts(100 * MS, [25.0, -25.0], [0.0, -5.0]));
    let (_, status) = seq.cycle("test");
    assert_eq!(status.blocked_arcs, [0, 0]);
    assert_eq!(status.chosen_arc as usize, straight);

    // A track younger than `moving_min_age_s`, or one the classifier calls a channel marker
    // that wobbles slower than `marker_max_speed_mps`, blocks where it is: its velocity is a few
    // noisy updates or its blob changing shape, not motion. Far to starboard, it leaves the
    // straight arc free.
    let mut young = crossing;
    young.contacts[0].age_s = 0.8;
    let mut marker = crossing;
    marker.contacts[0].class = contact_class::CHANNEL_MARKER;
    marker.contacts[0].velocity = [0.0, 1.8];
    for list in [young, marker] {
        let mut seq = started(EAST);
        feed(&mut seq, 100 * MS, &[]);
        seq.on_contacts(&list);
        let (_, status) = seq.cycle("test");
        assert!(!status.arc_blocked(straight), "{:?}", list.contacts[0]);
    }

    // A tentative track does not steer the boat yet.
    let mut tentative = crossing;
    tentative.contacts[0].confirmed = 0;
    let mut seq = started(EAST);
    feed(&mut seq, 100 * MS, &[]);
    seq.on_contacts(&tentative);
    assert_eq!(seq.cycle("test").1.blocked_arcs, [0, 0]);
}

#[test]
fn a_buoy_the_tracker_holds_blocks_arcs_before_the_map_confirms_it() {
    // The map has nothing yet at the arc threshold; the tracker has a buoy 20 m dead ahead.
    let mut buoy = boat_contacts(100 * MS, [20.0, 0.0], [0.1, -0.1]);
    buoy.contacts[0].class = contact_class::CHANNEL_MARKER;
    buoy.contacts[0].extent = [1.0, 1.0, 1.0];
    let mut seq = started(EAST);
    feed(&mut seq, 100 * MS, &[]);
    seq.on_contacts(&buoy);
    let (cmd, status) = seq.cycle("test");
    let straight = seq.arcs().nearest(0.0);
    assert!(status.arc_blocked(straight), "straight arc {straight} free");
    assert!(status.chosen_arc >= 0);
    assert!(!status.arc_blocked(status.chosen_arc as usize));
    assert_eq!(cmd.mode, command_mode::NAVIGATING);

    // A buoy's track may wobble at 1.5 m/s and blocks where it is; a "marker" drifting at 4.5 m/s
    // (wave glint, or in transit perhaps a boat) blocks where it will be: south of our course by
    // the time we get there.
    for (speed, blocks) in [(1.5, true), (4.5, false)] {
        let mut moved = buoy;
        moved.contacts[0].velocity = [0.0, -speed];
        let mut seq = started(EAST);
        feed(&mut seq, 100 * MS, &[]);
        seq.on_contacts(&moved);
        assert_eq!(
            seq.cycle("test").1.arc_blocked(straight),
            blocks,
            "marker at {speed} m/s"
        );
    }

    // The tracker's false alarms steer nothing.
    let mut false_alarm = buoy;
    false_alarm.contacts[0].class = contact_class::FALSE_ALARM;
    let mut seq = started(EAST);
    feed(&mut seq, 100 * MS, &[]);
    seq.on_contacts(&false_alarm);
    assert_eq!(seq.cycle("test").1.blocked_arcs, [0, 0]);
}

#[test]
fn shore_sized_and_slow_extended_contacts_are_left_to_the_map() {
    // A 20 x 34 m blob of bank, "moving" at 6 m/s as it changes shape, across our course; a boat
    // the same size; and a 10 x 8 m patch the classifier calls extended (wave glint) dead ahead,
    // drifting slower than `marker_max_speed_mps` (faster, in transit, it may be a boat's wake:
    // `in_transit_a_fast_marker_or_extended_track_coming_head_on_blocks_its_lane_like_a_boat`).
    let mut bank = boat_contacts(100 * MS, [25.0, -25.0], [0.0, 6.0]);
    bank.contacts[0].class = contact_class::EXTENDED;
    bank.contacts[0].extent = [20.0, 34.0, 3.0];
    let mut big_boat = bank;
    big_boat.contacts[0].class = contact_class::BOAT;
    let mut patch = boat_contacts(100 * MS, [20.0, 0.0], [1.5, 1.0]);
    patch.contacts[0].class = contact_class::EXTENDED;
    patch.contacts[0].extent = [10.0, 8.0, 2.0];
    for list in [bank, big_boat, patch] {
        let mut seq = started(EAST);
        feed(&mut seq, 100 * MS, &[]);
        seq.on_contacts(&list);
        let (cmd, status) = seq.cycle("test");
        assert_eq!(status.blocked_arcs, [0, 0], "{:?}", list.contacts[0]);
        assert_eq!(cmd.mode, command_mode::NAVIGATING);
    }
    // The map still holds an extended obstacle that persists.
    let mut seq = started(EAST);
    feed(&mut seq, 100 * MS, &[(20.0, 0.0)]);
    seq.on_contacts(&patch);
    let straight = seq.arcs().nearest(0.0);
    assert!(seq.cycle("test").1.arc_blocked(straight));
}

#[test]
fn in_transit_a_fast_marker_or_extended_track_coming_head_on_blocks_its_lane_like_a_boat() {
    // Heading east at 5 m/s; 50 m ahead and 6 m to port a compact track comes west at 6 m/s: a
    // boat seen bow-on, which the classifier may call a channel marker or, along its wake,
    // extended. We would meet 23 m on, 6 m apart: too close for the hull, the margin and its 3 m
    // half-extent.
    let mut oncoming = boat_contacts(100 * MS, [50.0, 6.0], [-6.0, 0.0]);
    oncoming.contacts[0].extent = [5.0, 3.0, 2.0];
    for class in [contact_class::CHANNEL_MARKER, contact_class::EXTENDED] {
        oncoming.contacts[0].class = class;
        let mut seq = started(EAST);
        feed(&mut seq, 100 * MS, &[]);
        seq.on_contacts(&oncoming);
        let (cmd, status) = seq.cycle("test");
        let straight = seq.arcs().nearest(0.0);
        assert!(
            status.arc_blocked(straight),
            "class {class}: straight arc free"
        );
        // Turning to port would cross its lane ahead of it; the boat turns to starboard.
        let chosen = status.chosen_arc;
        assert!(
            chosen >= 0 && chosen < straight as i32,
            "class {class}: chose arc {chosen}"
        );
        assert_eq!(cmd.mode, command_mode::NAVIGATING);

        // Following a boat 20 m ahead, the same track is left to the map as drifting glint: near
        // a followed target's wake, such tracks swerved the boat off its target.
        let mut contacts = oncoming;
        contacts.count = 2;
        contacts.contacts[1] = Contact {
            id: 3,
            ..boat_contacts(100 * MS, [20.0, -6.0], [5.0, 0.0]).contacts[0]
        };
        let mut seq = started("[[step]]\ntype = \"follow\"\ncontact_id = 3\nastern_m = 20.0\n");
        feed(&mut seq, 100 * MS, &[]);
        seq.on_contacts(&contacts);
        assert_eq!(seq.cycle("test").1.blocked_arcs, [0, 0], "class {class}");
    }

    // A fast "extended" piece drifting south-west 25 m ahead and 45 m to port would pass 23 m
    // off our course (`arcs.fast_contact_cpa_m` 20 m): glint along a bank, left to the map,
    // though as a boat it would meet the hardest turn to port.
    let mut drifting = boat_contacts(100 * MS, [25.0, 45.0], [-1.0, -4.0]);
    drifting.contacts[0].class = contact_class::EXTENDED;
    drifting.contacts[0].extent = [5.0, 3.5, 5.0];
    let blocked_with = |cpa_m: f64| {
        let mut cfg = Config::default();
        cfg.arcs.fast_contact_cpa_m = cpa_m;
        let mut seq = Sequencer::new(cfg).unwrap();
        seq.load_mission(EAST).unwrap();
        feed(&mut seq, 100 * MS, &[]);
        seq.on_contacts(&drifting);
        seq.cycle("test").1.blocked_arcs
    };
    assert_eq!(blocked_with(20.0), [0, 0]);
    assert_ne!(blocked_with(30.0), [0, 0]);
}

#[test]
fn a_boat_met_head_on_is_passed_port_to_port_even_with_the_waypoint_to_port() {
    // Heading east at 5 m/s toward a waypoint 22 deg to port, beyond a bend; 70 m ahead and 8 m
    // to port a boat comes west at 6 m/s, down our lane: we would meet 32 m on, 8 m apart.
    const NORTH_EAST: &str =
        "[[step]]\ntype = \"goto\"\nwaypoints = [[300.0, 120.0]]\nspeed_mps = 5.0\n";
    let boat = boat_contacts(100 * MS, [70.0, 8.0], [-6.0, 0.0]);
    let direction = |seq: &Sequencer, arc: i32| seq.arcs().arcs()[arc as usize].direction;
    let run =
        |head_on_max_course_deg: f64, yaw: f64, contacts: &ContactList, seq: Option<Sequencer>| {
            let mut seq = seq.unwrap_or_else(|| {
                let mut cfg = Config::default();
                cfg.arcs.head_on_max_course_deg = head_on_max_course_deg;
                let mut seq = Sequencer::new(cfg).unwrap();
                seq.load_mission(NORTH_EAST).unwrap();
                seq
            });
            let t = contacts.hdr.stamp_ns;
            seq.on_ins(&ins(t, yaw, 5.0)).unwrap();
            let (h, c) = map(t, &[]);
            seq.on_map(&h, &c).unwrap();
            seq.on_contacts(contacts);
            let (cmd, status) = seq.cycle("test");
            assert_eq!(cmd.mode, command_mode::NAVIGATING);
            (seq, status.chosen_arc)
        };

    // Without the rule the boat turns to port, toward the waypoint and across the boat's bow.
    let (seq, arc) = run(0.0, 0.0, &boat, None);
    assert!(direction(&seq, arc) > 0.0, "arc {arc} without the rule");
    // With it (30 deg), to starboard.
    let (seq, arc) = run(30.0, 0.0, &boat, None);
    assert!(direction(&seq, arc) <= 0.0, "arc {arc} with the rule");

    // Turned 40 deg to starboard, the boat would pass 28 m off, on a course 40 deg off our
    // reciprocal: not head-on if met now, but the boat already met stays met, so we do not turn
    // back across its bow ...
    let later = |position: [f64; 2]| boat_contacts(200 * MS, position, [-6.0, 0.0]);
    let yaw = -40f64.to_radians();
    let (_, arc) = run(30.0, yaw, &later([64.0, 8.0]), None);
    let fresh = arc;
    let (seq, arc) = run(30.0, yaw, &later([64.0, 8.0]), Some(seq));
    assert!(
        direction(&seq, fresh) > 0.0,
        "arc {fresh} when first met turned away"
    );
    assert!(direction(&seq, arc) <= 0.0, "arc {arc} after meeting it");
    // ... until it is abeam: then the course turns back toward the waypoint.
    let (seq, arc) = run(30.0, yaw, &later([-5.0, 8.0]), Some(seq));
    assert!(direction(&seq, arc) > 0.0, "arc {arc} with the boat abeam");
}

#[test]
fn a_boat_met_head_on_while_already_turned_to_port_makes_us_turn_to_starboard_of_its_reciprocal() {
    // Heading 20 deg to port of east, toward a waypoint beyond a bend, when a boat 60 m ahead comes
    // west at 6 m/s: holding this course (no port turn) would still cross its lane. The arcs that
    // end to port of east, the reciprocal of its course, count as blocked: we turn 20 deg or more
    // to starboard.
    const NORTH_EAST: &str =
        "[[step]]\ntype = \"goto\"\nwaypoints = [[300.0, 120.0]]\nspeed_mps = 5.0\n";
    let yaw = 20f64.to_radians();
    let mut seq = Sequencer::new(Config::default()).unwrap();
    seq.load_mission(NORTH_EAST).unwrap();
    let mut last = None;
    for k in 1..=5u64 {
        let t = k * 100 * MS;
        seq.on_ins(&ins(t, yaw, 5.0)).unwrap();
        let (h, c) = map(t, &[]);
        seq.on_map(&h, &c).unwrap();
        seq.on_contacts(&boat_contacts(t, [60.0, 15.0], [-6.0, 0.0]));
        last = Some(seq.cycle("test"));
    }
    let (cmd, status) = last.unwrap();
    assert_eq!(cmd.mode, command_mode::NAVIGATING);
    let direction = seq.arcs().arcs()[status.chosen_arc as usize].direction;
    assert!(
        direction <= -yaw + 0.02,
        "arc {} turns {:.1} deg",
        status.chosen_arc,
        direction.to_degrees()
    );
    assert!(cmd.rudder_rad < 0.0, "rudder {}", cmd.rudder_rad);
}

#[test]
fn close_behind_a_followed_boat_only_the_water_up_to_the_look_ahead_is_judged() {
    // Following boat #3 heading east at 5 m/s, 20 m ahead. A hazard cell dead ahead 37 m out and a
    // boat-class contact 38 m out beside the target's track: beyond the follow look-ahead (25 m,
    // whose corridor is 9 m wide at its end), so the boat stays on the target's track.
    const FOLLOW: &str = "[[step]]\ntype = \"follow\"\ncontact_id = 3\nastern_m = 20.0\n";
    let mut contacts = boat_contacts(100 * MS, [38.0, -3.0], [0.0, 0.0]);
    contacts.count = 2;
    contacts.contacts[0].extent = [2.0, 2.0, 1.0];
    contacts.contacts[1] = Contact {
        id: 3,
        ..boat_contacts(100 * MS, [20.0, 0.0], [5.0, 0.0]).contacts[0]
    };
    let far = [(37.0, 0.0)];
    let mut seq = started(FOLLOW);
    feed(&mut seq, 100 * MS, &far);
    seq.on_contacts(&contacts);
    let (cmd, status) = seq.cycle("test");
    let straight = seq.arcs().nearest(0.0);
    assert_eq!(status.blocked_arcs, [0, 0]);
    assert_eq!(status.chosen_arc as usize, straight);
    assert_eq!(cmd.mode, command_mode::NAVIGATING);

    // On the way to a waypoint the same water blocks the straight arc ...
    let mut seq = started(EAST);
    feed(&mut seq, 100 * MS, &far);
    seq.on_contacts(&contacts);
    assert!(seq.cycle("test").1.arc_blocked(straight));
    // Behind the target, the water it went over (its trail, `arcs.followed_wake_map_m`) blocks
    // nothing. Followed for 2 s as it went from 22 m ahead to 32 m (the vessel holds still here),
    // the cells it left 8-9 m astern of it block no arc, nor does its wake from before it was
    // followed, 6-8 m astern of where it was first seen (it was under way then) ...
    let followed = |cells: &[(f64, f64)]| {
        let mut seq = started(FOLLOW);
        let mut status = None;
        for k in 0..=20u64 {
            let t = (100 + 100 * k) * MS;
            let mut list = contacts;
            list.hdr.stamp_ns = t;
            list.contacts[1].position = [22.0 + 0.5 * k as f64, 0.0];
            feed(&mut seq, t, cells);
            seq.on_contacts(&list);
            status = Some(seq.cycle("test").1);
        }
        status.unwrap().arc_blocked(straight)
    };
    assert!(!followed(&[(23.0, 1.0), (24.0, -1.0)]));
    assert!(!followed(&[(14.0, 1.0), (16.0, -1.0)]));
    // ... but a hazard 27 m astern of it, beyond the trail's 20 m and its 4 m half-width, does.
    assert!(followed(&[(5.0, 1.0)]));
}

#[test]
fn a_track_born_close_in_blocks_no_arc_until_it_has_lasted() {
    // A 5.5 x 5 m "boat" born 13 m off the starboard bow (a ghost of glint or of a wake), seen by
    // the sequencer first at 0.2 s, then confirmed; the same blob as a track born 40 m out.
    let at = |position: [f64; 2], age_s: f32| {
        let mut list = boat_contacts(100 * MS, position, [0.0, 0.0]);
        list.contacts[0].extent = [5.5, 5.0, 3.0];
        list.contacts[0].age_s = age_s;
        list
    };
    let blocked_after = |first: ContactList, now: ContactList| {
        let mut seq = started(EAST);
        feed(&mut seq, 100 * MS, &[]);
        seq.on_contacts(&first);
        seq.cycle("test");
        seq.on_contacts(&now);
        seq.cycle("test").1
    };
    let ghost = blocked_after(at([10.0, -8.0], 0.2), at([10.0, -8.0], 0.6));
    assert_eq!(ghost.blocked_arcs, [0, 0]);
    assert_eq!(ghost.mode, command_mode::NAVIGATING);
    // Once it has lasted `late_birth_min_age_s` it blocks like any contact ...
    let lasting = blocked_after(at([10.0, -8.0], 0.2), at([10.0, -8.0], 3.2));
    assert_ne!(lasting.blocked_arcs, [0, 0]);
    // ... and a track born far out blocks from the start.
    let approached = blocked_after(at([40.0, -8.0], 0.2), at([10.0, -8.0], 0.6));
    assert_eq!(approached.blocked_arcs, lasting.blocked_arcs);
}

#[test]
fn a_young_track_that_lost_its_detection_blocks_no_arc_an_old_one_does() {
    // A 2 x 2 m "boat" 20 m dead ahead, coasting (not detected in the latest map) at 4 s old:
    // glint that lost its detection. The same track detected, or coasting at 8 s old (a real boat
    // hidden for a frame), blocks the straight arc.
    let blocked = |coasting: u8, age_s: f32| {
        let mut list = boat_contacts(100 * MS, [20.0, 0.0], [0.0, 0.5]);
        list.contacts[0].extent = [2.0, 2.0, 1.0];
        list.contacts[0].coasting = coasting;
        list.contacts[0].age_s = age_s;
        let mut seq = started(EAST);
        feed(&mut seq, 100 * MS, &[]);
        seq.on_contacts(&list);
        let status = seq.cycle("test").1;
        status.arc_blocked(seq.arcs().nearest(0.0))
    };
    assert!(!blocked(1, 4.0));
    assert!(blocked(0, 4.0));
    assert!(blocked(1, 8.0));
}

#[test]
fn following_the_boat_brakes_astern_only_close_to_the_target() {
    // Following boat #3 heading east at 5 m/s while doing 8 m/s. 18 m behind it (a turning
    // target's lagging track reads it this close) the boat sheds speed by drag; 12 m behind it
    // brakes astern.
    const FOLLOW: &str = "[[step]]\ntype = \"follow\"\ncontact_id = 3\nastern_m = 20.0\n";
    let throttle_at = |range: f64| {
        let mut seq = started(FOLLOW);
        let mut throttle = f32::NAN;
        for k in 1..=10 {
            let t = k * 100 * MS;
            seq.on_ins(&ins(t, 0.0, 8.0)).unwrap();
            let (h, c) = map(t, &[]);
            seq.on_map(&h, &c).unwrap();
            let mut target = boat_contacts(t, [range, 0.0], [5.0, 0.0]);
            target.contacts[0].id = 3;
            seq.on_contacts(&target);
            throttle = seq.cycle("test").0.throttle_pct;
        }
        throttle
    };
    let far = throttle_at(18.0);
    assert!((0.0..10.0).contains(&far), "{far}");
    let close = throttle_at(12.0);
    assert!(close < -10.0, "{close}");
}
