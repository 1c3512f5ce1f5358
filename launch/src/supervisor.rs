//! `usv up`: starts a process set in dependency order, restarts services that exit or stop sending
//! heartbeats (by their restart policy, with exponential backoff), swaps a service's program on
//! request, and on `usv down` or a signal stops everything and sweeps the shared memory it left.

use crate::child;
use crate::control::{self, Envelope, Reply, Request, ServiceStatus};
use crate::launchfile::{resolve_program, ProcessSet, RestartPolicy, ServiceSpec};
use messages::{service_state, topics, Heartbeat};
use std::collections::VecDeque;
use std::process::Child;
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// The supervisor wakes this often to reap, read heartbeats and answer requests.
const POLL: Duration = Duration::from_millis(10);
/// A service that ran this long before failing restarts with the initial backoff again.
pub const BACKOFF_RESET_AFTER: Duration = Duration::from_secs(10);
/// Window over which `usv ps` computes input rates.
const RATE_WINDOW: Duration = Duration::from_secs(3);

/// What to do once the current process of a service has exited.
#[derive(Debug, Clone, PartialEq)]
enum AfterExit {
    /// Apply the restart policy.
    Policy,
    /// Start again at once (restart or swap requested).
    StartNow,
    /// Stay down (set shutting down).
    StayDown,
}

struct Running {
    process: Child,
    pid: u32,
    started: Instant,
    /// When this process's newest heartbeat arrived (the heartbeat itself is `Managed::last_beat`).
    last_beat_at: Option<Instant>,
    /// (arrival, processed) samples for the input rate.
    rate_samples: VecDeque<(Instant, u64)>,
    /// Set once SIGTERM was sent: SIGKILL follows at this instant.
    kill_at: Option<Instant>,
    /// Killed by the supervisor for a missed heartbeat (counts as a failure).
    hung: bool,
}

struct Managed {
    spec: ServiceSpec,
    /// Newest heartbeat of any process of this service (kept after it exits, for the record).
    last_beat: Option<Heartbeat>,
    running: Option<Running>,
    after_exit: AfterExit,
    restarts: u32,
    backoff: Duration,
    next_start: Option<Instant>,
    last_exit: String,
}

impl Managed {
    fn state(&self) -> String {
        match &self.running {
            Some(r) if r.kill_at.is_some() => "stopping".into(),
            Some(r) => match (r.last_beat_at, &self.last_beat) {
                (Some(_), Some(b)) => service_state::name(b.state).into(),
                _ if self.spec.heartbeat_timeout_ms.is_some() => "starting".into(),
                _ => "running".into(),
            },
            None if self.next_start.is_some() => "backoff".into(),
            None => format!("stopped ({})", self.last_exit),
        }
    }

    fn status(&self, now: Instant) -> ServiceStatus {
        let r = self.running.as_ref();
        let beat_time = r.and_then(|r| r.last_beat_at);
        let beat = self.last_beat.as_ref();
        ServiceStatus {
            name: self.spec.name.clone(),
            pid: r.map(|r| r.pid),
            state: self.state(),
            restarts: self.restarts,
            heartbeat_age_ms: beat_time.map(|t| now.duration_since(t).as_millis() as u64),
            input_rate_hz: r.and_then(|r| input_rate(&r.rate_samples)),
            processed: beat.map_or(0, |b| b.processed),
            rejected: beat.map_or(0, |b| b.rejected),
            errors: beat.map_or(0, |b| b.errors),
            last_processing_us: beat.map(|b| b.last_processing_us),
            max_processing_us: beat.map(|b| b.max_processing_us),
            last_error: beat
                .map(|b| b.last_error.as_str().to_string())
                .unwrap_or_default(),
            program: self.spec.program.display().to_string(),
        }
    }
}

