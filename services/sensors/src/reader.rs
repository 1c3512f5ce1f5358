//! Reads the replay channels of a recording (see `messages::recording`) in log-time order, with seek
//! and a recovery mode for files whose writer was killed.
//!
//! Opening scans the top-level records (chunk headers only, no chunk data), so it is fast on large
//! files and works the same with or without a summary section: a truncated file yields every complete
//! chunk and [`Recording::truncation`] says where it stopped. Chunk data is decompressed and its CRC
//! checked when the iterator reaches it.

use messages::recording::RAW_ENCODING;
use std::collections::{BTreeMap, BinaryHeap};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";
/// Opcode + length.
const RECORD_PREFIX: u64 = 9;

mod op {
    pub use mcap::records::op::*;
}

#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not an MCAP file (bad magic at offset {offset})")]
    NotMcap { path: PathBuf, offset: u64 },
    #[error("{path}: corrupt record at offset {offset}: {what}")]
    Corrupt {
        path: PathBuf,
        offset: u64,
        what: String,
    },
    #[error("{path}: chunk at offset {offset} fails its CRC (stored {stored:#010x}, computed {computed:#010x})")]
    Crc {
        path: PathBuf,
        offset: u64,
        stored: u32,
        computed: u32,
    },
}

/// Where and why reading a file without a proper end stopped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Truncation {
    /// Offset of the first incomplete record; everything before it was read.
    pub offset: u64,
    pub file_len: u64,
    pub reason: String,
}

/// A replay channel.
#[derive(Debug, Clone)]
pub struct Channel {
    pub id: u16,
    pub topic: String,
    /// Versioned type name, e.g. `usv.StereoFrame.v1`.
    pub type_name: String,
}

#[derive(Debug, Clone)]
struct ChunkRef {
    offset: u64,
    start: u64,
    end: u64,
    compression: String,
    uncompressed_size: u64,
    crc: u32,
    /// Offset and length of the (compressed) records.
    data: (u64, u64),
    /// Channels with messages in the chunk, from its message indexes (empty: unknown).
    channels: Vec<u16>,
}

/// One recorded message of a replay channel.
#[derive(Debug, Clone)]
pub struct Message {
    pub log_time: u64,
    /// Sensor stamp of the message (`Header::stamp_ns`).
    pub publish_time: u64,
    pub sequence: u32,
    pub channel: u16,
    /// Framed bytes: split with `messages::recording::split`.
    pub data: Vec<u8>,
}

/// The most a chunk may hold uncompressed: a corrupt size field must not make the reader allocate
/// terabytes. Chunks span 0.5 s of log by default; a recorded closed-loop run with two 640x480
/// heads writes about 18 MB a second.
const MAX_CHUNK_BYTES: u64 = 1 << 30;

pub struct Recording {
    path: PathBuf,
    file: File,
    schema_names: BTreeMap<u16, String>,
    channels: BTreeMap<u16, Channel>,
    chunks: Vec<ChunkRef>,
    truncation: Option<Truncation>,
}

