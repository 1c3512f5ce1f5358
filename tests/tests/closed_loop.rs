//! The whole stack in closed loop on the simulator, through `usv` exactly as a user runs it: short
//! versions of the `usv eval --closed-loop` scenarios, the chaos run, and the replay regression test.
//! Longer scenario runs are `#[ignore]`d: `cargo test --release --workspace -- --ignored`.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use tests::{bin, serial};

fn checkout() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
        .to_path_buf()
}

fn scenario(name: &str) -> String {
    checkout()
        .join("services/sim/scenarios")
        .join(format!("{name}.toml"))
        .display()
        .to_string()
}

/// `usv eval <args> --json` in a scratch directory; the report of the one scenario.
fn eval(args: &[&str]) -> Value {
    let out_dir = tempfile::tempdir().expect("temp dir");
    let out = Command::new(bin("usv"))
        // Not "run by cargo": the test already built every program, usv must not build again.
        .env_remove("CARGO")
        // usv finds the services' configurations (launch/sets/) in the checkout it runs in.
        .current_dir(checkout())
        .arg("eval")
        .args(args)
        .args(["--json", "--out"])
        .arg(out_dir.path())
        .output()
        .expect("run usv eval");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "usv eval failed\nstdout:\n{stdout}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_str(stdout.lines().last().unwrap_or_default())
        .unwrap_or_else(|e| panic!("no JSON report ({e}):\n{stdout}"));
    eprintln!("{report:#}");
    report
}

/// `usv eval --closed-loop` of a scenario with the test-sized heads (640x480, 5 frames/s).
fn closed_loop(name: &str, duration_s: &str, extra: &[&str]) -> Value {
    let scenario = scenario(name);
    let mut args = vec![
        scenario.as_str(),
        "--closed-loop",
        "--duration",
        duration_s,
        "--head-scale",
        "0.5",
        "--camera-rate",
        "5",
    ];
    args.extend_from_slice(extra);
    eval(&args)
}

/// Smallest clearance (m) to the scenario's obstacles of `class` (truth class name).
fn clearance_to(r: &Value, class: &str) -> f64 {
    r["behaviour"]["approaches"]
        .as_array()
        .expect("approaches")
        .iter()
        .filter(|a| a["class"] == class)
        .filter_map(|a| a["clearance_m"].as_f64())
        .fold(f64::INFINITY, f64::min)
}

/// The whole pipeline worked: maps, commands traceable to camera frames, no service errors.
fn assert_working(r: &Value) {
    let b = &r["behaviour"];
    assert!(b["commands"].as_u64().unwrap_or(0) > 0, "no commands");
    assert!(b["world_maps"].as_u64().unwrap_or(0) > 0, "no world maps");
    assert!(
        b["camera_to_command_ms"]["p50"].is_number(),
        "no command could be traced back to its camera frame"
    );
    for s in r["services"].as_array().expect("services") {
        assert_eq!(s["errors"], 0, "service errors: {s}");
    }
}

#[test]
fn open_water_crossing_closed_loop_runs_the_whole_stack_and_keeps_clear_of_the_buoys() {
    let _guard = serial();
    let r = closed_loop("open_water_crossing", "20", &[]);
    assert_working(&r);
    // The buoys lie 25 m to starboard of the track 90 m out and 260 m out: the boat keeps well
    // clear of them.
    let buoys = clearance_to(&r, "buoy");
    assert!(buoys > 5.0, "too close to a buoy: {buoys} m");
    let contacts = r["behaviour"]["confirmed_contacts"]
        .as_array()
        .expect("contacts");
    assert!(
        !contacts.is_empty(),
        "the tracker confirmed no contact in 20 s with a boat and buoys ahead"
    );
}

/// The crossing boat cuts across the mission's track: the sequencer predicts it along its tracked
/// velocity and keeps clear of where it will be, for the whole 40 s scenario.
#[test]
fn crossing_boat_is_avoided() {
    let _guard = serial();
    let r = closed_loop("open_water_crossing", "40", &[]);
    assert_working(&r);
    assert_eq!(r["behaviour"]["collision"], false, "{:#}", r["behaviour"]);
    let boat = clearance_to(&r, "boat");
    assert!(
        boat.is_finite(),
        "no clearance to the crossing boat was measured"
    );
    assert!(boat > 5.0, "too close to the crossing boat: {boat} m");
}

#[test]
fn chaos_kills_and_a_hung_perception_leave_the_boat_safe_and_the_log_complete() {
    let _guard = serial();
    let r = closed_loop(
        "open_water_crossing",
        "20",
        &["--chaos", "7", "--record", "--lockstep-timeout-ms", "500"],
    );
    let buoys = clearance_to(&r, "buoy");
    assert!(buoys > 5.0, "too close to a buoy under chaos: {buoys} m");
    let chaos = &r["chaos"];
    assert!(
        chaos["kills"].as_u64().unwrap() >= 3,
        "too few kills: {chaos:#}"
    );
    assert_eq!(chaos["not_recovered"], 0, "{chaos:#}");
    // Recovery is measured to the new process's first heartbeat, which perception sends only
    // after loading its model, with the whole stack running on the test machine's two cores:
    // 107-291 ms in the chaos runs (README), so 2 s is a fault, not load.
    let worst = chaos["max_recovery_ms"].as_f64().expect("recovery times");
    assert!(
        worst <= 2000.0,
        "a killed service took {worst} ms to come back: {chaos:#}"
    );
    let hang = &chaos["hang"];
    assert!(
        hang["safe_stop_commands"].as_u64().unwrap_or(0) > 0,
        "no safe stop while perception hung: {hang:#}"
    );
    assert!(
        hang["recovered_ms"].is_number(),
        "perception not replaced: {hang:#}"
    );
    assert_eq!(
        r["recording"]["complete"], true,
        "the recorder lost messages of the simulator: {:#}",
        r["recording"]
    );
}

#[test]
fn replayed_recording_gives_the_committed_outputs() {
    let _guard = serial();
    let dir = checkout().join("tests/data/replay");
    let out = Command::new(bin("usv"))
        .env_remove("CARGO")
        .current_dir(checkout())
        .arg("regress")
        .arg(&dir)
        .output()
        .expect("run usv regress");
    assert!(
        out.status.success(),
        "usv regress failed\nstdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn bridge_pylon_passage_closed_loop() {
    let _guard = serial();
    let r = closed_loop("bridge_pylons", "50", &[]);
    assert_working(&r);
    assert!(clearance_to(&r, "pylon") > 2.0, "{:#}", r["behaviour"]);
    assert!(r["behaviour"]["waypoints_reached"].as_u64().unwrap() >= 1);
}

/// The buoy field: a 90 m river between wooded banks, three buoys, moored boats and traffic. Every
/// 40 m arc meets a bank or a contact whenever the boat points across the river, so this run
/// exercises the slow-down along an arc free close in; before it, the boat turned into buoy 2.
#[test]
fn cluttered_river_buoy_field_closed_loop() {
    let _guard = serial();
    let r = closed_loop("cluttered_river", "60", &[]);
    assert_working(&r);
    assert_eq!(r["behaviour"]["collision"], false, "{:#}", r["behaviour"]);
    let buoys = clearance_to(&r, "buoy");
    assert!(buoys > 2.0, "too close to a buoy: {buoys} m");
    assert!(r["behaviour"]["waypoints_reached"].as_u64().unwrap() >= 1);
}
