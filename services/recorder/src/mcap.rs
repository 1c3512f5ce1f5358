//! A chunked MCAP writer (https://mcap.dev/spec) with one open chunk per channel class, so images and
//! small messages get their own compression (the `mcap` crate's writer has one compression for the
//! whole file and copies every message into its chunk). Large uncompressed messages are written as a
//! chunk of their own straight from the caller's buffers, without a copy.
//!
//! Crash safety: a chunk is written (and handed to the kernel) as a whole once it reaches
//! `chunk_bytes` or spans `chunk_duration_ns` of log time, so a killed process loses at most the open
//! chunks. The summary (schemas, channels, statistics, chunk indexes) is written by [`Writer::finish`].

use std::collections::BTreeMap;
use std::io::{self, BufWriter, Write};

const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

mod op {
    pub const HEADER: u8 = 0x01;
    pub const FOOTER: u8 = 0x02;
    pub const SCHEMA: u8 = 0x03;
    pub const CHANNEL: u8 = 0x04;
    pub const MESSAGE: u8 = 0x05;
    pub const CHUNK: u8 = 0x06;
    pub const MESSAGE_INDEX: u8 = 0x07;
    pub const CHUNK_INDEX: u8 = 0x08;
    pub const STATISTICS: u8 = 0x0B;
    pub const SUMMARY_OFFSET: u8 = 0x0E;
    pub const DATA_END: u8 = 0x0F;
}

/// Opcode + length + channel id + sequence + log time + publish time.
const MESSAGE_HEADER_LEN: usize = 1 + 8 + 2 + 4 + 8 + 8;

#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    #[error("write failed: {0}")]
    Io(#[from] io::Error),
    #[error("unknown channel id {0}")]
    UnknownChannel(u16),
    #[error("too many {0} (the format allows 65535)")]
    TooMany(&'static str),
    #[error("the writer failed earlier and cannot continue")]
    Failed,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compression {
    #[default]
    None,
    Lz4,
    Zstd,
}

impl Compression {
    /// Name in the chunk record.
    pub fn mcap_name(self) -> &'static str {
        match self {
            Self::None => "",
            Self::Lz4 => "lz4",
            Self::Zstd => "zstd",
        }
    }
}

impl std::str::FromStr for Compression {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "none" => Ok(Self::None),
            "lz4" => Ok(Self::Lz4),
            "zstd" => Ok(Self::Zstd),
            _ => Err(format!("unknown compression {s:?}: use none, lz4 or zstd")),
        }
    }
}

/// Chunk stream of a channel: large (images, grids) or small messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    Bulk = 0,
    Small = 1,
}

#[derive(Debug, Clone)]
pub struct WriterOptions {
    pub bulk_compression: Compression,
    pub small_compression: Compression,
    /// A chunk is closed once its uncompressed records reach this size.
    pub chunk_bytes: usize,
    /// ... or once it spans this much log time (what a crash can lose at most).
    pub chunk_duration_ns: u64,
    /// Uncompressed messages at least this large become a chunk of their own, written without a copy.
    pub direct_bytes: usize,
    pub zstd_level: i32,
    /// Chunk CRCs let a reader detect corrupt data; costs about 0.1 ms per 2.4 MB frame.
    pub chunk_crc: bool,
}

impl Default for WriterOptions {
    fn default() -> Self {
        Self {
            bulk_compression: Compression::None,
            small_compression: Compression::Zstd,
            chunk_bytes: 8 << 20,
            chunk_duration_ns: 500_000_000,
            direct_bytes: 256 << 10,
            zstd_level: 1,
            chunk_crc: true,
        }
    }
}

/// What was written, from [`Writer::finish`].
#[derive(Debug, Clone, Default)]
pub struct Stats {
    pub messages: u64,
    pub chunks: u32,
    pub bytes: u64,
    pub channel_messages: BTreeMap<u16, u64>,
}

/// Little-endian record encoding.
trait Put {
    fn u16(&mut self, v: u16);
    fn u32(&mut self, v: u32);
    fn u64(&mut self, v: u64);
    fn str(&mut self, s: &str);
    /// Starts a record; returns the position to pass to `end_record`.
    fn begin(&mut self, opcode: u8) -> usize;
    fn end_record(&mut self, start: usize);
}

