//! Shared by the process tests: the bridge as a child process in a domain of its own, a source
//! that publishes stereo frames, INS and world maps over shared memory, and a Foxglove client.
#![allow(dead_code)]

use futures_util::StreamExt;
use messages::{
    topics, GeodeticOrigin, GridGeometry, Header, InsState, MapCell, PixelEncoding, Pose,
    StereoFrameHeader, WorldMapHeader,
};
use runtime::Ports;
use serde_json::Value;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

pub type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// A running `bridge run`; SIGTERM and domain cleanup on drop.
pub struct Bridge {
    pub child: Child,
    pub domain: String,
    pub dir: std::path::PathBuf,
}

impl Bridge {
    pub fn start(domain: &str, config: &str) -> Self {
        let dir = std::env::temp_dir().join(domain);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bridge.toml");
        std::fs::write(&path, config).unwrap();
        let child = Command::new(env!("CARGO_BIN_EXE_bridge"))
            .args(["run", "--config"])
            .arg(&path)
            .env(runtime::domain::DOMAIN_ENV, domain)
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start bridge");
        Self {
            child,
            domain: domain.into(),
            dir,
        }
    }

    /// SIGTERM, then the exit status.
    pub fn stop(&mut self) -> std::process::ExitStatus {
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
        self.child.wait().unwrap()
    }
}

impl Drop for Bridge {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            self.stop();
        }
        let _ = runtime::cleanup::remove_domain_leftovers(&self.domain);
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Files of `domain` left in /dev/shm.
pub fn leftovers(domain: &str) -> Vec<String> {
    std::fs::read_dir("/dev/shm")
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.contains(domain))
                .collect()
        })
        .unwrap_or_default()
}

/// A port that was free a moment ago.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub const WIDTH: u32 = 640;
pub const HEIGHT: u32 = 480;
pub const GRID: GridGeometry = GridGeometry {
    width: 200,
    height: 100,
    resolution_m: 0.5,
    center: [10.0, 20.0],
};

/// Left-plane pixel of the test pattern; the right plane is all 255.
pub fn pixel(x: usize, y: usize) -> u8 {
    ((x + 2 * y) % 251) as u8
}

pub fn cell(i: usize) -> MapCell {
    MapCell {
        hazard: (i % 7) as u8,
        cost: (i % 11) as u8,
        water: (i % 3) as u8,
        observed: 1,
        max_height_cm: (i % 100) as i16,
        elevation_cm: -((i % 50) as i16),
    }
}

pub const ORIGIN: GeodeticOrigin = GeodeticOrigin {
    latitude_deg: 59.0,
    longitude_deg: 10.0,
    altitude_m: 0.0,
};

/// Publishes a stereo frame (head `hh_left`), an INS sample and a world map every `period` on a
/// thread of its own, until stopped. Stamps are the monotonic clock at publication, so a client
/// on this machine can measure latency.
pub struct Source {
    stop: Arc<AtomicBool>,
    pub frames: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Source {
    pub fn start(period: Duration, with_maps: bool) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let frames = Arc::new(AtomicU64::new(0));
        let (s, f) = (stop.clone(), frames.clone());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || {
            let node = runtime::tool_node("bridge_test_source").unwrap();
            let mut frame_pub = topics::STEREO_FRAME.publisher(&node).unwrap();
            let mut ins_pub = topics::INS.publisher(&node).unwrap();
            let mut map_pub = topics::WORLD_MAP.publisher(&node).unwrap();
            // Frames sent before the bridge subscribes would be lost (INS is subscribed at the same time).
            let end = Instant::now() + Duration::from_secs(20);
            while frame_pub.subscriber_count() == 0
                || (with_maps && map_pub.subscriber_count() == 0)
            {
                assert!(Instant::now() < end, "the bridge did not subscribe");
                std::thread::sleep(Duration::from_millis(20));
            }
            ready_tx.send(()).unwrap();
            let mut next = Instant::now();
            while !s.load(Ordering::Relaxed) {
                let stamp = runtime::clock::monotonic_ns();
                let mut sample = frame_pub.loan_slice(2 * (WIDTH * HEIGHT) as usize).unwrap();
                *sample.user_header_mut() = StereoFrameHeader {
                    hdr: Header::new(frame_pub.next_seq(), stamp, "hh_left"),
                    head: "hh_left".into(),
                    width: WIDTH,
                    height: HEIGHT,
                    stride: WIDTH,
                    encoding: PixelEncoding::Mono8 as u32,
                };
                let payload = sample.payload_mut();
                let (left, right) = payload.split_at_mut((WIDTH * HEIGHT) as usize);
                for (i, p) in left.iter_mut().enumerate() {
                    *p = pixel(i % WIDTH as usize, i / WIDTH as usize);
                }
                right.fill(255);
                frame_pub.send(sample).unwrap();
                f.fetch_add(1, Ordering::Relaxed);
                ins_pub
                    .publish(&InsState {
                        hdr: Header::new(ins_pub.next_seq(), stamp, "ins"),
                        origin: ORIGIN,
                        pose: Pose {
                            position: [100.0, 50.0, 0.0],
                            yaw: 0.5,
                            ..Default::default()
                        },
                        position_sigma: 0.1,
                        ..Default::default()
                    })
                    .unwrap();
                if with_maps {
                    let mut sample = map_pub.loan_slice(GRID.cell_count()).unwrap();
                    *sample.user_header_mut() = WorldMapHeader {
                        hdr: Header::new(map_pub.next_seq(), stamp, "mapper"),
                        grid: GRID,
                        ..Default::default()
                    };
                    for (i, c) in sample.payload_mut().iter_mut().enumerate() {
                        *c = cell(i);
                    }
                    map_pub.send(sample).unwrap();
                }
                next += period;
                if let Some(wait) = next.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
            }
        });
        ready_rx
            .recv_timeout(Duration::from_secs(30))
            .expect("source not ready");
        Self {
            stop,
            frames,
            thread: Some(thread),
        }
    }
}

impl Drop for Source {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Connects as Foxglove does (offering the subprotocol), retrying while the server starts.
pub async fn connect(port: u16) -> Ws {
    let end = Instant::now() + Duration::from_secs(20);
    loop {
        let mut request = format!("ws://127.0.0.1:{port}/")
            .into_client_request()
            .unwrap();
        request.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            "foxglove.websocket.v1".parse().unwrap(),
        );
        match tokio_tungstenite::connect_async(request).await {
            Ok((ws, response)) => {
                assert_eq!(
                    response.headers()["Sec-WebSocket-Protocol"],
                    "foxglove.websocket.v1"
                );
                return ws;
            }
            Err(e) => {
                assert!(Instant::now() < end, "cannot connect: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
    }
}

/// The next message, or a panic after `timeout`.
pub async fn next(ws: &mut Ws, timeout: Duration) -> Message {
    match tokio::time::timeout(timeout, ws.next()).await {
        Ok(Some(Ok(m))) => m,
        other => panic!("no message from the bridge: {other:?}"),
    }
}

pub fn json(m: &Message) -> Value {
    match m {
        Message::Text(t) => serde_json::from_str(t.as_str()).unwrap(),
        other => panic!("expected a text message, got {other:?}"),
    }
}
