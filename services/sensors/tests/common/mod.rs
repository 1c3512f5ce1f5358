//! Shared by the recorder's and the sensors' process tests: a domain of the test's own, a node in it,
//! known messages on several topics, and running the recorder.
#![allow(dead_code)]

use messages::iceoryx2::prelude::*;
use messages::*;
use runtime::{Ports, Publisher};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// Tests that run the recorder run one at a time: they expect exact message counts through the
/// topics' shallow subscriber buffers, and two recorders at once on two cores make a stall likelier.
pub use runtime::testing::serial;

/// A domain for one test, cleaned up on drop.
pub struct Domain {
    pub name: String,
    node: Option<Node<ipc::Service>>,
}

impl Domain {
    pub fn new() -> Self {
        static COUNTER: AtomicU32 = AtomicU32::new(0);
        let name = format!(
            "rec{}x{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        );
        runtime::domain::quiet_iceoryx_logs();
        let node = NodeBuilder::new()
            .name(&"test".try_into().unwrap())
            .config(&runtime::domain::config_for(Some(&name)).unwrap())
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .unwrap();
        Self {
            name,
            node: Some(node),
        }
    }

    pub fn node(&self) -> &Node<ipc::Service> {
        self.node.as_ref().expect("node lives until drop")
    }

    pub fn command(&self, program: &Path) -> Command {
        let mut cmd = Command::new(program);
        cmd.env("USV_DOMAIN", &self.name).env("USV_LOG", "warn");
        cmd
    }
}

impl Drop for Domain {
    fn drop(&mut self) {
        // The node must be gone before the domain counts as empty.
        self.node.take();
        let config = runtime::domain::config_for(Some(&self.name)).unwrap();
        runtime::cleanup::sweep_dead_nodes(&config);
        let _ = runtime::cleanup::remove_domain_leftovers(&self.name);
    }
}

/// A workspace binary next to the test executable (`<target>/<profile>/`).
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let path = exe.parent().and_then(Path::parent).unwrap().join(name);
    assert!(
        path.exists(),
        "{} not built: run `cargo test -p recorder -p sensors`",
        path.display()
    );
    path
}

