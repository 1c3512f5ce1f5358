//! Files written by the recorder library read back with the `mcap` crate's own reader: channels,
//! schemas, counts, chunk indexes and the exact replay bytes.

use messages::recording::{bytes_of, split, RAW_ENCODING};
use messages::*;
use recorder::{Compression, Recording, RecordingOptions, WriterOptions};
use std::collections::BTreeMap;

fn stereo(seq: u64) -> (StereoFrameHeader, Vec<u8>) {
    let h = StereoFrameHeader {
        hdr: Header::new(seq, 1_000 + seq, "port"),
        head: Name::new("port"),
        width: 640,
        height: 480,
        stride: 640,
        encoding: PixelEncoding::Mono8 as u32,
    };
    (
        h,
        (0..h.payload_len())
            .map(|i| (i as u64 * 7 + seq) as u8)
            .collect(),
    )
}

fn ins(seq: u64) -> InsState {
    InsState {
        hdr: Header::new(seq, 1_000 + seq, "ins"),
        ..Default::default()
    }
}

/// 30 INS messages and 10 stereo frames (Foxglove image for every 2nd frame).
fn record_file(image: Compression, small: Compression) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.mcap");
    let file = std::fs::File::create(&path).unwrap();
    let opts = RecordingOptions {
        writer: WriterOptions {
            bulk_compression: image,
            small_compression: small,
            chunk_bytes: 1 << 20,
            ..Default::default()
        },
        image_view_every: 2,
        ..Default::default()
    };
    let mut rec = Recording::new(file, opts).unwrap();
    let s = rec
        .add_topic::<[u8], StereoFrameHeader>(topics::STEREO_FRAME.name, 1)
        .unwrap();
    let i = rec
        .add_topic::<InsState, ()>(topics::INS.name, size_of::<InsState>())
        .unwrap();
    for k in 0..30u64 {
        rec.write(i, 10 * k, &(), &ins(k)).unwrap();
        if k % 3 == 0 {
            let (h, p) = stereo(k / 3);
            rec.write(s, 10 * k + 1, &h, p.as_slice()).unwrap();
        }
    }
    rec.finish().unwrap();
    drop(rec);
    std::fs::read(&path).unwrap()
}

#[test]
fn mcap_crate_reads_every_compression() {
    for (image, small) in [
        (Compression::None, Compression::Zstd),
        (Compression::Lz4, Compression::Lz4),
        (Compression::None, Compression::None),
    ] {
        let bytes = record_file(image, small);
        let summary = mcap::read::Summary::read(&bytes).unwrap().expect("summary");
        let stats = summary.stats.as_ref().expect("statistics");
        // 30 ins + 30 fix + 30 tf + 10 frames + 5 images.
        assert_eq!(stats.message_count, 105, "{image:?}/{small:?}");
        assert!(!summary.chunk_indexes.is_empty());
        let mut counts = BTreeMap::new();
        let mut schemas = BTreeMap::new();
        for m in mcap::read::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap_or_else(|e| panic!("{image:?}/{small:?}: {e}"));
            *counts.entry(m.channel.topic.clone()).or_insert(0) += 1;
            let schema = m.channel.schema.as_ref().unwrap();
            schemas.insert(m.channel.topic.clone(), schema.name.clone());
            if m.channel.topic == topics::STEREO_FRAME.name {
                assert_eq!(m.channel.message_encoding, RAW_ENCODING);
                let (h, p) = split(&m.data).unwrap();
                let (want_h, want_p) = stereo(m.sequence as u64);
                assert_eq!(h, bytes_of(&want_h));
                assert_eq!(p, want_p.as_slice());
                assert_eq!(m.publish_time, want_h.hdr.stamp_ns);
            }
            if m.channel.topic == "usv/sensors/stereo_frame/image" {
                let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
                assert_eq!(v["width"], 640);
            }
        }
        assert_eq!(counts[topics::STEREO_FRAME.name], 10);
        assert_eq!(counts[topics::INS.name], 30);
        assert_eq!(counts["usv/sensors/ins/fix"], 30);
        assert_eq!(counts["usv/sensors/stereo_frame/image"], 5);
        assert_eq!(schemas[topics::STEREO_FRAME.name], "usv.StereoFrame.v1");
        assert_eq!(schemas["usv/sensors/ins/tf"], "foxglove.FrameTransform");

        // Seeking by time through the chunk and message indexes.
        let ins_channel = summary
            .channels
            .values()
            .find(|c| c.topic == topics::INS.name)
            .unwrap()
            .id;
        let mut seen = 0;
        for chunk in &summary.chunk_indexes {
            let idx = summary.read_message_indexes(&bytes, chunk).unwrap();
            for (channel, entries) in idx {
                if channel.id == ins_channel {
                    for e in entries {
                        let m = summary.seek_message(&bytes, chunk, &e).unwrap();
                        assert_eq!(m.log_time, e.log_time);
                        seen += 1;
                    }
                }
            }
        }
        assert_eq!(seen, 30);
    }
}

#[test]
#[ignore = "benchmark: cargo test --release -p recorder --test mcap_conformance -- --ignored --nocapture (BENCH_FULL=1 for the long run)"]
fn bench() {
    let quick = std::env::var_os("BENCH_FULL").is_none();
    for (name, value, unit) in recorder::bench::run(quick) {
        println!("{name:<50} {value:>10.2} {unit}");
    }
}
