//! Real processes: record known messages with the `recorder` binary, replay them with `sensors
//! replay` and compare bytes; a killed recorder; corrupt files.

mod common;

use common::*;
use messages::recording::{bytes_of, split};
use messages::*;
use runtime::{Ports, Receive};
use sensors::{ReadError, Recording};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

/// Topic -> framed bytes of every recorded message, in order.
fn recorded(path: &Path) -> BTreeMap<String, Vec<Vec<u8>>> {
    let rec = Recording::open(path).unwrap();
    assert!(rec.truncation().is_none(), "{:?}", rec.truncation());
    let topic_of: BTreeMap<u16, String> = rec.channels().map(|c| (c.id, c.topic.clone())).collect();
    let mut out: BTreeMap<String, Vec<Vec<u8>>> = BTreeMap::new();
    for m in rec.messages(0, |_| true) {
        let m = m.unwrap();
        out.entry(topic_of[&m.channel].clone())
            .or_default()
            .push(m.data);
    }
    out
}

fn framed(header: &[u8], payload: &[u8]) -> Vec<u8> {
    let mut v = messages::recording::prefix(header.len()).to_vec();
    v.extend_from_slice(header);
    v.extend_from_slice(payload);
    v
}

fn record_known(d: &Domain, out: &Path, extra: &[&str]) {
    let mut sender = Sender::new(d);
    let child = start_recorder(d, &sender, out, extra);
    sender.send_all();
    std::thread::sleep(Duration::from_millis(200));
    check_report(&stop_recorder(child));
}

#[test]
fn record_then_replay_is_byte_identical() {
    let _serial = common::serial();
    let d = Domain::new();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    record_known(&d, &file, &[]);

    // The file holds what was sent (fields checked through the recorded bytes).
    let rec = recorded(&file);
    let counts: Vec<usize> = TOPICS.iter().map(|t| rec[*t].len()).collect();
    assert_eq!(counts, COUNTS.map(|c| c as usize));
    for (k, data) in rec[topics::STEREO_FRAME.name].iter().enumerate() {
        let (h, p) = split(data).unwrap();
        let (want_h, want_p) = stereo(k as u64);
        let got: StereoFrameHeader = unsafe { std::ptr::read_unaligned(h.as_ptr().cast()) };
        assert_eq!(
            (got.hdr, got.width, got.head),
            (want_h.hdr, want_h.width, want_h.head)
        );
        assert_eq!(p, want_p.as_slice());
    }
    for (k, data) in rec[topics::INS.name].iter().enumerate() {
        let (h, p) = split(data).unwrap();
        assert!(h.is_empty());
        let got: InsState = unsafe { std::ptr::read_unaligned(p.as_ptr().cast()) };
        assert_eq!((got.hdr, got.pose), (ins(k as u64).hdr, ins(k as u64).pose));
    }
    for (k, data) in rec[topics::LOCAL_MAP.name].iter().enumerate() {
        let (_, p) = split(data).unwrap();
        assert_eq!(p, bytes_of(local_map(k as u64).1.as_slice()));
    }

    // Replay: subscribe first, then collect everything the replayer publishes.
    let subs = (
        topics::STEREO_FRAME.subscriber(d.node()).unwrap(),
        topics::INS.subscriber(d.node()).unwrap(),
        topics::CONTACTS.subscriber(d.node()).unwrap(),
        topics::LOCAL_MAP.subscriber(d.node()).unwrap(),
    );
    let mut child = d
        .command(&bin("sensors"))
        .arg("replay")
        .arg(&file)
        .args(["--rate", "2", "--topics", &TOPICS.join(",")])
        .spawn()
        .unwrap();
    let mut got: BTreeMap<&str, Vec<Vec<u8>>> = BTreeMap::new();
    let end = Instant::now() + Duration::from_secs(30);
    let mut exited_at = None;
    while Instant::now() < end
        && exited_at.is_none_or(|t: Instant| t.elapsed() < Duration::from_millis(300))
    {
        if exited_at.is_none() && child.try_wait().unwrap().is_some() {
            exited_at = Some(Instant::now());
        }
        while let Some(b) = subs
            .0
            .receive_with(|h, p| framed(bytes_of(h), bytes_of(p)))
            .unwrap()
        {
            got.entry(TOPICS[0]).or_default().push(b);
        }
        while let Some(b) = subs
            .1
            .receive_with(|h, p| framed(bytes_of(h), bytes_of(p)))
            .unwrap()
        {
            got.entry(TOPICS[1]).or_default().push(b);
        }
        while let Some(b) = subs
            .2
            .receive_with(|h, p| framed(bytes_of(h), bytes_of(p)))
            .unwrap()
        {
            got.entry(TOPICS[2]).or_default().push(b);
        }
        while let Some(b) = subs
            .3
            .receive_with(|h, p| framed(bytes_of(h), bytes_of(p)))
            .unwrap()
        {
            got.entry(TOPICS[3]).or_default().push(b);
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let status = child.wait().unwrap();
    assert!(status.success(), "sensors replay failed: {status:?}");
    for t in TOPICS {
        assert_eq!(
            got.get(t).map_or(0, Vec::len),
            rec[t].len(),
            "{t}: replayed count"
        );
        assert!(
            got[t] == rec[t],
            "{t}: replayed bytes differ from the recording"
        );
    }
}

/// Sequence numbers of a recording's INS samples, or the first read error.
fn ins_seqs(rec: Recording) -> Result<Vec<u32>, ReadError> {
    let Some(ins_id) = rec
        .channels()
        .find(|c| c.topic == topics::INS.name)
        .map(|c| c.id)
    else {
        return Ok(Vec::new());
    };
    rec.messages(0, |_| true)
        .filter_map(|m| match m {
            Ok(m) => (m.channel == ins_id).then_some(Ok(m.sequence)),
            Err(e) => Some(Err(e)),
        })
        .collect()
}

#[test]
fn killed_recorder_leaves_a_readable_file() {
    let _serial = common::serial();
    let d = Domain::new();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("killed.mcap");
    let mut sender = Sender::new(&d);
    let child = start_recorder(&d, &sender, &file, &["--chunk-seconds", "0.1"]);
    sender.send_all();
    // Chunks close every 0.1 s: wait until the last INS sample is on disk (a loaded machine may
    // take longer than the nominal 0.2 s), then kill.
    let on_disk = || {
        let rec = Recording::open(&file).ok()?;
        ins_seqs(rec).ok().map(|seqs| seqs.len())
    };
    let deadline = Instant::now() + Duration::from_secs(10);
    while on_disk().unwrap_or(0) < 50 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(50));
    }
    signal(&child, libc::SIGKILL);
    let _ = child.wait_with_output();
    let len = std::fs::metadata(&file).unwrap().len();

    let check = |path: &Path, expect_offset: u64| {
        let rec = Recording::open(path).unwrap();
        let t = rec
            .truncation()
            .expect("a killed recorder's file has no end")
            .clone();
        assert_eq!(t.offset, expect_offset, "{t:?}");
        assert_eq!(ins_seqs(rec).unwrap(), (0..50).collect::<Vec<u32>>());
    };
    check(&file, len);
    // Killed in the middle of writing a chunk: that chunk is cut off, everything before it is read.
    let mut bytes = std::fs::read(&file).unwrap();
    bytes.extend_from_slice(&[0x06, 0, 0, 16, 0, 0, 0, 0, 0, 1, 2, 3]);
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes).unwrap();
    check(&cut, len);
}

