//! What a service reports about itself: counters and state, published as `Heartbeat` messages.

use crate::clock::monotonic_ns;
use crate::pubsub::Publisher;
use messages::{service_state, FixedStr, Header, Heartbeat};
use std::time::Instant;

/// The handler's view of its service's health. Every processed, rejected or failed input goes through
/// here, so the supervisor, `usv ps` and lock-step sources see it.
pub struct Health {
    publisher: Publisher<Heartbeat, ()>,
    beat: Heartbeat,
    /// Set when something changed that a lock-step source may be waiting for.
    pending: bool,
}

impl Health {
    pub(crate) fn new(publisher: Publisher<Heartbeat, ()>, name: &str) -> Self {
        let beat = Heartbeat {
            hdr: Header::new(0, 0, name),
            pid: std::process::id(),
            state: service_state::STARTING,
            ..Default::default()
        };
        Self {
            publisher,
            beat,
            pending: true,
        }
    }

    /// An input derived from sensor time `stamp_ns` was processed; `started` is when work on it began.
    /// Record only the service's primary input (the one derived from camera frames): lock-step
    /// sources read `last_input_stamp_ns` as "this frame is done", so a faster side input such as INS
    /// must not advance it.
    pub fn record(&mut self, stamp_ns: u64, started: Instant) {
        let us = started.elapsed().as_micros().min(u32::MAX as u128) as u32;
        let b = &mut self.beat;
        b.processed += 1;
        b.last_input_stamp_ns = stamp_ns;
        b.last_processing_us = us;
        b.max_processing_us = b.max_processing_us.max(us);
        b.state = service_state::RUNNING;
        self.pending = true;
    }

    /// An input was refused as bad (wrong size, NaN, belongs to another frame ...). The stamp still
    /// counts as handled, so a lock-step source does not wait forever on a frame that will never pass.
    pub fn reject(&mut self, stamp_ns: u64, reason: &str) {
        tracing::warn!("input rejected: {reason}");
        let b = &mut self.beat;
        b.rejected += 1;
        b.last_input_stamp_ns = b.last_input_stamp_ns.max(stamp_ns);
        b.last_error = FixedStr::new(reason);
        b.state = service_state::DEGRADED;
        self.pending = true;
    }

    pub(crate) fn error(&mut self, error: &anyhow::Error) {
        tracing::error!("{error:#}");
        let b = &mut self.beat;
        b.errors += 1;
        b.last_error = FixedStr::new(&format!("{error:#}"));
        b.state = service_state::DEGRADED;
        self.pending = true;
    }

    pub(crate) fn missed_deadline(&mut self, topic: &str) {
        let b = &mut self.beat;
        b.missed_deadlines += 1;
        b.last_error = FixedStr::new(&format!("no data on {topic}"));
        b.state = service_state::DEGRADED;
        self.pending = true;
    }

    pub(crate) fn set_state(&mut self, state: u8) {
        self.beat.state = state;
        self.pending = true;
    }

    pub fn processed(&self) -> u64 {
        self.beat.processed
    }

    pub fn last(&self) -> &Heartbeat {
        &self.beat
    }

    pub(crate) fn take_pending(&mut self) -> bool {
        std::mem::take(&mut self.pending)
    }

    pub(crate) fn publish(&mut self) {
        self.beat.hdr.seq = self.publisher.next_seq();
        self.beat.hdr.stamp_ns = monotonic_ns();
        if let Err(e) = self.publisher.publish(&self.beat) {
            tracing::warn!("heartbeat not published: {e:#}");
        }
    }
}