impl Put for Vec<u8> {
    fn u16(&mut self, v: u16) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn str(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.extend_from_slice(s.as_bytes());
    }
    fn begin(&mut self, opcode: u8) -> usize {
        self.push(opcode);
        self.u64(0);
        self.len()
    }
    fn end_record(&mut self, start: usize) {
        let len = (self.len() - start) as u64;
        self[start - 8..start].copy_from_slice(&len.to_le_bytes());
    }
}

fn message_header(
    buf: &mut Vec<u8>,
    channel: u16,
    sequence: u32,
    log_time: u64,
    publish_time: u64,
    data_len: usize,
) {
    buf.push(op::MESSAGE);
    buf.u64((MESSAGE_HEADER_LEN - 9 + data_len) as u64);
    buf.u16(channel);
    buf.u32(sequence);
    buf.u64(log_time);
    buf.u64(publish_time);
}

/// Byte counter in front of the file, for chunk and index offsets.
struct Counting<W: Write> {
    inner: BufWriter<W>,
    pos: u64,
}

impl<W: Write> Counting<W> {
    fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.inner.write_all(bytes)?;
        self.pos += bytes.len() as u64;
        Ok(())
    }
}

/// The open chunk of one class.
#[derive(Default)]
struct OpenChunk {
    compression: Compression,
    records: Vec<u8>,
    /// Channel -> (log time, offset in `records`), kept allocated between chunks.
    index: BTreeMap<u16, Vec<(u64, u64)>>,
    start: u64,
    end: u64,
    messages: usize,
}

struct ChannelEntry {
    class: Class,
}

pub struct Writer<W: Write> {
    out: Counting<W>,
    opts: WriterOptions,
    open: [OpenChunk; 2],
    channels: Vec<ChannelEntry>,
    /// Schema and channel records, repeated in the summary.
    schema_records: Vec<u8>,
    channel_records: Vec<u8>,
    schemas: u16,
    chunk_indexes: Vec<u8>,
    stats: Stats,
    time_bounds: Option<(u64, u64)>,
    scratch: Vec<u8>,
    failed: bool,
    finished: bool,
}

impl<W: Write> Writer<W> {
    pub fn new(out: W, opts: WriterOptions) -> Result<Self, WriteError> {
        let mut out = Counting {
            inner: BufWriter::with_capacity(1 << 20, out),
            pos: 0,
        };
        let mut head = MAGIC.to_vec();
        let start = head.begin(op::HEADER);
        head.str("usv");
        head.str(concat!("usv-recorder ", env!("CARGO_PKG_VERSION")));
        head.end_record(start);
        out.put(&head)?;
        let mut open: [OpenChunk; 2] = Default::default();
        open[Class::Bulk as usize].compression = opts.bulk_compression;
        open[Class::Small as usize].compression = opts.small_compression;
        Ok(Self {
            out,
            opts,
            open,
            channels: Vec::new(),
            schema_records: Vec::new(),
            channel_records: Vec::new(),
            schemas: 0,
            chunk_indexes: Vec::new(),
            stats: Stats::default(),
            time_bounds: None,
            scratch: Vec::new(),
            failed: false,
            finished: false,
        })
    }

    /// Adds a schema and returns its id (ids start at 1; 0 means "no schema").
    pub fn add_schema(
        &mut self,
        name: &str,
        encoding: &str,
        data: &[u8],
    ) -> Result<u16, WriteError> {
        let id = self
            .schemas
            .checked_add(1)
            .ok_or(WriteError::TooMany("schemas"))?;
        let mut rec = Vec::new();
        let start = rec.begin(op::SCHEMA);
        rec.u16(id);
        rec.str(name);
        rec.str(encoding);
        rec.u32(data.len() as u32);
        rec.extend_from_slice(data);
        rec.end_record(start);
        // Written at top level, before any chunk that uses it, so a truncated file still has it.
        self.guard(|w| w.out.put(&rec).map_err(Into::into))?;
        self.schema_records.extend_from_slice(&rec);
        self.schemas = id;
        Ok(id)
    }