/// Opens and reads a whole file; the error if any.
fn read_all(path: &Path) -> Result<usize, ReadError> {
    let rec = Recording::open(path)?;
    let mut n = 0;
    for m in rec.messages(0, |_| true) {
        m?;
        n += 1;
    }
    Ok(n)
}

#[test]
fn corrupt_files_give_errors_with_offsets() {
    let d = Domain::new();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("good.mcap");
    // Short chunks, so a cut in the middle leaves complete chunks before it.
    record_known(&d, &file, &["--chunk-seconds", "0.1"]);
    let good = std::fs::read(&file).unwrap();
    let total: u64 = COUNTS.iter().sum();
    assert_eq!(read_all(&file).unwrap() as u64, total);
    let bad = dir.path().join("bad.mcap");
    let with = |bytes: &[u8]| {
        std::fs::write(&bad, bytes).unwrap();
        read_all(&bad)
    };

    // Not an MCAP file at all.
    let e = with(b"hello").unwrap_err();
    assert!(matches!(e, ReadError::NotMcap { offset: 0, .. }), "{e}");

    // A flipped byte in the payload of a stereo frame (the largest messages) fails the chunk CRC.
    let needle = &stereo(5).1[100..140];
    let at = good
        .windows(needle.len())
        .position(|w| w == needle)
        .expect("frame bytes in file");
    let mut b = good.clone();
    b[at] ^= 0xff;
    let e = with(&b).unwrap_err();
    assert!(matches!(e, ReadError::Crc { .. }), "{e}");
    assert!(e.to_string().contains("offset"), "{e}");

    // A record header turned into garbage.
    let mut b = good.clone();
    let first_record = 8;
    let header_len =
        u64::from_le_bytes(b[first_record + 1..first_record + 9].try_into().unwrap()) as usize;
    b[first_record + 9 + header_len] = 0x42;
    let e = with(&b).unwrap_err();
    assert!(
        matches!(e, ReadError::Corrupt { offset, .. } if offset == (first_record + 9 + header_len) as u64),
        "{e}"
    );

    // Truncated: every complete chunk before the cut, and where it stopped.
    let cut = good.len() / 2;
    std::fs::write(&bad, &good[..cut]).unwrap();
    let rec = Recording::open(&bad).unwrap();
    let t = rec.truncation().unwrap().clone();
    assert!(t.offset <= cut as u64 && t.file_len == cut as u64, "{t:?}");
    let n = read_all(&bad).unwrap();
    assert!(n > 0 && (n as u64) < total, "{n}");

    // No byte flip anywhere panics.
    for i in (0..good.len()).step_by(good.len() / 200 + 1) {
        let mut b = good.clone();
        b[i] ^= 0x5a;
        let _ = with(&b);
    }
}
