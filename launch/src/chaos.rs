//! Chaos during an evaluation run (`usv eval --closed-loop --chaos SEED`): kill -9 a random pipeline
//! service at random times and measure how long the supervisor takes to bring it back (new process,
//! first heartbeat); once per run, hang perception with SIGSTOP until the supervisor's heartbeat
//! timeout replaces it, and count the safe-stop commands the sequencer gives while the map is stale.
//! The run's other figures (clearance, collisions) say whether the boat stayed safe throughout.

use crate::control::ServiceStatus;
use crate::observe::Observation;
use crate::session::Session;
use crate::supervisor::BACKOFF_RESET_AFTER;
use serde_json::json;
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// A killed service not back after this long counts as not recovered.
const GIVE_UP: Duration = Duration::from_secs(10);

struct Outage {
    service: String,
    signal: &'static str,
    old_pid: u32,
    at: Instant,
    scenario_s: f64,
    safe_stops_before: u64,
}

pub struct Chaos {
    seed: u64,
    rng: u64,
    victims: Vec<String>,
    /// Wall time of each victim's latest kill or hang.
    last_killed: HashMap<String, Instant>,
    next_kill: Instant,
    hang_service: Option<String>,
    hang_after: Duration,
    started: Instant,
    outage: Option<Outage>,
    records: Vec<serde_json::Value>,
    recoveries_ms: Vec<f64>,
    hang_record: Option<serde_json::Value>,
}

impl Chaos {
    /// `victims`: services that may be killed; `hang`: the service to hang once (perception).
    pub fn new(seed: u64, victims: Vec<String>, hang: Option<String>) -> Self {
        let mut chaos = Self {
            seed,
            rng: seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            victims,
            last_killed: HashMap::new(),
            next_kill: Instant::now(),
            hang_service: hang,
            hang_after: Duration::from_secs(12),
            started: Instant::now(),
            outage: None,
            records: Vec::new(),
            recoveries_ms: Vec::new(),
            hang_record: None,
        };
        chaos.next_kill = Instant::now() + chaos.pause();
        chaos
    }

    /// xorshift64*: reproducible from the seed, no dependency for a handful of draws.
    fn next(&mut self) -> u64 {
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// 2 to 5 s between kills.
    fn pause(&mut self) -> Duration {
        Duration::from_millis(2000 + self.next() % 3000)
    }

    /// Called often from the evaluation loop.
    pub fn step(&mut self, session: &Session, obs: &Observation) -> anyhow::Result<()> {
        if let Some(outage) = &self.outage {
            let services = session.ps()?;
            if back(&services, &outage.service, outage.old_pid) || outage.at.elapsed() > GIVE_UP {
                self.finish(&services, obs);
            }
            return Ok(());
        }
        let hang_due = self.hang_record.is_none()
            && self.hang_service.is_some()
            && self.started.elapsed() >= self.hang_after;
        if !hang_due && Instant::now() < self.next_kill {
            return Ok(());
        }
        let (service, signal, name) = if hang_due {
            (
                self.hang_service.clone().unwrap_or_default(),
                libc::SIGSTOP,
                "SIGSTOP",
            )
        } else {
            // The supervisor backs off a crash loop on purpose (a process that ran less than
            // `BACKOFF_RESET_AFTER` restarts later each time), and each kill should measure a
            // plain restart: a service whose restarted process has not run that long is spared,
            // and when every one is that recent the one killed longest ago is taken. Wall time,
            // as the supervisor counts: in lock-step a scenario second takes several.
            let spare = BACKOFF_RESET_AFTER + Duration::from_secs(1);
            let candidates: Vec<String> = self
                .victims
                .iter()
                .filter(|v| self.last_killed.get(*v).is_none_or(|t| t.elapsed() > spare))
                .cloned()
                .collect();
            let victim = if candidates.is_empty() {
                self.victims
                    .iter()
                    .min_by_key(|v| self.last_killed.get(*v).copied())
                    .cloned()
                    .unwrap_or_default()
            } else {
                let k = (self.next() % candidates.len() as u64) as usize;
                candidates[k].clone()
            };
            (victim, libc::SIGKILL, "SIGKILL")
        };
        let services = session.ps()?;
        let Some(pid) = services
            .iter()
            .find(|s| s.name == service && s.heartbeat_age_ms.is_some())
            .and_then(|s| s.pid)
        else {
            // Not up (yet): try another time.
            self.next_kill = Instant::now() + Duration::from_millis(200);
            return Ok(());
        };
        // SAFETY: kill(2) on a child of the set's supervisor.
        unsafe { libc::kill(pid as libc::pid_t, signal) };
        // A hung service is replaced too, after the heartbeat timeout: counting from the hang
        // spares it longer than needed, never too briefly.
        self.last_killed.insert(service.clone(), Instant::now());
        self.outage = Some(Outage {
            service,
            signal: name,
            old_pid: pid,
            at: Instant::now(),
            scenario_s: obs.scenario_time_s(),
            safe_stops_before: obs.safe_stop_commands,
        });
        Ok(())
    }

    fn finish(&mut self, services: &[ServiceStatus], obs: &Observation) {
        let Some(o) = self.outage.take() else { return };
        let recovered = back(services, &o.service, o.old_pid);
        let ms = o.at.elapsed().as_secs_f64() * 1e3;
        let record = json!({
            "service": o.service, "signal": o.signal, "scenario_s": (o.scenario_s * 10.0).round() / 10.0,
            "recovered_ms": recovered.then_some((ms * 10.0).round() / 10.0),
            "safe_stop_commands": obs.safe_stop_commands - o.safe_stops_before,
        });
        if o.signal == "SIGSTOP" {
            self.hang_record = Some(record);
        } else {
            if recovered {
                self.recoveries_ms.push(ms);
            }
            self.records.push(record);
        }
        self.next_kill = Instant::now() + self.pause();
    }

    pub fn report(&self) -> serde_json::Value {
        let unrecovered = self
            .records
            .iter()
            .filter(|r| r["recovered_ms"].is_null())
            .count();
        json!({
            "seed": self.seed,
            "kills": self.records.len(),
            "not_recovered": unrecovered,
            "max_recovery_ms": self.recoveries_ms.iter().copied().fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v)))),
            "events": self.records,
            "hang": self.hang_record,
        })
    }
}

