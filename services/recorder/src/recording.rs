//! A recording: every topic gets a replay channel (exact bytes, see `messages::recording`) and the
//! Foxglove channels its [`View`] declares. Counts messages and sequence gaps per topic and source.

use crate::foxglove::{self, Schema, View, ViewState};
use crate::mcap::{Class, Stats, WriteError, Writer, WriterOptions};
use messages::iceoryx2::prelude::{IceoryxSend, ZeroCopySend};
use messages::recording::{bytes_of, prefix, type_name, RAW_ENCODING};
use messages::summary::Inspect;
use messages::Name;
use std::collections::BTreeMap;
use std::io::Write;

#[derive(Debug, Clone)]
pub struct RecordingOptions {
    pub writer: WriterOptions,
    /// Write a Foxglove image for every n-th stereo frame (1 = every frame, 0 = none).
    pub image_view_every: u32,
    /// Write the Foxglove channels at all.
    pub foxglove: bool,
}

impl Default for RecordingOptions {
    fn default() -> Self {
        Self {
            writer: WriterOptions::default(),
            image_view_every: 1,
            foxglove: true,
        }
    }
}

/// Per-topic counters, reported at exit.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TopicStats {
    pub topic: String,
    pub messages: u64,
    /// Messages missing between consecutive sequence numbers of one source: lost before they reached
    /// the recorder (queue overflow, a publisher with no room) or never sent.
    pub dropped: u64,
    /// A source's sequence went backwards: its publisher restarted.
    pub restarts: u64,
    pub foxglove_messages: u64,
}

/// Index of a topic in a [`Recording`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TopicId(usize);

struct TopicEntry {
    channel: u16,
    views: Vec<(Schema, u16)>,
    stats: TopicStats,
    /// Last sequence number per source (few sources per topic: a linear search is fastest).
    last_seq: Vec<(Name, u64)>,
    /// Image views are subsampled.
    is_image: bool,
}

pub struct Recording<W: Write> {
    writer: Writer<W>,
    opts: RecordingOptions,
    topics: Vec<TopicEntry>,
    foxglove_schemas: BTreeMap<Schema, u16>,
    view_state: ViewState,
    scratch: Vec<u8>,
}

impl<W: Write> Recording<W> {
    pub fn new(out: W, opts: RecordingOptions) -> Result<Self, WriteError> {
        Ok(Self {
            writer: Writer::new(out, opts.writer.clone())?,
            opts,
            topics: Vec::new(),
            foxglove_schemas: BTreeMap::new(),
            view_state: ViewState::default(),
            scratch: Vec::new(),
        })
    }

    /// Adds a topic with payload `P` and user header `H`; `element_size` is the slice element size
    /// (or the payload size for fixed-size topics), recorded so a reader can check its build's types.
    pub fn add_topic<P, H>(
        &mut self,
        topic: &str,
        element_size: usize,
    ) -> Result<TopicId, WriteError>
    where
        P: ?Sized + ZeroCopySend,
        H: ZeroCopySend + View<P>,
    {
        let name = type_name::<P, H>();
        let header_size = std::mem::size_of::<H>();
        let description = format!(
            "{name}: u32 LE user header length | user header ({header_size} bytes) | payload ({element_size}-byte elements)"
        );
        let schema = self
            .writer
            .add_schema(name, RAW_ENCODING, description.as_bytes())?;
        let is_slice = header_size > 0;
        let class = if is_slice { Class::Bulk } else { Class::Small };
        let metadata = [
            ("header_size", header_size.to_string()),
            ("element_size", element_size.to_string()),
        ];
        let channel = self
            .writer
            .add_channel(topic, schema, RAW_ENCODING, &metadata, class)?;
        let mut views = Vec::new();
        if self.opts.foxglove {
            for &s in H::schemas() {
                if s == Schema::RawImage && self.opts.image_view_every == 0 {
                    continue;
                }
                let schema_id = match self.foxglove_schemas.get(&s) {
                    Some(&id) => id,
                    None => {
                        let id = self.writer.add_schema(
                            s.name(),
                            foxglove::SCHEMA_ENCODING,
                            s.json_schema().as_bytes(),
                        )?;
                        self.foxglove_schemas.insert(s, id);
                        id
                    }
                };
                let view_class = if matches!(s, Schema::RawImage | Schema::Grid) {
                    Class::Bulk
                } else {
                    Class::Small
                };
                let ch = self.writer.add_channel(
                    &format!("{topic}/{}", s.suffix()),
                    schema_id,
                    foxglove::MESSAGE_ENCODING,
                    &[],
                    view_class,
                )?;
                views.push((s, ch));
            }
        }
        self.topics.push(TopicEntry {
            channel,
            is_image: H::schemas().contains(&Schema::RawImage),
            views,
            stats: TopicStats {
                topic: topic.to_string(),
                ..Default::default()
            },
            last_seq: Vec::new(),
        });
        Ok(TopicId(self.topics.len() - 1))
    }