fn input_rate(samples: &VecDeque<(Instant, u64)>) -> Option<f64> {
    let (t0, n0) = samples.front()?;
    let (t1, n1) = samples.back()?;
    let dt = t1.duration_since(*t0).as_secs_f64();
    (dt > 0.2).then(|| (n1 - n0) as f64 / dt)
}

pub struct Supervisor {
    set: ProcessSet,
    domain: Option<String>,
    services: Vec<Managed>,
    shutting_down: Option<Instant>,
}

impl Supervisor {
    pub fn new(set: ProcessSet, domain: Option<String>) -> Self {
        let services = set
            .services
            .iter()
            .map(|spec| Managed {
                spec: spec.clone(),
                last_beat: None,
                running: None,
                after_exit: AfterExit::Policy,
                restarts: 0,
                backoff: Duration::from_millis(spec.backoff_initial_ms),
                next_start: Some(Instant::now()),
                last_exit: "not started".into(),
            })
            .collect();
        Self {
            set,
            domain,
            services,
            shutting_down: None,
        }
    }

    /// Runs until `usv down` or SIGINT/SIGTERM; returns after every child is gone.
    pub fn run(mut self) -> anyhow::Result<()> {
        let (listener, socket) = control::bind(self.domain.as_deref())?;
        let node = runtime::Service::start("usv-supervisor")?;
        let heartbeats = node.subscriber(&topics::HEARTBEAT)?;
        let (tx, requests) = mpsc::channel::<Envelope>();
        std::thread::spawn(move || control::serve(listener, tx));
        tracing::info!(
            set = %self.set.name,
            domain = self.domain.as_deref().unwrap_or("default"),
            services = self.services.len(),
            "process set up; stop it with `usv down` or Ctrl-C"
        );

        let mut down_requests: Vec<Envelope> = Vec::new();
        loop {
            let now = Instant::now();
            if node.shutdown().requested() && self.shutting_down.is_none() {
                self.begin_shutdown(now);
            }
            while let Ok(envelope) = requests.try_recv() {
                if let Request::Down = envelope.request {
                    self.begin_shutdown(now);
                    down_requests.push(envelope);
                } else {
                    let _ = envelope.reply.send(self.handle(envelope.request, now));
                }
            }
            while let Some(sample) = heartbeats.receive()? {
                self.on_heartbeat(sample.payload(), now);
            }
            self.reap(now);
            if let Some(deadline) = self.shutting_down {
                if self.services.iter().all(|m| m.running.is_none()) {
                    break;
                }
                if now >= deadline {
                    self.kill_all();
                }
            } else {
                self.check_heartbeats(now);
                self.start_due(now);
            }
            self.escalate_stops(now);
            std::thread::sleep(POLL);
        }

        drop(heartbeats);
        drop(node);
        let cleanup = self.sweep();
        let _ = std::fs::remove_file(&socket);
        let reply = match &cleanup {
            Ok(()) => Reply::Ok {
                message: format!("set '{}' stopped", self.set.name),
            },
            Err(e) => Reply::Error {
                message: format!("set '{}' stopped, but cleanup failed: {e:#}", self.set.name),
            },
        };
        for envelope in down_requests {
            let _ = envelope.reply.send(reply.clone());
            let _ = envelope.written.recv_timeout(Duration::from_secs(2));
        }
        cleanup
    }

    /// Removes what dead processes of the domain left in shared memory.
    fn sweep(&self) -> anyhow::Result<()> {
        let config = runtime::domain::config_for(self.domain.as_deref())?;
        let swept = runtime::cleanup::sweep_dead_nodes(&config);
        let files = match &self.domain {
            Some(domain) => runtime::cleanup::remove_domain_leftovers(domain)?,
            None => 0,
        };
        tracing::info!(swept, files, "process set down");
        Ok(())
    }