    pub fn add_channel(
        &mut self,
        topic: &str,
        schema_id: u16,
        message_encoding: &str,
        metadata: &[(&str, String)],
        class: Class,
    ) -> Result<u16, WriteError> {
        let id = u16::try_from(self.channels.len()).map_err(|_| WriteError::TooMany("channels"))?;
        let mut rec = Vec::new();
        let start = rec.begin(op::CHANNEL);
        rec.u16(id);
        rec.u16(schema_id);
        rec.str(topic);
        rec.str(message_encoding);
        let mut map = Vec::new();
        for (k, v) in metadata {
            map.str(k);
            map.str(v);
        }
        rec.u32(map.len() as u32);
        rec.extend_from_slice(&map);
        rec.end_record(start);
        self.guard(|w| w.out.put(&rec).map_err(Into::into))?;
        self.channel_records.extend_from_slice(&rec);
        self.channels.push(ChannelEntry { class });
        Ok(id)
    }

    /// Marks the writer failed if `f` fails: a half-written record must not be followed by more.
    fn guard<T>(
        &mut self,
        f: impl FnOnce(&mut Self) -> Result<T, WriteError>,
    ) -> Result<T, WriteError> {
        if self.failed || self.finished {
            return Err(WriteError::Failed);
        }
        let result = f(self);
        self.failed = result.is_err();
        result
    }

    /// Writes one message whose data is the concatenation of `parts`. Log times should not decrease
    /// per channel (readers merge chunks by time; within a chunk they keep the written order).
    pub fn write(
        &mut self,
        channel: u16,
        sequence: u32,
        log_time: u64,
        publish_time: u64,
        parts: &[&[u8]],
    ) -> Result<(), WriteError> {
        let class = self
            .channels
            .get(channel as usize)
            .ok_or(WriteError::UnknownChannel(channel))?
            .class;
        self.guard(|w| {
            let len: usize = parts.iter().map(|p| p.len()).sum();
            *w.stats.channel_messages.entry(channel).or_default() += 1;
            w.stats.messages += 1;
            w.time_bounds = Some(match w.time_bounds {
                None => (log_time, log_time),
                Some((a, b)) => (a.min(log_time), b.max(log_time)),
            });
            let c = class as usize;
            if w.open[c].compression == Compression::None && len >= w.opts.direct_bytes {
                w.close_chunk(c)?;
                w.write_direct(channel, sequence, log_time, publish_time, parts, len)?;
            } else {
                let open = &mut w.open[c];
                if open.messages == 0 {
                    open.start = log_time;
                    open.end = log_time;
                }
                open.start = open.start.min(log_time);
                open.end = open.end.max(log_time);
                let offset = open.records.len() as u64;
                open.index
                    .entry(channel)
                    .or_default()
                    .push((log_time, offset));
                message_header(
                    &mut open.records,
                    channel,
                    sequence,
                    log_time,
                    publish_time,
                    len,
                );
                for p in parts {
                    open.records.extend_from_slice(p);
                }
                open.messages += 1;
                if open.records.len() >= w.opts.chunk_bytes {
                    w.close_chunk(c)?;
                }
            }
            w.close_stale(log_time)
        })
    }

    /// Closes chunks that span `chunk_duration_ns` up to `now` (same clock as the log times). Call it
    /// periodically so a quiet channel class does not keep its data in memory.
    pub fn flush_stale(&mut self, now: u64) -> Result<(), WriteError> {
        self.guard(|w| w.close_stale(now))
    }

    fn close_stale(&mut self, now: u64) -> Result<(), WriteError> {
        for c in 0..self.open.len() {
            let o = &self.open[c];
            if o.messages > 0 && now.saturating_sub(o.start) >= self.opts.chunk_duration_ns {
                self.close_chunk(c)?;
            }
        }
        Ok(())
    }

