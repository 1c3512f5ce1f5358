//! Live inputs. A device driver (a stereo head, an INS) implements [`Source`]; the sensors service
//! polls it and publishes what it produces on the same topics replay uses, so the rest of the stack
//! cannot tell a live run from a replay.
//!
//! Rules for a driver:
//! - Stamp with the sensor's own time of capture (`Header::stamp_ns`), in nanoseconds on the clock
//!   the INS and cameras share (a hardware-synchronized clock, or CLOCK_MONOTONIC when there is none).
//! - Fill images in place: [`Sink::stereo`] hands out the buffer to fill (shared memory when the sink
//!   publishes), so a 2.4 MB pair is never copied or allocated per frame.
//! - Return an error for a device fault (disconnected, bad frame size); the service reports it in its
//!   heartbeat and retries. Never hand out a partial frame.

use messages::{InsState, StereoFrameHeader};
use std::time::Duration;

#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    #[error("{device}: {message}")]
    Device { device: String, message: String },
    #[error("cannot publish: {0}")]
    Sink(String),
}

/// Where a source delivers its samples.
pub trait Sink {
    /// A stereo pair described by `header` (its `payload_len()` bytes); `fill` writes the left then
    /// the right plane into the buffer it is given.
    fn stereo(
        &mut self,
        header: &StereoFrameHeader,
        fill: &mut dyn FnMut(&mut [u8]),
    ) -> Result<(), SourceError>;
    fn ins(&mut self, state: &InsState) -> Result<(), SourceError>;
}

/// A live device.
pub trait Source {
    /// Device name for logs and errors (a head name, "ins").
    fn name(&self) -> &str;
    /// Waits at most `timeout` for the device's next sample and delivers it to `sink`. Returns
    /// `Ok(false)` if nothing arrived in time.
    fn poll(&mut self, timeout: Duration, sink: &mut dyn Sink) -> Result<bool, SourceError>;
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::{Header, Name, PixelEncoding};

    /// A test pattern camera: what a driver looks like.
    struct Pattern {
        seq: u64,
    }

    impl Source for Pattern {
        fn name(&self) -> &str {
            "pattern"
        }
        fn poll(&mut self, _: Duration, sink: &mut dyn Sink) -> Result<bool, SourceError> {
            let header = StereoFrameHeader {
                hdr: Header::new(self.seq, self.seq * 100_000_000, "pattern"),
                head: Name::new("pattern"),
                width: 4,
                height: 2,
                stride: 4,
                encoding: PixelEncoding::Mono8 as u32,
            };
            self.seq += 1;
            sink.stereo(&header, &mut |buf| {
                buf.iter_mut().enumerate().for_each(|(i, b)| *b = i as u8)
            })?;
            Ok(true)
        }
    }

    #[derive(Default)]
    struct Collect(Vec<Vec<u8>>);

    impl Sink for Collect {
        fn stereo(
            &mut self,
            h: &StereoFrameHeader,
            fill: &mut dyn FnMut(&mut [u8]),
        ) -> Result<(), SourceError> {
            let mut buf = vec![0; h.payload_len()];
            fill(&mut buf);
            self.0.push(buf);
            Ok(())
        }
        fn ins(&mut self, _: &InsState) -> Result<(), SourceError> {
            Ok(())
        }
    }

    #[test]
    fn a_source_fills_the_sink_buffer() {
        let mut sink = Collect::default();
        let mut cam = Pattern { seq: 0 };
        assert!(cam.poll(Duration::ZERO, &mut sink).unwrap());
        assert_eq!(sink.0[0], (0..16).collect::<Vec<u8>>());
    }
}
