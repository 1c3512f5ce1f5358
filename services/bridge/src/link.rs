//! Framing of one message on the cross-host link: the same bytes a recording holds
//! (`messages::recording`: u32 LE user-header length | user header | payload), so the receiving side
//! republishes exactly what was published, with the replay code path's length checks.

pub use messages::recording::split;

/// Writes the frame of (`header`, `payload`) into `out`, replacing its contents.
pub fn frame(header: &[u8], payload: &[u8], out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&messages::recording::prefix(header.len()));
    out.extend_from_slice(header);
    out.extend_from_slice(payload);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_round_trip() {
        let mut out = vec![1, 2, 3];
        frame(b"head", b"payload", &mut out);
        assert_eq!(split(&out), Some((&b"head"[..], &b"payload"[..])));
        frame(b"", b"fixed", &mut out);
        assert_eq!(split(&out), Some((&b""[..], &b"fixed"[..])));
    }
}