    /// A chunk holding one uncompressed message, written from the caller's buffers.
    fn write_direct(
        &mut self,
        channel: u16,
        sequence: u32,
        log_time: u64,
        publish_time: u64,
        parts: &[&[u8]],
        len: usize,
    ) -> Result<(), WriteError> {
        let mut msg = Vec::with_capacity(MESSAGE_HEADER_LEN);
        message_header(&mut msg, channel, sequence, log_time, publish_time, len);
        let crc = if self.opts.chunk_crc {
            let mut h = crc32fast::Hasher::new();
            h.update(&msg);
            parts.iter().for_each(|p| h.update(p));
            h.finalize()
        } else {
            0
        };
        let records_len = (msg.len() + len) as u64;
        let chunk_start = self.out.pos;
        let mut head = std::mem::take(&mut self.scratch);
        head.clear();
        let rec_start = chunk_header(&mut head, log_time, log_time, records_len, crc, "");
        let n = head.len();
        head[n - 8..n].copy_from_slice(&records_len.to_le_bytes());
        let body_len = (head.len() - rec_start) as u64 + records_len;
        head[rec_start - 8..rec_start].copy_from_slice(&body_len.to_le_bytes());
        head.extend_from_slice(&msg);
        let result = (|| {
            self.out.put(&head)?;
            for p in parts {
                self.out.put(p)?;
            }
            Ok::<_, io::Error>(())
        })();
        self.scratch = head;
        result?;
        let chunk_len = self.out.pos - chunk_start;
        let mut index = BTreeMap::new();
        index.insert(channel, vec![(log_time, 0u64)]);
        self.finish_chunk(
            chunk_start,
            chunk_len,
            (log_time, log_time),
            &index,
            "",
            records_len,
            records_len,
        )
    }

    fn close_chunk(&mut self, c: usize) -> Result<(), WriteError> {
        if self.open[c].messages == 0 {
            return Ok(());
        }
        let mut open = std::mem::take(&mut self.open[c]);
        let records = &open.records;
        let crc = if self.opts.chunk_crc {
            crc32fast::hash(records)
        } else {
            0
        };
        let mut buf = std::mem::take(&mut self.scratch);
        buf.clear();
        let rec_start = chunk_header(
            &mut buf,
            open.start,
            open.end,
            records.len() as u64,
            crc,
            open.compression.mcap_name(),
        );
        let data_start = buf.len();
        match open.compression {
            Compression::None => buf.extend_from_slice(records),
            Compression::Lz4 => {
                let mut enc = lz4::EncoderBuilder::new().level(0).build(buf)?;
                enc.write_all(records)?;
                let (b, r) = enc.finish();
                r?;
                buf = b;
            }
            Compression::Zstd => {
                zstd::stream::copy_encode(&records[..], &mut buf, self.opts.zstd_level)?;
            }
        }
        let compressed = (buf.len() - data_start) as u64;
        buf[data_start - 8..data_start].copy_from_slice(&compressed.to_le_bytes());
        buf.end_record(rec_start);
        let chunk_start = self.out.pos;
        let result = self.out.put(&buf);
        self.scratch = buf;
        result?;
        let chunk_len = self.out.pos - chunk_start;
        let name = open.compression.mcap_name();
        let uncompressed = open.records.len() as u64;
        let bounds = (open.start, open.end);
        let r = self.finish_chunk(
            chunk_start,
            chunk_len,
            bounds,
            &open.index,
            name,
            compressed,
            uncompressed,
        );
        // Keep the buffers for the next chunk of this class.
        open.records.clear();
        open.index.values_mut().for_each(Vec::clear);
        open.messages = 0;
        self.open[c] = open;
        r
    }

    /// Writes the message indexes after a chunk, remembers its chunk index and hands the data to
    /// the kernel (a complete chunk survives the process being killed).
    #[allow(clippy::too_many_arguments)]
    fn finish_chunk(
        &mut self,
        chunk_start: u64,
        chunk_len: u64,
        (start, end): (u64, u64),
        index: &BTreeMap<u16, Vec<(u64, u64)>>,
        compression: &str,
        compressed: u64,
        uncompressed: u64,
    ) -> Result<(), WriteError> {
        let index_start = self.out.pos;
        let mut offsets = Vec::new();
        let mut buf = Vec::new();
        for (&channel, entries) in index.iter().filter(|(_, e)| !e.is_empty()) {
            offsets.push((channel, index_start + buf.len() as u64));
            let s = buf.begin(op::MESSAGE_INDEX);
            buf.u16(channel);
            buf.u32((entries.len() * 16) as u32);
            for &(t, o) in entries {
                buf.u64(t);
                buf.u64(o);
            }
            buf.end_record(s);
        }
        self.out.put(&buf)?;
        self.out.inner.flush()?;

        let ci = &mut self.chunk_indexes;
        let s = ci.begin(op::CHUNK_INDEX);
        ci.u64(start);
        ci.u64(end);
        ci.u64(chunk_start);
        ci.u64(chunk_len);
        ci.u32((offsets.len() * 10) as u32);
        for (channel, offset) in offsets {
            ci.u16(channel);
            ci.u64(offset);
        }
        ci.u64(buf.len() as u64);
        ci.str(compression);
        ci.u64(compressed);
        ci.u64(uncompressed);
        ci.end_record(s);
        self.stats.chunks += 1;
        Ok(())
    }

