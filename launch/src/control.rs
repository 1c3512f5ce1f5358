//! The supervisor's control channel: one JSON request and one JSON reply per connection over a Unix
//! socket in the run directory, one socket per domain. `usv ps|restart|swap|down` are its clients.

use serde::{Deserialize, Serialize};
use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "cmd", rename_all = "kebab-case")]
pub enum Request {
    Ps,
    Restart {
        service: String,
    },
    Swap {
        service: String,
        program: String,
        args: Vec<String>,
    },
    Down,
}

/// One row of `usv ps`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ServiceStatus {
    pub name: String,
    pub pid: Option<u32>,
    pub state: String,
    pub restarts: u32,
    pub heartbeat_age_ms: Option<u64>,
    /// Inputs processed per second over the last few seconds (from heartbeats).
    pub input_rate_hz: Option<f64>,
    pub processed: u64,
    pub rejected: u64,
    pub errors: u64,
    /// Processing time of the last input and the worst so far (us), from heartbeats.
    pub last_processing_us: Option<u32>,
    pub max_processing_us: Option<u32>,
    pub last_error: String,
    pub program: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "reply", rename_all = "kebab-case")]
pub enum Reply {
    Ok {
        message: String,
    },
    Ps {
        set: String,
        services: Vec<ServiceStatus>,
    },
    Error {
        message: String,
    },
}

/// A request from a client, the channel its reply goes back on, and a signal that the reply was
/// written (the supervisor waits for it before exiting after `down`).
pub struct Envelope {
    pub request: Request,
    pub reply: mpsc::Sender<Reply>,
    pub written: mpsc::Receiver<()>,
}

/// Directory of the control sockets: `$USV_RUN_DIR`, or `/tmp/usv`.
pub fn run_dir() -> PathBuf {
    std::env::var_os("USV_RUN_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/tmp/usv"))
}

pub fn socket_path(domain: Option<&str>) -> PathBuf {
    run_dir().join(format!("{}.sock", domain.unwrap_or("default")))
}

/// Binds the control socket; refuses if a live supervisor already owns it.
pub fn bind(domain: Option<&str>) -> anyhow::Result<(UnixListener, PathBuf)> {
    let path = socket_path(domain);
    std::fs::create_dir_all(run_dir())?;
    if UnixStream::connect(&path).is_ok() {
        anyhow::bail!(
            "a process set is already running in domain '{}' (socket {}); stop it with `usv down` or use --domain",
            domain.unwrap_or("default"),
            path.display()
        );
    }
    let _ = std::fs::remove_file(&path);
    let listener = UnixListener::bind(&path)
        .map_err(|e| anyhow::anyhow!("cannot bind control socket {}: {e}", path.display()))?;
    Ok((listener, path))
}

/// Accepts connections forever, forwarding each request to the supervisor loop.
pub fn serve(listener: UnixListener, to_supervisor: mpsc::Sender<Envelope>) {
    for stream in listener.incoming().flatten() {
        let to_supervisor = to_supervisor.clone();
        std::thread::spawn(move || {
            let _ = handle(stream, &to_supervisor);
        });
    }
}

fn handle(stream: UnixStream, to_supervisor: &mpsc::Sender<Envelope>) -> anyhow::Result<()> {
    let mut line = String::new();
    BufReader::new(&stream).read_line(&mut line)?;
    let (written_tx, written) = mpsc::channel();
    let reply = match serde_json::from_str::<Request>(&line) {
        Ok(request) => {
            let (reply, rx) = mpsc::channel();
            to_supervisor
                .send(Envelope {
                    request,
                    reply,
                    written,
                })
                .map_err(|_| anyhow::anyhow!("supervisor loop is gone"))?;
            rx.recv()?
        }
        Err(e) => Reply::Error {
            message: format!("malformed request: {e}"),
        },
    };
    let mut stream = stream;
    writeln!(stream, "{}", serde_json::to_string(&reply)?)?;
    stream.flush()?;
    let _ = written_tx.send(());
    Ok(())
}

/// Sends one request to the supervisor of `domain` and waits for the reply.
pub fn call(domain: Option<&str>, request: &Request, timeout: Duration) -> anyhow::Result<Reply> {
    let path = socket_path(domain);
    let mut stream = UnixStream::connect(&path).map_err(|e| {
        anyhow::anyhow!(
            "no process set is running in domain '{}' ({}: {e})",
            domain.unwrap_or("default"),
            path.display()
        )
    })?;
    stream.set_read_timeout(Some(timeout))?;
    writeln!(stream, "{}", serde_json::to_string(request)?)?;
    let mut line = String::new();
    BufReader::new(&stream).read_line(&mut line)?;
    Ok(serde_json::from_str(&line)?)
}