impl Recording {
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let io = |source| ReadError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut file = File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        let mut magic = [0u8; 8];
        if len < 8 || file.read_exact(&mut magic).is_err() || &magic != MAGIC {
            return Err(ReadError::NotMcap {
                path: path.to_path_buf(),
                offset: 0,
            });
        }
        let mut rec = Self {
            path: path.to_path_buf(),
            file,
            schema_names: BTreeMap::new(),
            channels: BTreeMap::new(),
            chunks: Vec::new(),
            truncation: None,
        };
        rec.scan(len)?;
        Ok(rec)
    }

    fn corrupt(&self, offset: u64, what: impl Into<String>) -> ReadError {
        ReadError::Corrupt {
            path: self.path.clone(),
            offset,
            what: what.into(),
        }
    }

    fn io(&self, source: std::io::Error) -> ReadError {
        ReadError::Io {
            path: self.path.clone(),
            source,
        }
    }

    fn read_at(&mut self, offset: u64, len: u64) -> Result<Vec<u8>, ReadError> {
        let mut buf = vec![0; len as usize];
        self.file
            .seek(SeekFrom::Start(offset))
            .and_then(|_| self.file.read_exact(&mut buf))
            .map_err(|e| self.io(e))?;
        Ok(buf)
    }

    /// Walks the data section record by record. A finished file (magic at the end) must be intact;
    /// a file without one was cut short, and reading stops at its first incomplete record.
    fn scan(&mut self, len: u64) -> Result<(), ReadError> {
        let finished = len >= 16 && self.read_at(len - 8, 8)? == MAGIC;
        let mut pos = 8;
        loop {
            let stop = |reason: &str| Truncation {
                offset: pos,
                file_len: len,
                reason: reason.to_string(),
            };
            if pos + RECORD_PREFIX > len {
                if finished {
                    return Err(self.corrupt(pos, "data section runs into the end of the file"));
                }
                self.truncation = Some(stop(if pos == len {
                    "file ends after a complete record"
                } else {
                    "incomplete record header"
                }));
                return Ok(());
            }
            let prefix = self.read_at(pos, RECORD_PREFIX)?;
            let opcode = prefix[0];
            let body_len = u64::from_le_bytes(prefix[1..9].try_into().expect("8 bytes"));
            let body_start = pos + RECORD_PREFIX;
            if body_len > len - body_start {
                if finished {
                    return Err(self.corrupt(
                        pos,
                        format!("record length {body_len} runs past the end of the file"),
                    ));
                }
                self.truncation = Some(stop(
                    "incomplete record (the writer was stopped while writing it)",
                ));
                return Ok(());
            }
            match opcode {
                op::SCHEMA | op::CHANNEL => {
                    let body = self.read_at(body_start, body_len)?;
                    self.add_definition(pos, opcode, &body)?;
                }
                op::CHUNK => self.add_chunk(pos, body_start, body_len)?,
                op::MESSAGE_INDEX => {
                    let body = self.read_at(body_start, body_len.min(2))?;
                    if let (Some(chunk), Ok(id)) =
                        (self.chunks.last_mut(), body.as_slice().try_into())
                    {
                        chunk.channels.push(u16::from_le_bytes(id));
                    }
                }
                op::DATA_END | op::FOOTER => return Ok(()),
                op::HEADER
                | op::CHUNK_INDEX
                | op::ATTACHMENT
                | op::ATTACHMENT_INDEX
                | op::STATISTICS
                | op::METADATA
                | op::METADATA_INDEX
                | op::SUMMARY_OFFSET => {}
                op::MESSAGE => {
                    return Err(
                        self.corrupt(pos, "message outside a chunk (not written by the recorder)")
                    )
                }
                o if o >= 0x80 => {} // private records
                o => return Err(self.corrupt(pos, format!("unknown opcode {o:#04x}"))),
            }
            pos = body_start + body_len;
        }
    }

    fn add_definition(&mut self, pos: u64, opcode: u8, body: &[u8]) -> Result<(), ReadError> {
        match mcap::read::parse_record(opcode, body) {
            Ok(mcap::records::Record::Schema { header, .. }) => {
                self.schema_names.insert(header.id, header.name);
            }
            Ok(mcap::records::Record::Channel(c)) => {
                if c.message_encoding == RAW_ENCODING {
                    let type_name = self
                        .schema_names
                        .get(&c.schema_id)
                        .cloned()
                        .unwrap_or_default();
                    self.channels.insert(
                        c.id,
                        Channel {
                            id: c.id,
                            topic: c.topic,
                            type_name,
                        },
                    );
                }
            }
            Ok(_) => {}
            Err(e) => return Err(self.corrupt(pos, format!("bad schema or channel record: {e}"))),
        }
        Ok(())
    }

    fn add_chunk(&mut self, pos: u64, body_start: u64, body_len: u64) -> Result<(), ReadError> {
        // Fixed fields, the compression name (short), then the records length.
        let head = self.read_at(body_start, body_len.min(8 * 3 + 4 + 4 + 64 + 8))?;
        let u64_at = |o: usize| {
            head.get(o..o + 8)
                .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
        };
        let u32_at = |o: usize| {
            head.get(o..o + 4)
                .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
        };
        let parsed = (|| {
            let (start, end, size) = (u64_at(0)?, u64_at(8)?, u64_at(16)?);
            let crc = u32_at(24)?;
            let name_len = u32_at(28)? as usize;
            let name = std::str::from_utf8(head.get(32..32 + name_len)?)
                .ok()?
                .to_string();
            let data_len = u64_at(32 + name_len)?;
            let data_start = (32 + name_len + 8) as u64;
            (data_start.checked_add(data_len)? <= body_len).then_some(ChunkRef {
                offset: pos,
                start,
                end,
                compression: name,
                uncompressed_size: size,
                crc,
                data: (body_start + data_start, data_len),
                channels: Vec::new(),
            })
        })();
        let chunk = parsed.ok_or_else(|| self.corrupt(pos, "bad chunk header"))?;
        if !matches!(chunk.compression.as_str(), "" | "lz4" | "zstd") {
            return Err(self.corrupt(pos, format!("unknown compression {:?}", chunk.compression)));
        }
        self.chunks.push(chunk);
        Ok(())
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// `Some` if the file has no proper end (its writer was killed): what was read and where it stopped.
    pub fn truncation(&self) -> Option<&Truncation> {
        self.truncation.as_ref()
    }

    pub fn channels(&self) -> impl Iterator<Item = &Channel> {
        self.channels.values()
    }

    pub fn channel(&self, id: u16) -> Option<&Channel> {
        self.channels.get(&id)
    }

    /// First and last log time (ns) of the complete chunks.
    pub fn time_range(&self) -> Option<(u64, u64)> {
        let start = self.chunks.iter().map(|c| c.start).min()?;
        let end = self.chunks.iter().map(|c| c.end).max()?;
        Some((start, end))
    }

    /// Messages of the replay channels whose topic `want` accepts, from log time `from` on, in
    /// log-time order (messages with equal times keep their written order).
    pub fn messages(self, from: u64, want: impl Fn(&str) -> bool) -> Messages {
        let wanted: Vec<u16> = self
            .channels
            .values()
            .filter(|c| want(&c.topic))
            .map(|c| c.id)
            .collect();
        let mut messages = Messages {
            rec: self,
            order: Vec::new(),
            next: 0,
            from,
            wanted,
            pending: BinaryHeap::new(),
            counter: 0,
        };
        messages.rewind();
        messages
    }

    /// Decompresses a chunk, checks its CRC and returns its messages of `wanted` channels.
    fn load(&mut self, index: usize, from: u64, wanted: &[u16]) -> Result<Vec<Message>, ReadError> {
        let chunk = self.chunks[index].clone();
        if chunk.uncompressed_size > MAX_CHUNK_BYTES {
            return Err(self.corrupt(
                chunk.offset,
                format!(
                    "chunk header says {} bytes uncompressed, over the {MAX_CHUNK_BYTES} a chunk may hold",
                    chunk.uncompressed_size
                ),
            ));
        }
        let raw = self.read_at(chunk.data.0, chunk.data.1)?;
        let size = chunk.uncompressed_size as usize;
        let records = match chunk.compression.as_str() {
            "" => raw,
            "lz4" => {
                let mut out = Vec::with_capacity(size);
                lz4::Decoder::new(raw.as_slice())
                    .and_then(|mut d| d.read_to_end(&mut out))
                    .map_err(|e| {
                        self.corrupt(chunk.offset, format!("lz4 chunk does not decompress: {e}"))
                    })?;
                out
            }
            _ => zstd::bulk::decompress(&raw, size).map_err(|e| {
                self.corrupt(chunk.offset, format!("zstd chunk does not decompress: {e}"))
            })?,
        };
        if records.len() != size {
            return Err(self.corrupt(
                chunk.offset,
                format!(
                    "chunk holds {} bytes, its header says {size}",
                    records.len()
                ),
            ));
        }
        if chunk.crc != 0 {
            let computed = crc32fast::hash(&records);
            if computed != chunk.crc {
                return Err(ReadError::Crc {
                    path: self.path.clone(),
                    offset: chunk.offset,
                    stored: chunk.crc,
                    computed,
                });
            }
        }
        let mut out = Vec::new();
        let mut pos = 0usize;
        while pos < records.len() {
            let bad = |what: &str| {
                self.corrupt(
                    chunk.offset,
                    format!("{what} at byte {pos} of the chunk's records"),
                )
            };
            let prefix = records
                .get(pos..pos + 9)
                .ok_or_else(|| bad("incomplete record"))?;
            let len = u64::from_le_bytes(prefix[1..9].try_into().expect("8 bytes")) as usize;
            let body = records
                .get(pos + 9..(pos + 9).saturating_add(len))
                .ok_or_else(|| bad("record overruns the chunk"))?;
            if prefix[0] == op::MESSAGE {
                let header = body.get(..22).ok_or_else(|| bad("short message record"))?;
                let channel = u16::from_le_bytes([header[0], header[1]]);
                let log_time = u64::from_le_bytes(header[6..14].try_into().expect("8 bytes"));
                if wanted.contains(&channel) && log_time >= from {
                    out.push(Message {
                        log_time,
                        publish_time: u64::from_le_bytes(
                            header[14..22].try_into().expect("8 bytes"),
                        ),
                        sequence: u32::from_le_bytes(header[2..6].try_into().expect("4 bytes")),
                        channel,
                        data: body[22..].to_vec(),
                    });
                }
            }
            pos += 9 + len;
        }
        Ok(out)
    }
}

