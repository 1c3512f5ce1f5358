//! The supervisor with real processes over real shared memory: crashes, hangs, swaps, its own death,
//! clean shutdown and bad launch files.

use std::time::{Duration, Instant};
use tests::*;

const PIPELINE: &str = r#"
name = "pipeline"
heartbeat_timeout_ms = 600
stop_grace_ms = 1000

[[service]]
name = "talker"
program = "{bin}/test-talker"
args = ["--rate-hz", "100", "--tag", "1"]
restart = "always"

[[service]]
name = "listener"
program = "{bin}/test-listener"
args = ["--out", "{dir}/received.txt"]
depends_on = ["talker"]
"#;

fn received(set: &RunningSet) -> Vec<Received> {
    read_received(&set.dir.path().join("received.txt"))
}

/// Waits until the listener has logged a sample that satisfies `pred`.
fn wait_received(set: &RunningSet, timeout: Duration, pred: impl Fn(&Received) -> bool) -> bool {
    wait_for(timeout, || received(set).iter().any(&pred).then_some(())).is_some()
}

fn start_pipeline() -> RunningSet {
    let set = RunningSet::start(PIPELINE);
    set.wait_running("talker", Duration::from_secs(10))
        .expect("talker up");
    set.wait_running("listener", Duration::from_secs(10))
        .expect("listener up");
    assert!(
        wait_received(&set, Duration::from_secs(5), |_| true),
        "no data flowed"
    );
    set
}

#[test]
fn killed_publisher_then_subscriber_are_restarted_within_500ms_and_data_flows_again() {
    let _serial = serial();
    let mut set = start_pipeline();

    for service in ["talker", "listener"] {
        let old = set.pid_of(service).unwrap();
        let killed_at = Instant::now();
        let killed_ns = runtime::clock::monotonic_ns();
        kill(old, libc::SIGKILL);
        let new = set
            .wait_new_pid(service, old, Duration::from_secs(5))
            .unwrap_or_else(|| panic!("{service} was not restarted"));
        let restart = killed_at.elapsed();
        assert!(
            restart <= Duration::from_millis(500),
            "{service} restarted after {restart:?}"
        );
        // New samples, published after the kill, reach a listener again.
        let flows = wait_received(&set, Duration::from_secs(5), |r| {
            r.stamp_ns > killed_ns && r.received_ns > killed_ns + 50_000_000
        });
        assert!(flows, "no data after {service} was restarted (pid {new})");
        assert_eq!(set.ps()[service]["restarts"].as_u64(), Some(1));
    }
    assert!(set.down());
}

#[test]
fn stopped_service_is_killed_after_heartbeat_timeout_and_restarted() {
    let _serial = serial();
    let mut set = start_pipeline();
    let old = set.pid_of("talker").unwrap();
    let stopped_at = Instant::now();
    kill(old, libc::SIGSTOP);
    let new = set
        .wait_new_pid("talker", old, Duration::from_secs(5))
        .expect("hung talker was not replaced");
    let took = stopped_at.elapsed();
    // 600 ms heartbeat timeout, plus up to one heartbeat period of slack and the restart.
    assert!(
        took >= Duration::from_millis(500) && took <= Duration::from_millis(1500),
        "replaced after {took:?}"
    );
    assert!(!pid_alive(old), "the stopped process is still there");
    let after = runtime::clock::monotonic_ns();
    assert!(
        wait_received(&set, Duration::from_secs(5), |r| r.stamp_ns > after),
        "no data from the restarted talker (pid {new})"
    );
    assert!(set.down());
}