    /// Records one received message at `log_time` (ns, the recorder's clock).
    pub fn write<P, H>(
        &mut self,
        id: TopicId,
        log_time: u64,
        header: &H,
        payload: &P,
    ) -> Result<(), WriteError>
    where
        P: ?Sized + IceoryxSend,
        H: IceoryxSend + Inspect<P> + View<P>,
    {
        let entry = &mut self.topics[id.0];
        let hdr = header.header(payload);
        track_sequence(entry, hdr.source, hdr.seq);
        entry.stats.messages += 1;
        let header_bytes = bytes_of(header);
        let framing = prefix(header_bytes.len());
        self.writer.write(
            entry.channel,
            hdr.seq as u32,
            log_time,
            hdr.stamp_ns,
            &[&framing, header_bytes, bytes_of(payload)],
        )?;
        let stamp = hdr.stamp_ns;
        let subsample = entry.is_image
            && self.opts.image_view_every > 1
            && !(entry.stats.messages - 1).is_multiple_of(self.opts.image_view_every as u64);
        if subsample {
            return Ok(());
        }
        for i in 0..self.topics[id.0].views.len() {
            let (schema, channel) = self.topics[id.0].views[i];
            self.scratch.clear();
            if header.render(payload, schema, &mut self.view_state, &mut self.scratch) {
                let seq = self.topics[id.0].stats.foxglove_messages as u32;
                self.writer
                    .write(channel, seq, log_time, stamp, &[&self.scratch])?;
                self.topics[id.0].stats.foxglove_messages += 1;
            }
        }
        Ok(())
    }

    /// Closes chunks older than the chunk duration (call periodically with the recorder's clock).
    pub fn flush_stale(&mut self, now: u64) -> Result<(), WriteError> {
        self.writer.flush_stale(now)
    }

    pub fn stats(&self) -> impl Iterator<Item = &TopicStats> {
        self.topics.iter().map(|t| &t.stats)
    }

    pub fn finish(&mut self) -> Result<Stats, WriteError> {
        self.writer.finish()
    }

    pub fn position(&self) -> u64 {
        self.writer.position()
    }
}

fn track_sequence(entry: &mut TopicEntry, source: Name, seq: u64) {
    match entry.last_seq.iter_mut().find(|(s, _)| *s == source) {
        Some((_, last)) => {
            if seq > *last {
                entry.stats.dropped += seq - *last - 1;
            } else {
                entry.stats.restarts += 1;
            }
            *last = seq;
        }
        None => entry.last_seq.push((source, seq)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::*;

    #[test]
    fn counts_gaps_and_restarts_per_source() {
        let mut rec = Recording::new(Vec::new(), RecordingOptions::default()).unwrap();
        let id = rec
            .add_topic::<InsState, ()>(topics::INS.name, size_of::<InsState>())
            .unwrap();
        for (seq, src) in [(0, "a"), (1, "a"), (0, "b"), (4, "a"), (1, "b"), (0, "a")] {
            let ins = InsState {
                hdr: Header::new(seq, seq * 10, src),
                ..Default::default()
            };
            rec.write(id, seq, &(), &ins).unwrap();
        }
        let s = rec.stats().next().unwrap().clone();
        assert_eq!((s.messages, s.dropped, s.restarts), (6, 2, 1));
        assert_eq!(s.foxglove_messages, 12);
    }
}