/// The text report of a chaos run ([`Chaos::report`]): what was killed when, how soon each came
/// back, and the hang.
pub fn report_lines(report: &serde_json::Value) -> Vec<String> {
    let ms = |v: &serde_json::Value| {
        v.as_f64()
            .map_or("never".to_string(), |ms| format!("{ms:.0} ms"))
    };
    let events = report["events"]
        .as_array()
        .map_or(&[][..], |e| e.as_slice());
    let (kills, lost) = (
        report["kills"].as_u64().unwrap_or(0),
        report["not_recovered"].as_u64().unwrap_or(0),
    );
    let mut lines = vec![format!(
        "chaos (seed {}): {kills} kill -9, {} back{}{}",
        report["seed"],
        kills - lost.min(kills),
        report["max_recovery_ms"]
            .as_f64()
            .map_or(String::new(), |m| format!(" within {m:.0} ms")),
        if lost > 0 {
            format!(", {lost} never")
        } else {
            String::new()
        },
    )];
    lines.extend(events.iter().map(|e| {
        format!(
            "  {:>5.1} s  {:<16} back after {}",
            e["scenario_s"].as_f64().unwrap_or(0.0),
            e["service"].as_str().unwrap_or("?"),
            ms(&e["recovered_ms"]),
        )
    }));
    let hang = &report["hang"];
    if hang.is_object() {
        lines.push(format!(
            "  {:>5.1} s  {:<16} hung (SIGSTOP), replaced after {}; {} safe-stop commands meanwhile",
            hang["scenario_s"].as_f64().unwrap_or(0.0),
            hang["service"].as_str().unwrap_or("?"),
            ms(&hang["recovered_ms"]),
            hang["safe_stop_commands"],
        ));
    }
    lines
}

/// True once `service` runs as a new process that has sent a heartbeat.
fn back(services: &[ServiceStatus], service: &str, old_pid: u32) -> bool {
    services.iter().any(|s| {
        s.name == service && s.pid.is_some_and(|p| p != old_pid) && s.heartbeat_age_ms.is_some()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_text_report_names_each_kill_its_recovery_and_the_hang() {
        let report = json!({
            "seed": 7, "kills": 2, "not_recovered": 1, "max_recovery_ms": 141.7,
            "events": [
                {"service": "tracker", "signal": "SIGKILL", "scenario_s": 0.8, "recovered_ms": 141.7, "safe_stop_commands": 0},
                {"service": "mapper", "signal": "SIGKILL", "scenario_s": 3.4, "recovered_ms": null, "safe_stop_commands": 0},
            ],
            "hang": {"service": "perception", "signal": "SIGSTOP", "scenario_s": 6.2, "recovered_ms": 5085.9, "safe_stop_commands": 20},
        });
        let lines = report_lines(&report);
        assert_eq!(
            lines[0],
            "chaos (seed 7): 2 kill -9, 1 back within 142 ms, 1 never"
        );
        assert!(lines[1].contains("tracker") && lines[1].ends_with("back after 142 ms"));
        assert!(lines[2].contains("mapper") && lines[2].ends_with("back after never"));
        assert!(
            lines[3].contains("perception")
                && lines[3].contains("replaced after 5086 ms; 20 safe-stop")
        );
        assert_eq!(
            report_lines(&json!({"seed": 1, "kills": 0, "not_recovered": 0, "events": []})).len(),
            1
        );
    }
}
