//! The `usv` binary as a user meets it (this test also makes `cargo test` build `usv` for the
//! end-to-end tests in `tests/`).

use std::process::Command;

fn usv() -> Command {
    Command::new(env!("CARGO_BIN_EXE_usv"))
}

#[test]
fn commands_without_a_running_set_say_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = usv()
        .env("USV_RUN_DIR", dir.path())
        .args(["--domain", "nobody-here", "ps"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no process set is running in domain 'nobody-here'"),
        "{err}"
    );
}

#[test]
fn unknown_benchmark_lists_the_available_ones() {
    let out = usv().args(["bench", "nope"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("available: ipc, recorder, sim"));
}

#[test]
fn invalid_domain_is_refused() {
    let out = usv().args(["--domain", "a/b", "ps"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("invalid domain"));
}

#[test]
fn ipc_benchmark_prints_every_figure_as_json_and_cleans_up() {
    let out = usv()
        .args(["bench", "ipc", "--quick", "--json"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let figures: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object per line"))
        .collect();
    let find = |name: &str, wake: &str, size: u64| {
        figures
            .iter()
            .find(|f| f["figure"] == name && f["wake"] == wake && f["size_bytes"] == size)
            .and_then(|f| f["value"].as_f64())
            .unwrap_or_else(|| panic!("missing {name} {wake} {size}"))
    };
    for size in [64, 2_457_600, 10_485_760] {
        for wake in ["busy", "waitset"] {
            let p50 = find("latency_p50_us", wake, size);
            let p99 = find("latency_p99_us", wake, size);
            assert!(
                p50 > 0.0 && p50 <= p99,
                "{wake} {size}: p50 {p50} p99 {p99}"
            );
        }
    }
    let uds = find("latency_p50_us", "uds", 2_457_600);
    let shm = find("latency_p50_us", "busy", 2_457_600);
    // Zero copy must beat copying 2.4 MB through the kernel even on a loaded machine.
    assert!(uds > 5.0 * shm, "uds {uds} us vs shm {shm} us");
    let leftovers: Vec<_> = std::fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with("iox2_usv_bench")
        })
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
