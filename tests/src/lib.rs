//! Helpers for end-to-end tests: start `usv up` on a launch file in a domain and run directory of the
//! test's own (so tests never see each other), query it, and clean up whatever happens.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// Directory holding the workspace's binaries (`usv`, services, test helpers): the test executable
/// lives in `<target>/<profile>/deps/`.
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent()
        .and_then(Path::parent)
        .expect("target directory")
        .to_path_buf()
}

/// Path of a workspace binary; panics with a hint if it was not built.
pub fn bin(name: &str) -> PathBuf {
    let path = bin_dir().join(name);
    assert!(
        path.exists(),
        "{} not found: build the workspace first (`cargo build --release --workspace`)",
        path.display()
    );
    path
}

/// Timing-sensitive process tests run one at a time: the machine may have only two cores.
pub use runtime::testing::serial;

/// Polls `f` every 5 ms until it returns `Some` or `timeout` passes.
pub fn wait_for<T>(timeout: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let end = Instant::now() + timeout;
    loop {
        if let Some(v) = f() {
            return Some(v);
        }
        if Instant::now() >= end {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

pub fn pid_alive(pid: u32) -> bool {
    // A zombie has exited; only its parent's wait is missing.
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Ok(stat) => !stat
            .rsplit(')')
            .next()
            .is_some_and(|rest| rest.trim_start().starts_with('Z')),
        Err(_) => false,
    }
}

pub fn kill(pid: u32, signal: libc::c_int) {
    // SAFETY: plain syscall.
    unsafe { libc::kill(pid as libc::pid_t, signal) };
}

/// A process set started with `usv up` for one test.
pub struct RunningSet {
    pub domain: String,
    pub dir: tempfile::TempDir,
    pub supervisor: Child,
}

impl RunningSet {
    /// Writes `launch` (TOML) to a fresh directory and starts `usv up` on it. `{bin}` in the text is
    /// replaced by the binary directory and `{dir}` by the test directory.
    pub fn start(launch: &str) -> Self {
        static COUNTER: AtomicU32 = AtomicU32::new(0);
        let domain = format!(
            "t{}x{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        );
        let dir = tempfile::tempdir().expect("temp dir");
        let text = launch
            .replace("{bin}", &bin_dir().display().to_string())
            .replace("{dir}", &dir.path().display().to_string());
        let file = dir.path().join("set.toml");
        std::fs::write(&file, text).expect("write launch file");
        let supervisor = Self::usv_command(&domain, dir.path())
            .arg("up")
            .arg(&file)
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start usv up");
        let set = Self {
            domain,
            dir,
            supervisor,
        };
        let socket = set.dir.path().join(format!("{}.sock", set.domain));
        wait_for(Duration::from_secs(10), || socket.exists().then_some(()))
            .expect("usv up did not open its control socket");
        set
    }

    fn usv_command(domain: &str, run_dir: &Path) -> Command {
        let mut cmd = Command::new(bin("usv"));
        cmd.env("USV_DOMAIN", domain).env("USV_RUN_DIR", run_dir);
        cmd
    }

    /// Runs `usv <args>` against this set.
    pub fn usv(&self, args: &[&str]) -> Output {
        Self::usv_command(&self.domain, self.dir.path())
            .args(args)
            .output()
            .expect("run usv")
    }

    /// `usv ps --json` as (name -> service object).
    pub fn ps(&self) -> serde_json::Value {
        let out = self.usv(&["ps", "--json"]);
        assert!(
            out.status.success(),
            "usv ps failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("ps json");
        let mut by_name = serde_json::Map::new();
        for s in v["services"].as_array().expect("services") {
            by_name.insert(s["name"].as_str().unwrap().to_string(), s.clone());
        }
        serde_json::Value::Object(by_name)
    }

    pub fn pid_of(&self, service: &str) -> Option<u32> {
        self.ps()[service]["pid"].as_u64().map(|p| p as u32)
    }

    /// Waits until `service` runs with a pid other than `old` and has sent a heartbeat; returns it.
    pub fn wait_new_pid(&self, service: &str, old: u32, timeout: Duration) -> Option<u32> {
        wait_for(timeout, || {
            let ps = self.ps();
            let s = &ps[service];
            let pid = s["pid"].as_u64()? as u32;
            (pid != old).then_some(pid)
        })
    }

    /// Waits until `service` is running and has sent its first heartbeat.
    pub fn wait_running(&self, service: &str, timeout: Duration) -> Option<u32> {
        wait_for(timeout, || {
            let ps = self.ps();
            let s = &ps[service];
            (s["heartbeat_age_ms"].is_u64()).then(|| s["pid"].as_u64().map(|p| p as u32))?
        })
    }

    /// `usv down`, then waits for `usv up` to exit; returns its success.
    pub fn down(&mut self) -> bool {
        let out = self.usv(&["down"]);
        assert!(
            out.status.success(),
            "usv down failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let status = wait_for(Duration::from_secs(15), || {
            self.supervisor.try_wait().ok().flatten()
        })
        .expect("usv up did not exit after usv down");
        status.success()
    }

    /// iceoryx2 files of this set's domain still on the machine.
    pub fn leftover_files(&self) -> Vec<PathBuf> {
        let prefix = runtime::domain::file_prefix(Some(&self.domain));
        let mut found = Vec::new();
        for dir in [
            "/dev/shm",
            "/tmp/iceoryx2",
            "/tmp/iceoryx2/services",
            "/tmp/iceoryx2/nodes",
        ] {
            let Ok(entries) = std::fs::read_dir(dir) else {
                continue;
            };
            for e in entries.flatten() {
                if e.file_name().to_string_lossy().starts_with(&prefix) {
                    found.push(e.path());
                }
            }
        }
        found
    }
}

impl Drop for RunningSet {
    fn drop(&mut self) {
        if self.supervisor.try_wait().ok().flatten().is_none() {
            // Children die with the supervisor (PR_SET_PDEATHSIG).
            let _ = self.supervisor.kill();
            let _ = self.supervisor.wait();
            std::thread::sleep(Duration::from_millis(100));
        }
        let config = runtime::domain::config_for(Some(&self.domain)).expect("domain config");
        runtime::cleanup::sweep_dead_nodes(&config);
        let _ = runtime::cleanup::remove_domain_leftovers(&self.domain);
    }
}

/// One line written by `test-listener`.
#[derive(Debug, Clone, Copy)]
pub struct Received {
    pub pid: u32,
    pub seq: u64,
    pub stamp_ns: u64,
    pub tag: f64,
    pub received_ns: u64,
}

pub fn read_received(path: &Path) -> Vec<Received> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines()
        .filter_map(|line| {
            let f: Vec<_> = line.split_whitespace().collect();
            Some(Received {
                pid: f.first()?.parse().ok()?,
                seq: f.get(1)?.parse().ok()?,
                stamp_ns: f.get(2)?.parse().ok()?,
                tag: f.get(3)?.parse().ok()?,
                received_ns: f.get(4)?.parse().ok()?,
            })
        })
        .collect()
}