    /// Closes the open chunks and writes data end, summary, summary offsets and footer.
    pub fn finish(&mut self) -> Result<Stats, WriteError> {
        self.guard(|w| {
            for c in 0..w.open.len() {
                w.close_chunk(c)?;
            }
            let mut tail = Vec::new();
            let s = tail.begin(op::DATA_END);
            tail.u32(0);
            tail.end_record(s);
            w.out.put(&tail)?;

            let summary_start = w.out.pos;
            let mut summary = Vec::new();
            let mut groups = Vec::new();
            let mut group = |summary: &mut Vec<u8>, opcode: u8, bytes: &[u8]| {
                if !bytes.is_empty() {
                    groups.push((
                        opcode,
                        summary_start + summary.len() as u64,
                        bytes.len() as u64,
                    ));
                    summary.extend_from_slice(bytes);
                }
            };
            group(&mut summary, op::SCHEMA, &w.schema_records);
            group(&mut summary, op::CHANNEL, &w.channel_records);
            let (t0, t1) = w.time_bounds.unwrap_or((0, 0));
            let mut st = Vec::new();
            let s = st.begin(op::STATISTICS);
            st.u64(w.stats.messages);
            st.u16(w.schemas);
            st.u32(w.channels.len() as u32);
            st.u32(0); // attachments
            st.u32(0); // metadata
            st.u32(w.stats.chunks);
            st.u64(t0);
            st.u64(t1);
            st.u32((w.stats.channel_messages.len() * 10) as u32);
            for (&c, &n) in &w.stats.channel_messages {
                st.u16(c);
                st.u64(n);
            }
            st.end_record(s);
            group(&mut summary, op::STATISTICS, &st);
            group(&mut summary, op::CHUNK_INDEX, &w.chunk_indexes);
            let offsets_start = summary_start + summary.len() as u64;
            for (opcode, start, len) in groups {
                let s = summary.begin(op::SUMMARY_OFFSET);
                summary.push(opcode);
                summary.u64(start);
                summary.u64(len);
                summary.end_record(s);
            }
            // Footer; its CRC covers the summary and the footer up to this field.
            let mut footer = Vec::new();
            let s = footer.begin(op::FOOTER);
            footer.u64(summary_start);
            footer.u64(offsets_start);
            let mut h = crc32fast::Hasher::new();
            h.update(&summary);
            h.update(&footer);
            footer.u32(h.finalize());
            footer.end_record(s);
            footer.extend_from_slice(MAGIC);
            w.out.put(&summary)?;
            w.out.put(&footer)?;
            w.out.inner.flush()?;
            w.stats.bytes = w.out.pos;
            Ok(())
        })?;
        self.finished = true;
        Ok(self.stats.clone())
    }

    /// Bytes written so far.
    pub fn position(&self) -> u64 {
        self.out.pos
    }

    pub fn get_ref(&self) -> &W {
        self.out.inner.get_ref()
    }
}

impl<W: Write> Drop for Writer<W> {
    /// A writer dropped without `finish` (an error path) still leaves a complete file when it can.
    fn drop(&mut self) {
        if !self.finished && !self.failed {
            let _ = self.finish();
        }
    }
}

/// Chunk record up to and including the records length (left 0 for the caller to patch); returns
/// the record body start for `end_record`.
fn chunk_header(
    buf: &mut Vec<u8>,
    start: u64,
    end: u64,
    uncompressed: u64,
    crc: u32,
    compression: &str,
) -> usize {
    let s = buf.begin(op::CHUNK);
    buf.u64(start);
    buf.u64(end);
    buf.u64(uncompressed);
    buf.u32(crc);
    buf.str(compression);
    buf.u64(0);
    s
}
