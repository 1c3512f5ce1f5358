//! Recorder throughput: 2 heads x 1280x960 mono stereo pairs (2.4 MB each) at 10 Hz worth of data,
//! written as fast as possible through the MCAP writer and, in the same run, with a plain
//! `File::write_all` of the same bytes. Files go to the system temp directory and are deleted.
//! Both go through the page cache (no fsync): this measures the writer's own cost.

use crate::mcap::Compression;
use crate::recording::{Recording, RecordingOptions};
use messages::{topics, Header, Name, PixelEncoding, StereoFrameHeader};
use std::io::Write;
use std::time::Instant;

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 960;
const HEADS: usize = 2;
const RATE_HZ: usize = 10;

/// A camera-like image: smooth gradient plus sensor noise (lz4 finds some but not much to remove).
fn frame(seed: u64) -> Vec<u8> {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..2 * (WIDTH * HEIGHT) as usize)
        .map(|i| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let row = (i / WIDTH as usize) % HEIGHT as usize;
            ((row / 8) as u64 + (x & 7)) as u8
        })
        .collect()
}

fn header(seq: u64, head: usize) -> StereoFrameHeader {
    StereoFrameHeader {
        hdr: Header::new(seq, seq * 100_000_000, "bench"),
        head: Name::new(["port", "starboard"][head]),
        width: WIDTH,
        height: HEIGHT,
        stride: WIDTH,
        encoding: PixelEncoding::Mono8 as u32,
    }
}

/// Seconds to write `pairs` frames plainly.
fn plain(frames: &[Vec<u8>], pairs: usize) -> std::io::Result<f64> {
    let mut file = tempfile::tempfile()?;
    let start = Instant::now();
    for i in 0..pairs {
        let h = header(i as u64, i % HEADS);
        file.write_all(messages::recording::bytes_of(&h))?;
        file.write_all(&frames[i % frames.len()])?;
    }
    file.flush()?;
    Ok(start.elapsed().as_secs_f64())
}

/// Seconds to record `pairs` frames, and the file size.
fn recorded(
    frames: &[Vec<u8>],
    pairs: usize,
    opts: RecordingOptions,
) -> anyhow::Result<(f64, u64)> {
    let file = tempfile::tempfile()?;
    let start = Instant::now();
    let mut rec = Recording::new(file, opts)?;
    let id = rec.add_topic::<[u8], StereoFrameHeader>(topics::STEREO_FRAME.name, 1)?;
    for i in 0..pairs {
        let h = header(i as u64, i % HEADS);
        rec.write(id, h.hdr.stamp_ns, &h, frames[i % frames.len()].as_slice())?;
    }
    let stats = rec.finish()?;
    Ok((start.elapsed().as_secs_f64(), stats.bytes))
}

/// Runs the benchmark: `quick` writes 2 s of data (best of 2 rounds), otherwise 10 s (best of 3).
pub fn run(quick: bool) -> Vec<(String, f64, &'static str)> {
    match run_inner(quick) {
        Ok(rows) => rows,
        Err(e) => vec![(format!("recorder bench failed: {e:#}"), f64::NAN, "")],
    }
}

fn run_inner(quick: bool) -> anyhow::Result<Vec<(String, f64, &'static str)>> {
    let (seconds, rounds) = if quick { (2, 2) } else { (10, 3) };
    let pairs = seconds * RATE_HZ * HEADS;
    let frames: Vec<Vec<u8>> = (0..4).map(frame).collect();
    let bytes = (pairs * frames[0].len()) as f64;
    let raw_only = |compression| RecordingOptions {
        writer: crate::mcap::WriterOptions {
            bulk_compression: compression,
            ..Default::default()
        },
        foxglove: false,
        ..Default::default()
    };
    let (mut t_plain, mut t_none, mut t_lz4, mut t_view) = (f64::MAX, f64::MAX, f64::MAX, f64::MAX);
    let mut lz4_size = 0;
    // Interleaved rounds, best of each: the machine is shared and noisy.
    for _ in 0..rounds {
        t_plain = t_plain.min(plain(&frames, pairs)?);
        t_none = t_none.min(recorded(&frames, pairs, raw_only(Compression::None))?.0);
        let (t, size) = recorded(&frames, pairs, raw_only(Compression::Lz4))?;
        (t_lz4, lz4_size) = (t_lz4.min(t), size);
        t_view = t_view.min(recorded(&frames, pairs, RecordingOptions::default())?.0);
    }
    let mbs = |t: f64| bytes / t / 1e6;
    Ok(vec![
        ("plain write_all".into(), mbs(t_plain), "MB/s"),
        ("mcap uncompressed".into(), mbs(t_none), "MB/s"),
        (
            "mcap uncompressed".into(),
            pairs as f64 / t_none,
            "frames/s",
        ),
        (
            "mcap uncompressed / plain (target >= 0.8)".into(),
            t_plain / t_none,
            "x",
        ),
        ("mcap lz4".into(), mbs(t_lz4), "MB/s"),
        ("mcap lz4".into(), pairs as f64 / t_lz4, "frames/s"),
        (
            "mcap lz4 size / raw size".into(),
            lz4_size as f64 / bytes,
            "x",
        ),
        (
            "mcap uncompressed + foxglove image every frame".into(),
            mbs(t_view),
            "MB/s",
        ),
        (
            "needed for 2 heads x 10 Hz".into(),
            (frames[0].len() * HEADS * RATE_HZ) as f64 / 1e6,
            "MB/s",
        ),
    ])
}