pub fn wait_for(timeout: Duration, mut f: impl FnMut() -> bool) -> bool {
    let end = Instant::now() + timeout;
    while Instant::now() < end {
        if f() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    false
}

pub fn signal(child: &Child, sig: i32) {
    // SAFETY: plain syscall on our own child.
    unsafe { libc::kill(child.id() as i32, sig) };
}

/// Topics the tests publish on.
pub const TOPICS: [&str; 4] = [
    topics::STEREO_FRAME.name,
    topics::INS.name,
    topics::CONTACTS.name,
    topics::LOCAL_MAP.name,
];

pub fn stereo(seq: u64) -> (StereoFrameHeader, Vec<u8>) {
    let h = StereoFrameHeader {
        hdr: Header::new(seq, 1_000_000 + seq * 100_000_000, "port"),
        head: Name::new("port"),
        width: 64,
        height: 48,
        stride: 64,
        encoding: PixelEncoding::Mono8 as u32,
    };
    (
        h,
        (0..h.payload_len())
            .map(|i| (i as u64 * 31 + seq * 7) as u8)
            .collect(),
    )
}

pub fn ins(seq: u64) -> InsState {
    let mut s = InsState {
        hdr: Header::new(seq, 1_000_000 + seq * 20_000_000, "ins"),
        ..Default::default()
    };
    s.origin.latitude_deg = 47.0;
    s.pose.position = [seq as f64, 2.0 * seq as f64, 0.1];
    s.pose.yaw = 0.01 * seq as f64;
    s
}

pub fn contacts(seq: u64) -> ContactList {
    let mut c = ContactList {
        hdr: Header::new(seq, 1_000_000 + seq * 100_000_000, "tracker"),
        count: 2,
        ..Default::default()
    };
    c.contacts[0].id = 7;
    c.contacts[0].position = [seq as f64, 3.0];
    c.contacts[1].id = 9;
    c
}

pub fn local_map(seq: u64) -> (LocalMapHeader, Vec<MapCell>) {
    let h = LocalMapHeader {
        hdr: Header::new(seq, 1_000_000 + seq * 100_000_000, "perception"),
        frame_seq: seq,
        grid: GridGeometry {
            width: 20,
            height: 10,
            resolution_m: 0.5,
            center: [1.0, 2.0],
        },
        ..Default::default()
    };
    let cells = (0..200)
        .map(|i| MapCell {
            hazard: (i + seq as usize) as u8,
            cost: 3,
            ..Default::default()
        })
        .collect();
    (h, cells)
}

/// Publishers of the test topics.
pub struct Sender {
    pub stereo: Publisher<[u8], StereoFrameHeader>,
    pub ins: Publisher<InsState, ()>,
    pub contacts: Publisher<ContactList, ()>,
    pub map: Publisher<[MapCell], LocalMapHeader>,
}

/// How many messages per topic [`Sender::send_all`] publishes.
pub const COUNTS: [u64; 4] = [10, 50, 10, 5];

impl Sender {
    pub fn new(d: &Domain) -> Self {
        Self {
            stereo: topics::STEREO_FRAME.publisher(d.node()).unwrap(),
            ins: topics::INS.publisher(d.node()).unwrap(),
            contacts: topics::CONTACTS.publisher(d.node()).unwrap(),
            map: topics::LOCAL_MAP.publisher(d.node()).unwrap(),
        }
    }

    /// Waits until `n` subscribers (the recorder, ...) are connected to every topic.
    pub fn wait_subscribers(&self, n: usize) -> bool {
        wait_for(Duration::from_secs(15), || {
            self.stereo.subscriber_count() >= n
                && self.ins.subscriber_count() >= n
                && self.contacts.subscriber_count() >= n
                && self.map.subscriber_count() >= n
        })
    }

    /// Publishes [`COUNTS`] messages, interleaved, 10 ms apart.
    pub fn send_all(&mut self) {
        for k in 0..50u64 {
            self.ins.publish(&ins(k)).unwrap();
            if k % 5 == 0 {
                let s = k / 5;
                let (h, p) = stereo(s);
                let mut sample = self.stereo.loan_slice(p.len()).unwrap();
                *sample.user_header_mut() = h;
                sample.payload_mut().copy_from_slice(&p);
                self.stereo.send(sample).unwrap();
                self.contacts.publish(&contacts(s)).unwrap();
                if s % 2 == 0 {
                    let (h, cells) = local_map(s / 2);
                    let mut sample = self.map.loan_slice(cells.len()).unwrap();
                    *sample.user_header_mut() = h;
                    sample.payload_mut().copy_from_slice(&cells);
                    self.map.send(sample).unwrap();
                }
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

/// Starts the recorder on the test topics; returns it once it is subscribed to all of them.
pub fn start_recorder(d: &Domain, sender: &Sender, out: &Path, extra: &[&str]) -> Child {
    let child = d
        .command(&bin("recorder"))
        .arg("--out")
        .arg(out)
        .arg("--topics")
        .arg(TOPICS.join(","))
        .arg("--json")
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start recorder");
    assert!(sender.wait_subscribers(1), "recorder did not subscribe");
    child
}

/// SIGTERM, wait, and the recorder's JSON report.
pub fn stop_recorder(child: Child) -> serde_json::Value {
    signal(&child, libc::SIGTERM);
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "recorder failed: {:?}", out.status);
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.lines().last().expect("report line")).expect("report json")
}

/// Checks the report's counts: every message of [`COUNTS`], no drops.
pub fn check_report(report: &serde_json::Value) {
    assert_eq!(report["finished"], true);
    for (topic, want) in TOPICS.iter().zip(COUNTS) {
        let t = report["topics"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["topic"] == *topic)
            .unwrap();
        assert_eq!(t["messages"], want, "{topic}: {report}");
        assert_eq!(t["dropped"], 0, "{topic}: {report}");
    }
}