/// A message waiting in the merge of overlapping chunks, ordered by (log time, arrival).
struct Pending(Message, u64);

impl PartialEq for Pending {
    fn eq(&self, other: &Self) -> bool {
        self.key() == other.key()
    }
}
impl Eq for Pending {}
impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Pending {
    /// Reversed: `BinaryHeap` is a max-heap and the earliest message must come out first.
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        other.key().cmp(&self.key())
    }
}
impl Pending {
    fn key(&self) -> (u64, u64) {
        (self.0.log_time, self.1)
    }
}

/// Iterator over messages in log-time order. Chunks of different channel classes overlap in time,
/// so a chunk is loaded once the earliest pending message is not earlier than its start.
pub struct Messages {
    rec: Recording,
    order: Vec<usize>,
    next: usize,
    from: u64,
    wanted: Vec<u16>,
    pending: BinaryHeap<Pending>,
    counter: u64,
}

impl Messages {
    pub fn recording(&self) -> &Recording {
        &self.rec
    }

    /// Starts again from the first message (at or after `from`).
    pub fn rewind(&mut self) {
        let chunks = &self.rec.chunks;
        self.order = (0..chunks.len())
            .filter(|&i| {
                let c = &chunks[i];
                c.end >= self.from
                    && (c.channels.is_empty()
                        || c.channels.iter().any(|id| self.wanted.contains(id)))
            })
            .collect();
        self.order.sort_by_key(|&i| (chunks[i].start, i));
        self.next = 0;
        self.pending.clear();
    }
}

impl Iterator for Messages {
    type Item = Result<Message, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        while self.next < self.order.len() {
            let chunk_start = self.rec.chunks[self.order[self.next]].start;
            if self
                .pending
                .peek()
                .is_some_and(|p| p.0.log_time < chunk_start)
            {
                break;
            }
            let index = self.order[self.next];
            self.next += 1;
            match self.rec.load(index, self.from, &self.wanted) {
                Ok(messages) => {
                    for m in messages {
                        self.pending.push(Pending(m, self.counter));
                        self.counter += 1;
                    }
                }
                Err(e) => {
                    // Stop here: the caller decides whether to go on without this chunk.
                    self.order.clear();
                    self.pending.clear();
                    return Some(Err(e));
                }
            }
        }
        self.pending.pop().map(|p| Ok(p.0))
    }
}
