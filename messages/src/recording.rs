//! How a message is stored in a recording so that replay can republish exactly the same bytes.
//!
//! A recorded message (MCAP channel with message encoding [`RAW_ENCODING`], schema named after the
//! versioned type name, e.g. `usv.StereoFrame.v1`) is one byte string:
//!
//! ```text
//! u32 little-endian: user header length N | N bytes: user header | payload bytes (rest)
//! ```
//!
//! Both parts are the bytes as they were in shared memory (padding included), so a replayed message is
//! byte-identical to the recorded one. Fixed-size topics have an empty user header (N = 0).

/// MCAP message encoding (and schema encoding) of the replay channels.
pub const RAW_ENCODING: &str = "usv-raw";

/// Length of the framing prefix.
pub const PREFIX_LEN: usize = 4;

/// The framing prefix for a user header of `header_len` bytes.
pub fn prefix(header_len: usize) -> [u8; PREFIX_LEN] {
    (header_len as u32).to_le_bytes()
}

/// Splits a recorded message into (user header, payload); `None` if the prefix does not fit.
pub fn split(data: &[u8]) -> Option<(&[u8], &[u8])> {
    let len = u32::from_le_bytes(data.get(..PREFIX_LEN)?.try_into().ok()?) as usize;
    let rest = &data[PREFIX_LEN..];
    (len <= rest.len()).then(|| rest.split_at(len))
}

/// The bytes of a user header or payload as they lie in memory (padding included).
pub fn bytes_of<T: ?Sized + iceoryx2::prelude::IceoryxSend>(value: &T) -> &[u8] {
    // SAFETY: the pointer and size come from a valid reference; contract types are plain data, and
    // reading their bytes (padding as whatever the memory holds) is only ever used to copy them.
    unsafe {
        std::slice::from_raw_parts(value as *const T as *const u8, std::mem::size_of_val(value))
    }
}

/// Reads a recorded user header or fixed-size payload back into its type (`None` if `bytes` is
/// too short). Offline tools use it; the live path never copies.
///
/// # Safety
/// `T` must be valid for every bit pattern of its size: contract types made of plain numbers and
/// arrays (no `bool`, no enums), such as `InsState`, `GroundTruth` or `WorldMapHeader`.
pub unsafe fn read_value<T: Copy>(bytes: &[u8]) -> Option<T> {
    (bytes.len() >= size_of::<T>()).then(|| {
        // SAFETY: the length is checked; validity of the bit pattern is the caller's promise.
        unsafe { std::ptr::read_unaligned(bytes.as_ptr().cast::<T>()) }
    })
}

/// Reads a recorded slice payload back into its elements (trailing bytes short of one element are
/// ignored).
///
/// # Safety
/// As for [`read_value`].
pub unsafe fn read_slice<T: Copy>(bytes: &[u8]) -> Vec<T> {
    bytes
        .chunks_exact(size_of::<T>())
        // SAFETY: each chunk is exactly one element long; validity is the caller's promise.
        .map(|c| unsafe { std::ptr::read_unaligned(c.as_ptr().cast::<T>()) })
        .collect()
}

/// The versioned type name a topic's recorded schema is named after: the user header's for slice
/// topics (`usv.StereoFrame.v1`), the payload's for fixed-size topics (`usv.InsState.v1`).
pub fn type_name<P, H>() -> &'static str
where
    P: ?Sized + iceoryx2::prelude::ZeroCopySend,
    H: iceoryx2::prelude::ZeroCopySend,
{
    // SAFETY: `type_name` is only unsafe to implement, not to call.
    unsafe {
        if size_of::<H>() == 0 {
            <P as iceoryx2::prelude::ZeroCopySend>::type_name()
        } else {
            <H as iceoryx2::prelude::ZeroCopySend>::type_name()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_round_trip() {
        let mut data = prefix(3).to_vec();
        data.extend_from_slice(b"hdrpayload");
        assert_eq!(split(&data), Some((&b"hdr"[..], &b"payload"[..])));
        assert_eq!(split(&[1, 0]), None);
        assert_eq!(split(&prefix(9)), None);
        assert_eq!(bytes_of(&[1u8, 2, 3][..]), &[1, 2, 3]);
        assert_eq!(type_name::<crate::InsState, ()>(), "usv.InsState.v1");
        assert_eq!(
            type_name::<[u8], crate::StereoFrameHeader>(),
            "usv.StereoFrame.v1"
        );
    }

    #[test]
    fn recorded_bytes_read_back_into_their_types() {
        let cells = [
            crate::MapCell {
                hazard: 200,
                max_height_cm: -3,
                ..Default::default()
            },
            crate::MapCell {
                water: 2,
                elevation_cm: 41,
                ..Default::default()
            },
        ];
        let pose = crate::Pose {
            position: [1.0, -2.0, 0.5],
            yaw: 0.25,
            ..Default::default()
        };
        // Offset by one byte: recorded payloads need not be aligned.
        let mut bytes = vec![0u8];
        bytes.extend_from_slice(bytes_of(&pose));
        // SAFETY: Pose and MapCell are plain numbers.
        let back: Option<crate::Pose> = unsafe { read_value(&bytes[1..]) };
        assert_eq!(back, Some(pose));
        assert_eq!(unsafe { read_value::<crate::Pose>(&bytes[2..]) }, None);
        let mut bytes = vec![0u8];
        bytes.extend_from_slice(bytes_of(&cells[..]));
        bytes.push(9);
        assert_eq!(unsafe { read_slice::<crate::MapCell>(&bytes[1..]) }, cells);
    }
}
