//! Input watchdog in stream time: the map, the contacts and the INS each have a timeout; "now" is the
//! newest stamp of any input, so replay and lock-step runs trip exactly as live ones would, however
//! fast they run. An input that stops altogether (so that stream time stops too) is caught by the
//! wait loop's deadlines, which the binary reports through [`Watchdog::missed`].

use serde::Deserialize;

/// Bits of [`messages::SequencerStatus::stale_inputs`].
pub const MAP: u32 = 1;
pub const CONTACTS: u32 = 2;
pub const INS: u32 = 4;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WatchdogConfig {
    pub map_timeout_s: f64,
    pub contacts_timeout_s: f64,
    pub ins_timeout_s: f64,
    /// Contacts are always required while following one; with this set they are required always
    /// (when a tracker is part of the process set).
    pub require_contacts: bool,
}

impl Default for WatchdogConfig {
    fn default() -> Self {
        Self {
            map_timeout_s: 1.0,
            contacts_timeout_s: 1.0,
            ins_timeout_s: 0.5,
            require_contacts: false,
        }
    }
}

#[derive(Debug, Clone)]
pub struct Watchdog {
    timeouts_ns: [u64; 3],
    require_contacts: bool,
    /// Newest stamp of map, contacts, INS.
    last: [Option<u64>; 3],
    /// Inputs whose wall-clock deadline passed and that have not delivered since.
    missed: u32,
}

fn index(input: u32) -> usize {
    match input {
        MAP => 0,
        CONTACTS => 1,
        _ => 2,
    }
}

impl Watchdog {
    pub fn new(cfg: &WatchdogConfig) -> Self {
        let ns = |s: f64| (s.max(0.0) * 1e9) as u64;
        Self {
            timeouts_ns: [
                ns(cfg.map_timeout_s),
                ns(cfg.contacts_timeout_s),
                ns(cfg.ins_timeout_s),
            ],
            require_contacts: cfg.require_contacts,
            last: [None; 3],
            missed: 0,
        }
    }

    /// `input` (one of [`MAP`], [`CONTACTS`], [`INS`]) delivered data stamped `stamp_ns`.
    pub fn seen(&mut self, input: u32, stamp_ns: u64) {
        self.last[index(input)] = Some(stamp_ns);
        self.missed &= !input;
    }

    /// `input` missed its wall-clock deadline: stale until it delivers again.
    pub fn missed(&mut self, input: u32) {
        self.missed |= input;
    }

    /// Stream time: the newest stamp of any input (0 before the first).
    pub fn now(&self) -> u64 {
        self.last.iter().flatten().copied().max().unwrap_or(0)
    }

    /// Bits of the required inputs that are stale at `now` (never seen counts as stale).
    pub fn stale(&self, now: u64, need_contacts: bool) -> u32 {
        let mut bits = 0;
        for input in [MAP, CONTACTS, INS] {
            if input == CONTACTS && !(need_contacts || self.require_contacts) {
                continue;
            }
            let i = index(input);
            let old = match self.last[i] {
                Some(t) => now.saturating_sub(t) > self.timeouts_ns[i],
                None => true,
            };
            if old || self.missed & input != 0 {
                bits |= input;
            }
        }
        bits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000_000;

    #[test]
    fn trips_when_an_input_is_old_and_recovers_when_it_returns() {
        let mut w = Watchdog::new(&WatchdogConfig::default());
        assert_eq!(w.stale(0, false), MAP | INS, "nothing seen yet");
        w.seen(MAP, 10 * S);
        w.seen(INS, 10 * S);
        assert_eq!(w.stale(w.now(), false), 0);
        // Map keeps coming, INS stops: stale after 0.5 s of stream time.
        w.seen(MAP, 10 * S + S / 2);
        assert_eq!(w.stale(w.now(), false), 0);
        w.seen(MAP, 10 * S + S / 2 + 1);
        assert_eq!(w.stale(w.now(), false), INS);
        w.seen(INS, 11 * S);
        assert_eq!(w.stale(w.now(), false), 0, "recovered");
        // Contacts count only when needed.
        assert_eq!(w.stale(w.now(), true), CONTACTS);
        w.seen(CONTACTS, 11 * S);
        assert_eq!(w.stale(w.now(), true), 0);
    }

    #[test]
    fn a_missed_deadline_is_stale_until_data_returns() {
        let mut w = Watchdog::new(&WatchdogConfig::default());
        w.seen(MAP, S);
        w.seen(INS, S);
        w.missed(INS);
        assert_eq!(w.stale(w.now(), false), INS);
        w.seen(INS, S);
        assert_eq!(w.stale(w.now(), false), 0);
    }
}
