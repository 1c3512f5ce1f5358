use iceoryx2::prelude::ZeroCopySend;

/// A fixed-capacity UTF-8 string that can live in shared memory (no heap).
/// Longer input is truncated at a character boundary; the unused tail is zero.
#[repr(C)]
#[derive(Clone, Copy, PartialEq, Eq, ZeroCopySend)]
pub struct FixedStr<const N: usize> {
    len: u32,
    bytes: [u8; N],
}

impl<const N: usize> FixedStr<N> {
    pub const fn empty() -> Self {
        Self {
            len: 0,
            bytes: [0; N],
        }
    }

    pub fn new(text: &str) -> Self {
        let mut end = text.len().min(N);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        let mut bytes = [0; N];
        bytes[..end].copy_from_slice(&text.as_bytes()[..end]);
        Self {
            len: end as u32,
            bytes,
        }
    }

    pub fn as_str(&self) -> &str {
        let len = (self.len as usize).min(N);
        // Only `new` writes the bytes, and it writes whole characters; a corrupted sample still must
        // not panic a reader, so fall back to the longest valid prefix.
        match std::str::from_utf8(&self.bytes[..len]) {
            Ok(s) => s,
            Err(e) => std::str::from_utf8(&self.bytes[..e.valid_up_to()]).unwrap_or(""),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl<const N: usize> Default for FixedStr<N> {
    fn default() -> Self {
        Self::empty()
    }
}

impl<const N: usize> std::fmt::Debug for FixedStr<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

impl<const N: usize> std::fmt::Display for FixedStr<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl<const N: usize> From<&str> for FixedStr<N> {
    fn from(text: &str) -> Self {
        Self::new(text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncates_at_char_boundary() {
        let s = FixedStr::<4>::new("abé€");
        assert_eq!(s.as_str(), "abé");
        assert_eq!(FixedStr::<8>::new("stereo").as_str(), "stereo");
        assert!(FixedStr::<8>::empty().is_empty());
    }
}