    fn handle(&mut self, request: Request, now: Instant) -> Reply {
        let find =
            |services: &[Managed], name: &str| services.iter().position(|m| m.spec.name == name);
        match request {
            Request::Ps => Reply::Ps {
                set: self.set.name.clone(),
                services: self.services.iter().map(|m| m.status(now)).collect(),
            },
            Request::Restart { service } => match find(&self.services, &service) {
                Some(i) => {
                    self.restart(i, now);
                    Reply::Ok {
                        message: format!("restarting '{service}'"),
                    }
                }
                None => unknown(&service),
            },
            Request::Swap {
                service,
                program,
                args,
            } => {
                let Some(i) = find(&self.services, &service) else {
                    return unknown(&service);
                };
                let Some(path) = resolve_program(&program, std::path::Path::new("/")) else {
                    return Reply::Error {
                        message: format!("program '{program}' not found"),
                    };
                };
                let m = &mut self.services[i];
                m.spec.program = path;
                m.spec.args = args;
                self.restart(i, now);
                Reply::Ok {
                    message: format!("swapping '{service}' to {program}"),
                }
            }
            Request::Down => unreachable!("handled by the loop"),
        }
    }

    /// Stops the current process (if any) and starts the spec again as soon as it has exited.
    fn restart(&mut self, i: usize, now: Instant) {
        let grace = Duration::from_millis(self.set.stop_grace_ms);
        let m = &mut self.services[i];
        m.after_exit = AfterExit::StartNow;
        match &mut m.running {
            Some(r) => {
                if r.kill_at.is_none() {
                    child::signal_group(r.pid, libc::SIGTERM);
                    r.kill_at = Some(now + grace);
                }
            }
            None => m.next_start = Some(now),
        }
    }

    fn begin_shutdown(&mut self, now: Instant) {
        if self.shutting_down.is_some() {
            return;
        }
        tracing::info!("stopping process set");
        let grace = Duration::from_millis(self.set.stop_grace_ms);
        self.shutting_down = Some(now + grace);
        // Reverse start order: consumers go before their producers.
        for m in self.services.iter_mut().rev() {
            m.after_exit = AfterExit::StayDown;
            m.next_start = None;
            if let Some(r) = &mut m.running {
                child::signal_group(r.pid, libc::SIGTERM);
                r.kill_at = Some(now + grace);
            }
        }
    }

    fn kill_all(&mut self) {
        for m in &mut self.services {
            if let Some(r) = &m.running {
                child::signal_group(r.pid, libc::SIGKILL);
            }
        }
    }

    fn escalate_stops(&mut self, now: Instant) {
        for m in &mut self.services {
            if let Some(r) = &mut m.running {
                if r.kill_at.is_some_and(|t| now >= t) {
                    tracing::warn!(service = %m.spec.name, "did not stop in time, killing");
                    child::signal_group(r.pid, libc::SIGKILL);
                    r.kill_at = Some(now + Duration::from_secs(3600));
                }
            }
        }
    }

    fn on_heartbeat(&mut self, beat: &Heartbeat, now: Instant) {
        let name = beat.hdr.source.as_str();
        let Some(m) = self.services.iter_mut().find(|m| m.spec.name == name) else {
            return;
        };
        // Heartbeats of an earlier process of the same service may still be queued.
        let Some(r) = m.running.as_mut().filter(|r| r.pid == beat.pid) else {
            return;
        };
        r.last_beat_at = Some(now);
        m.last_beat = Some(*beat);
        r.rate_samples.push_back((now, beat.processed));
        while r
            .rate_samples
            .front()
            .is_some_and(|(t, _)| now.duration_since(*t) > RATE_WINDOW)
        {
            r.rate_samples.pop_front();
        }
    }

