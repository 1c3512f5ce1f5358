//! What keeps a live view cheap for the boat: a rate limit per channel and image downscaling.

use messages::{PixelEncoding, StereoFrameHeader};

/// Lets through at most `hz` messages per second on average. A source slightly faster than the
/// limit is thinned evenly (6 Hz -> 5 Hz, not 3 Hz), and a long pause does not allow a burst.
#[derive(Debug, Clone, Copy)]
pub struct RateLimit {
    interval_ns: u64,
    next_ns: Option<u64>,
}

impl RateLimit {
    pub fn new(hz: Option<f64>) -> Self {
        Self {
            interval_ns: hz.map_or(0, |hz| (1e9 / hz) as u64),
            next_ns: None,
        }
    }

    /// Whether a message arriving at `now_ns` may go out; records it if so.
    pub fn allow(&mut self, now_ns: u64) -> bool {
        if self.next_ns.is_some_and(|next| now_ns < next) {
            return false;
        }
        let due = self.next_ns.unwrap_or(now_ns) + self.interval_ns;
        self.next_ns = Some(if due >= now_ns {
            due
        } else {
            now_ns + self.interval_ns
        });
        true
    }
}

/// Why a frame cannot be shown.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ImageError {
    #[error("stereo frame with unknown pixel encoding {0}")]
    Encoding(u32),
    #[error("stereo frame payload has {got} bytes, its header says {want}")]
    Size { got: usize, want: usize },
    #[error("stereo frame of {width}x{height} with stride {stride} is inconsistent")]
    Geometry {
        width: u32,
        height: u32,
        stride: u32,
    },
}

/// Checks a frame before it is shown: the views crate would silently skip it.
pub fn check(h: &StereoFrameHeader, payload: &[u8]) -> Result<PixelEncoding, ImageError> {
    let enc = h.encoding().ok_or(ImageError::Encoding(h.encoding))?;
    if (h.stride as usize) < h.width as usize * enc.bytes_per_pixel() {
        return Err(ImageError::Geometry {
            width: h.width,
            height: h.height,
            stride: h.stride,
        });
    }
    if payload.len() != h.payload_len() {
        return Err(ImageError::Size {
            got: payload.len(),
            want: h.payload_len(),
        });
    }
    Ok(enc)
}

/// Shrinks the left plane of a checked frame by `factor` (box average over factor x factor pixels
/// per channel) into `out`, which becomes a frame payload for the returned header: the small left
/// plane, then a right plane of zeros (only the left image is shown). `out` keeps its capacity.
pub fn downscale(
    h: &StereoFrameHeader,
    payload: &[u8],
    factor: u32,
    out: &mut Vec<u8>,
) -> StereoFrameHeader {
    let bpp = h.encoding().map_or(1, |e| e.bytes_per_pixel());
    let f = factor.max(1) as usize;
    let (w, ht) = (h.width as usize / f, h.height as usize / f);
    let small = StereoFrameHeader {
        width: w as u32,
        height: ht as u32,
        stride: (w * bpp) as u32,
        ..*h
    };
    out.clear();
    out.resize(small.payload_len(), 0);
    let stride = h.stride as usize;
    let area = (f * f) as u32;
    for y in 0..ht {
        let dst = &mut out[y * w * bpp..(y + 1) * w * bpp];
        for x in 0..w {
            for c in 0..bpp {
                let mut sum = 0u32;
                for dy in 0..f {
                    let row = &payload[(y * f + dy) * stride..];
                    for dx in 0..f {
                        sum += row[(x * f + dx) * bpp + c] as u32;
                    }
                }
                dst[x * bpp + c] = ((sum + area / 2) / area) as u8;
            }
        }
    }
    small
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rate_limit_thins_evenly() {
        let ms = 1_000_000u64;
        let mut r = RateLimit::new(Some(5.0));
        // A 6 Hz source for 10 s: about 5 Hz get through, not 3.
        let passed = (0..60).filter(|i| r.allow(i * 1000 * ms / 6)).count();
        assert!((48..=51).contains(&passed), "{passed}");
        let mut r = RateLimit::new(Some(5.0));
        assert!(r.allow(0));
        assert!(!r.allow(100 * ms));
        // After a long pause one message passes, not a burst.
        assert!(r.allow(10_000 * ms));
        assert!(!r.allow(10_001 * ms));
        let mut unlimited = RateLimit::new(None);
        assert!((0..10).all(|_| unlimited.allow(5)));
    }

    fn frame(w: u32, h: u32, enc: PixelEncoding, stride: u32) -> StereoFrameHeader {
        StereoFrameHeader {
            width: w,
            height: h,
            stride,
            encoding: enc as u32,
            ..Default::default()
        }
    }

    #[test]
    fn downscale_averages_blocks() {
        // 4x2 mono with stride 5 (one padding byte per row), right plane all 9s.
        let h = frame(4, 2, PixelEncoding::Mono8, 5);
        let mut payload = vec![0, 2, 10, 20, 77, 4, 6, 30, 40, 77];
        payload.extend([9; 10]);
        assert_eq!(check(&h, &payload), Ok(PixelEncoding::Mono8));
        let mut out = Vec::new();
        let small = downscale(&h, &payload, 2, &mut out);
        assert_eq!((small.width, small.height, small.stride), (2, 1, 2));
        assert_eq!(out, vec![3, 25, 0, 0]);
        assert!(small.planes(&out).is_some());
        // RGB: channels are averaged separately.
        let h = frame(2, 2, PixelEncoding::Rgb8, 6);
        let left = [10, 0, 200, 20, 0, 200, 30, 0, 100, 40, 4, 100];
        let payload: Vec<u8> = left.iter().copied().chain([0; 12]).collect();
        let small = downscale(&h, &payload, 2, &mut out);
        assert_eq!((small.width, small.height, small.stride), (1, 1, 3));
        assert_eq!(&out[..3], &[25, 1, 150]);
    }

    #[test]
    fn bad_frames_are_named() {
        let h = frame(4, 2, PixelEncoding::Mono8, 4);
        assert_eq!(
            check(&h, &[0; 15]),
            Err(ImageError::Size { got: 15, want: 16 })
        );
        let h = frame(4, 2, PixelEncoding::Rgb8, 4);
        assert!(matches!(
            check(&h, &[0; 16]),
            Err(ImageError::Geometry { .. })
        ));
        let mut h = frame(4, 2, PixelEncoding::Mono8, 4);
        h.encoding = 7;
        assert_eq!(check(&h, &[0; 16]), Err(ImageError::Encoding(7)));
    }
}
