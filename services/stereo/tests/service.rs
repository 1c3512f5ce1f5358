//! The stereo service as a process: bad input is rejected and reported in its heartbeat, and the
//! process keeps running.

use messages::{topics, Header, Heartbeat, Name, PixelEncoding, StereoFrameHeader};
use runtime::Ports;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

const CALIB: &str = "width = 64\nheight = 48\nrotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\ntranslation = [-0.5, 0.0, 0.0]\n[left]\nfx = 50.0\nfy = 50.0\ncx = 31.5\ncy = 23.5\n[right]\nfx = 50.0\nfy = 50.0\ncx = 31.5\ncy = 23.5\n";

struct Stereo {
    child: Child,
    domain: String,
    _dir: tempfile::TempDir,
}

impl Stereo {
    fn start(domain: &str, calibration: &str) -> Self {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("calib.toml"), calibration).unwrap();
        let config = dir.path().join("stereo.toml");
        std::fs::write(
            &config,
            "head = \"front\"\ncalibration = \"calib.toml\"\n[matcher]\nalgo = \"bm\"\nnum_disparities = 16\nblock_size = 5\n",
        )
        .unwrap();
        std::env::set_var(runtime::domain::DOMAIN_ENV, domain);
        let child = Command::new(env!("CARGO_BIN_EXE_stereo"))
            .args(["run", "--config"])
            .arg(&config)
            .env(runtime::domain::DOMAIN_ENV, domain)
            .spawn()
            .unwrap();
        Self {
            child,
            domain: domain.to_string(),
            _dir: dir,
        }
    }
}

impl Drop for Stereo {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let config = runtime::domain::config_for(Some(&self.domain)).unwrap();
        runtime::cleanup::sweep_dead_nodes(&config);
        // Here, not after the test's last assert, so a failing test leaves nothing either (the
        // test's own node is gone by then: it lives in `send_and_watch`).
        let _ = runtime::cleanup::remove_domain_leftovers(&self.domain);
    }
}

/// Publishes one frame of the given size and waits for a heartbeat of `stereo` that satisfies `done`.
fn send_and_watch(width: u32, height: u32, done: impl Fn(&Heartbeat) -> bool) -> Option<Heartbeat> {
    let node = runtime::tool_node("stereo-test").unwrap();
    let mut frames = topics::STEREO_FRAME.publisher(&node).unwrap();
    let beats = topics::HEARTBEAT.subscriber(&node).unwrap();
    let end = Instant::now() + Duration::from_secs(20);
    let mut k = 0u64;
    while Instant::now() < end {
        // Repeat until the service is connected and has answered.
        let mut sample = frames.loan_slice(2 * (width * height) as usize).unwrap();
        sample.payload_mut().fill(100);
        *sample.user_header_mut() = StereoFrameHeader {
            hdr: Header::new(k, 1_000_000_000 + k, "test"),
            head: Name::new("front"),
            width,
            height,
            stride: width,
            encoding: PixelEncoding::Mono8 as u32,
        };
        frames.send(sample).unwrap();
        k += 1;
        std::thread::sleep(Duration::from_millis(100));
        while let Some(s) = beats.receive().unwrap() {
            let b = *s.payload();
            if b.hdr.source.as_str() == "stereo" && done(&b) {
                return Some(b);
            }
        }
    }
    None
}

#[test]
fn wrong_frame_size_is_rejected_and_reported_and_the_service_stays_up() {
    // The tests share this process's domain setting (the tool node reads it): one at a time.
    let _serial = runtime::testing::serial();
    let domain = format!("stereo{}a", std::process::id());
    let mut stereo = Stereo::start(&domain, CALIB);
    let beat = send_and_watch(32, 24, |b| b.rejected > 0).expect("no rejection reported");
    assert!(
        beat.last_error
            .as_str()
            .contains("is 32x24, calibration is 64x48"),
        "{}",
        beat.last_error
    );
    // A frame of the right size is processed afterwards by the same process.
    let beat = send_and_watch(64, 48, |b| b.processed > 0).expect("a good frame was not processed");
    assert_eq!(beat.pid, stereo.child.id());
    assert!(stereo.child.try_wait().unwrap().is_none());
}

#[test]
fn invalid_calibration_keeps_the_service_up_and_reports_the_fault() {
    let _serial = runtime::testing::serial();
    let domain = format!("stereo{}b", std::process::id());
    let broken = CALIB.replace("fx = 50.0\nfy", "fx = -1.0\nfy");
    let mut stereo = Stereo::start(&domain, &broken);
    let beat = send_and_watch(64, 48, |b| b.rejected > 0).expect("no fault reported");
    assert!(
        beat.last_error.as_str().contains("calibration"),
        "{}",
        beat.last_error
    );
    assert!(
        stereo.child.try_wait().unwrap().is_none(),
        "the service exited"
    );
}