    /// Kills services whose heartbeat stopped (hung, SIGSTOPped); `reap` then restarts them.
    fn check_heartbeats(&mut self, now: Instant) {
        for m in &mut self.services {
            let Some(timeout) = m.spec.heartbeat_timeout_ms.map(Duration::from_millis) else {
                continue;
            };
            let Some(r) = m.running.as_mut().filter(|r| r.kill_at.is_none()) else {
                continue;
            };
            let silent_for = match r.last_beat_at {
                Some(t) => now.duration_since(t),
                None if now.duration_since(r.started)
                    > Duration::from_millis(m.spec.startup_timeout_ms) =>
                {
                    timeout + Duration::from_millis(1)
                }
                None => Duration::ZERO,
            };
            if silent_for > timeout {
                tracing::warn!(service = %m.spec.name, pid = r.pid, ?silent_for, "heartbeat timeout, killing");
                child::signal_group(r.pid, libc::SIGKILL);
                r.hung = true;
                r.kill_at = Some(now + Duration::from_secs(3600));
            }
        }
    }

    fn reap(&mut self, now: Instant) {
        for m in &mut self.services {
            let Some(r) = m.running.as_mut() else {
                continue;
            };
            let status = match r.process.try_wait() {
                Ok(Some(status)) => status,
                Ok(None) => continue,
                Err(e) => {
                    tracing::error!(service = %m.spec.name, "cannot wait for child: {e}");
                    continue;
                }
            };
            let ran_for = now.duration_since(r.started);
            let hung = r.hung;
            m.running = None;
            m.last_exit = if hung {
                "heartbeat timeout".into()
            } else {
                status.to_string()
            };
            let failed = hung || !status.success();
            match m.after_exit {
                AfterExit::StayDown => {}
                AfterExit::StartNow => {
                    m.next_start = Some(now);
                    m.after_exit = AfterExit::Policy;
                }
                AfterExit::Policy => {
                    let restart = match m.spec.restart {
                        RestartPolicy::Never => false,
                        RestartPolicy::OnFailure => failed,
                        RestartPolicy::Always => true,
                    };
                    tracing::warn!(service = %m.spec.name, exit = %m.last_exit, restart, "service exited");
                    if restart {
                        if ran_for > BACKOFF_RESET_AFTER {
                            m.backoff = Duration::from_millis(m.spec.backoff_initial_ms);
                        }
                        m.next_start = Some(now + m.backoff);
                        m.backoff =
                            (m.backoff * 2).min(Duration::from_millis(m.spec.backoff_max_ms));
                        m.restarts += 1;
                    }
                }
            }
        }
    }

    /// Starts services whose start time has come and whose dependencies are up.
    fn start_due(&mut self, now: Instant) {
        for i in 0..self.services.len() {
            let m = &self.services[i];
            if m.running.is_some() || m.next_start.is_none_or(|t| now < t) {
                continue;
            }
            let deps_up = m.spec.depends_on.iter().all(|dep| {
                self.services.iter().any(|d| {
                    d.spec.name == *dep
                        && d.running.as_ref().is_some_and(|r| {
                            r.last_beat_at.is_some() || d.spec.heartbeat_timeout_ms.is_none()
                        })
                })
            });
            if !deps_up {
                continue;
            }
            let m = &mut self.services[i];
            m.next_start = None;
            match child::spawn(&m.spec, &self.set.dir, self.domain.as_deref()) {
                Ok(process) => {
                    let pid = process.id();
                    tracing::info!(service = %m.spec.name, pid, program = %m.spec.program.display(), "started");
                    m.running = Some(Running {
                        process,
                        pid,
                        started: now,
                        last_beat_at: None,
                        rate_samples: VecDeque::new(),
                        kill_at: None,
                        hung: false,
                    });
                }
                Err(e) => {
                    tracing::error!(service = %m.spec.name, "cannot start {}: {e}", m.spec.program.display());
                    m.last_exit = format!("spawn failed: {e}");
                    if m.spec.restart != RestartPolicy::Never {
                        m.next_start = Some(now + m.backoff);
                        m.backoff =
                            (m.backoff * 2).min(Duration::from_millis(m.spec.backoff_max_ms));
                    }
                }
            }
        }
    }
}

fn unknown(service: &str) -> Reply {
    Reply::Error {
        message: format!("no service named '{service}' in this set"),
    }
}
