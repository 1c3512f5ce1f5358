//! Lock-step pacing for sources (simulator, replay): publish frame k+1 only after every pipeline
//! service has finished frame k. "Finished" is read from heartbeats: a service reports the stamp of the
//! newest primary input it has processed or rejected (`Heartbeat::last_input_stamp_ns`), and stamps
//! are copied unchanged down the pipeline, so one number per service says how far it got.
//!
//! The source owns the heartbeat subscriber (so it can wait on it in `Service::run`) and feeds what
//! arrives to [`LockStep::observe`].

use crate::{Shutdown, Subscriber};
use messages::Heartbeat;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

pub struct LockStep {
    /// Service name -> newest stamp it reported done.
    done: BTreeMap<String, u64>,
    /// Frames for which the wait ran out (a service dropped the frame or died).
    pub timeouts: u64,
}

/// How a wait ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// Every service reported the stamp.
    Done,
    /// These services did not report it in time.
    TimedOut(Vec<String>),
    Shutdown,
}

impl LockStep {
    /// Paces on the named services (the pipeline downstream of the source).
    pub fn new(pipeline: &[String]) -> Self {
        Self {
            done: pipeline.iter().map(|s| (s.clone(), 0)).collect(),
            timeouts: 0,
        }
    }

    pub fn services(&self) -> impl Iterator<Item = &str> {
        self.done.keys().map(String::as_str)
    }

    /// Takes note of one heartbeat (others' heartbeats are ignored).
    pub fn observe(&mut self, beat: &Heartbeat) {
        if let Some(done) = self.done.get_mut(beat.hdr.source.as_str()) {
            *done = (*done).max(beat.last_input_stamp_ns);
        }
    }

    /// Feeds every heartbeat waiting in `heartbeats` to [`LockStep::observe`].
    pub fn update(&mut self, heartbeats: &Subscriber<Heartbeat, ()>) -> anyhow::Result<()> {
        while let Some(sample) = heartbeats.receive()? {
            self.observe(sample.payload());
        }
        Ok(())
    }

    /// True once every pipeline service reported `stamp_ns` done.
    pub fn done(&self, stamp_ns: u64) -> bool {
        self.done.values().all(|&done| done >= stamp_ns)
    }

    /// The services that have not reported `stamp_ns` yet.
    pub fn missing(&self, stamp_ns: u64) -> Vec<String> {
        self.done
            .iter()
            .filter(|(_, &done)| done < stamp_ns)
            .map(|(name, _)| name.clone())
            .collect()
    }

    /// Blocks until every pipeline service reported `stamp_ns` done, `timeout` passes, or shutdown.
    /// For sources without a wait loop of their own (a replay tool); services use `observe`.
    pub fn wait(
        &mut self,
        heartbeats: &Subscriber<Heartbeat, ()>,
        stamp_ns: u64,
        timeout: Duration,
        shutdown: &Shutdown,
    ) -> anyhow::Result<Step> {
        let end = Instant::now() + timeout;
        loop {
            self.update(heartbeats)?;
            let missing = self.missing(stamp_ns);
            if missing.is_empty() {
                return Ok(Step::Done);
            }
            if shutdown.requested() {
                return Ok(Step::Shutdown);
            }
            if Instant::now() >= end {
                self.timeouts += 1;
                return Ok(Step::TimedOut(missing));
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::{Header, Heartbeat};

    fn beat(source: &str, stamp: u64) -> Heartbeat {
        Heartbeat {
            hdr: Header::new(0, 0, source),
            last_input_stamp_ns: stamp,
            ..Default::default()
        }
    }

    #[test]
    fn done_only_when_every_pipeline_service_reported_the_stamp() {
        let mut l = LockStep::new(&["stereo".into(), "perception".into()]);
        assert!(!l.done(10));
        l.observe(&beat("stereo", 10));
        l.observe(&beat("recorder", 99));
        assert_eq!(l.missing(10), ["perception"]);
        l.observe(&beat("perception", 12));
        assert!(l.done(10));
        assert!(!l.done(11), "stereo has only reached 10");
        // An older heartbeat arriving late does not move a service back.
        l.observe(&beat("stereo", 5));
        assert!(l.done(10));
    }
}