#[test]
fn swap_under_load_interrupts_the_stream_at_most_once_and_loses_nothing() {
    let _serial = serial();
    let mut set = start_pipeline();
    std::thread::sleep(Duration::from_millis(300));
    let talker = tests::bin("test-talker").display().to_string();
    let out = set.usv(&[
        "swap",
        "talker",
        "--exec",
        &talker,
        "--rate-hz",
        "100",
        "--tag",
        "2",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        wait_received(&set, Duration::from_secs(5), |r| r.tag == 2.0),
        "no data from the swapped-in program"
    );
    std::thread::sleep(Duration::from_millis(300));
    let rx = received(&set);
    let listener_pids: std::collections::BTreeSet<_> = rx.iter().map(|r| r.pid).collect();
    assert_eq!(listener_pids.len(), 1, "the listener was disturbed");
    // Samples from the old program, then only from the new one, each without a hole: the swap
    // interrupts the stream once, where the programs change hands, and loses nothing. A sample
    // merely late (a loaded 2-core machine stalls a process for 60 ms now and then) is no loss.
    let first_new = rx.iter().position(|r| r.tag == 2.0).unwrap();
    assert!(rx[first_new..].iter().all(|r| r.tag == 2.0));
    for part in [&rx[..first_new], &rx[first_new..]] {
        let holes: Vec<_> = part
            .windows(2)
            .filter(|w| w[1].seq != w[0].seq + 1)
            .map(|w| (w[0].seq, w[1].seq))
            .collect();
        assert!(holes.is_empty(), "samples lost: {holes:?}");
    }
    // Gaps between consecutive arrivals, at 100 Hz nominal.
    let worst = rx
        .windows(2)
        .map(|w| w[1].received_ns.saturating_sub(w[0].received_ns))
        .max()
        .unwrap_or(0);
    assert!(worst < 1_000_000_000, "gap of {worst} ns during the swap");
    assert!(set.down());
}

#[test]
fn sigkill_of_the_supervisor_leaves_no_child() {
    let _serial = serial();
    let mut set = start_pipeline();
    let children = [
        set.pid_of("talker").unwrap(),
        set.pid_of("listener").unwrap(),
    ];
    set.supervisor.kill().unwrap();
    set.supervisor.wait().unwrap();
    let gone = wait_for(Duration::from_secs(2), || {
        children.iter().all(|&p| !pid_alive(p)).then_some(())
    });
    assert!(
        gone.is_some(),
        "children outlived the supervisor: {children:?}"
    );
}

#[test]
fn down_stops_everything_and_leaves_no_shared_memory() {
    let _serial = serial();
    let mut set = start_pipeline();
    let children = [
        set.pid_of("talker").unwrap(),
        set.pid_of("listener").unwrap(),
    ];
    assert!(
        !set.leftover_files().is_empty(),
        "the set uses no shared memory?"
    );
    assert!(set.down(), "usv up did not exit cleanly");
    assert!(children.iter().all(|&p| !pid_alive(p)));
    assert_eq!(set.leftover_files(), Vec::<std::path::PathBuf>::new());
}

#[test]
fn inspection_tools_see_a_running_set() {
    let _serial = serial();
    let mut set = start_pipeline();
    let topics = String::from_utf8(set.usv(&["topics"]).stdout).unwrap();
    assert!(topics.contains("usv/sensors/ins"), "{topics}");
    assert!(topics.contains("usv/health/heartbeat"), "{topics}");

    let out = set.usv(&["hz", "usv/sensors/ins", "--duration", "2", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let hz: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rate = hz["rate_hz"].as_f64().expect("a rate");
    assert!(
        (80.0..=120.0).contains(&rate),
        "rate {rate} Hz, expected ~100"
    );

    let out = set.usv(&["echo", "usv/sensors/ins", "--count", "3"]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(
        text.lines().filter(|l| l.contains("seq=")).count(),
        3,
        "{text}"
    );

    let ps = set.ps();
    let rate = ps["listener"]["input_rate_hz"].as_f64().unwrap_or(0.0);
    assert!((50.0..=150.0).contains(&rate), "listener input rate {rate}");
    let out = set.usv(&["hz", "usv/no/such/topic", "--duration", "0.1"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown topic"));
    assert!(set.down());
}

#[test]
fn malformed_launch_files_are_refused_and_start_nothing() {
    let _serial = serial();
    let dir = tempfile::tempdir().unwrap();
    let marker = dir.path().join("talker-ran");
    let talker = format!(
        "[[service]]\nname = \"talker\"\nprogram = \"{}\"\nargs = [\"--touch\", \"{}\"]\n",
        bin("test-talker").display(),
        marker.display()
    );
    let cases = [
        (
            format!("{talker}[[service]]\nname = \"b\"\nprogram = \"/bin/true\"\nrestart_policy = \"never\"\n"),
            vec!["restart_policy", "line 8"],
        ),
        (
            format!("{talker}[[service]]\nname = \"b\"\nprogram = \"no-such-program-here\"\n"),
            vec!["'b'", "no-such-program-here", "not found"],
        ),
        (
            format!("{talker}[[service]]\nname = \"b\"\nprogram = \"/bin/true\"\ndepends_on = [\"c\"]\n[[service]]\nname = \"c\"\nprogram = \"/bin/true\"\ndepends_on = [\"b\"]\n"),
            vec!["cycle", "b, c"],
        ),
        (
            format!("{talker}[[service]]\nname = \"talker\"\nprogram = \"/bin/true\"\n"),
            vec!["'talker'", "duplicate"],
        ),
    ];
    for (i, (text, expected)) in cases.iter().enumerate() {
        let file = dir.path().join(format!("bad{i}.toml"));
        std::fs::write(&file, text).unwrap();
        let out = std::process::Command::new(bin("usv"))
            .env("USV_DOMAIN", format!("bad{}x{i}", std::process::id()))
            .env("USV_RUN_DIR", dir.path())
            .arg("up")
            .arg(&file)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "case {i} was accepted");
        for word in expected {
            assert!(err.contains(word), "case {i}: {word:?} not in {err:?}");
        }
        assert!(!marker.exists(), "case {i} started a service");
    }
}
