//! Lock-step pacing for sources (simulator, replay): publish frame k+1 only after every pipeline
//! service has finished frame k. "Finished" is read from heartbeats: a service reports the stamp of the
//! newest primary input it has processed or rejected (`Heartbeat::last_input_stamp_ns`), and stamps
//! are copied unchanged down the pipeline, so one number per service says how far it got.

use crate::{Service, Shutdown, Subscriber};
use messages::{topics, Heartbeat};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

pub struct LockStep {
    heartbeats: Subscriber<Heartbeat, ()>,
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
    /// Waits on the named services (the pipeline downstream of the source).
    pub fn new(service: &Service, pipeline: &[String]) -> anyhow::Result<Self> {
        Ok(Self {
            heartbeats: service.subscriber(&topics::HEARTBEAT)?,
            done: pipeline.iter().map(|s| (s.clone(), 0)).collect(),
            timeouts: 0,
        })
    }

    pub fn services(&self) -> impl Iterator<Item = &str> {
        self.done.keys().map(String::as_str)
    }

    /// The heartbeat subscriber, to wait on it in `Service::run` (`lockstep.heartbeats().input(..)`).
    pub fn heartbeats(&self) -> &Subscriber<Heartbeat, ()> {
        &self.heartbeats
    }

    /// Reads the heartbeats that arrived since the last call.
    pub fn update(&mut self) -> anyhow::Result<()> {
        while let Some(sample) = self.heartbeats.receive()? {
            let beat = sample.payload();
            if let Some(done) = self.done.get_mut(beat.hdr.source.as_str()) {
                *done = (*done).max(beat.last_input_stamp_ns);
            }
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
    pub fn wait(
        &mut self,
        stamp_ns: u64,
        timeout: Duration,
        shutdown: &Shutdown,
    ) -> anyhow::Result<Step> {
        let end = Instant::now() + timeout;
        loop {
            self.update()?;
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
            // Heartbeats come right after a service finishes an input; a short sleep keeps this
            // cheap without adding much to the frame period.
            std::thread::sleep(Duration::from_micros(200));
        }
    }
}
