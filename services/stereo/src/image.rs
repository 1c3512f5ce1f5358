//! Mono8 images: a borrowed view (what matchers take) and an owned buffer.

use thiserror::Error;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum ImageError {
    #[error("image buffer has {got} bytes, expected {width}x{height} = {expected}")]
    BadLength {
        width: usize,
        height: usize,
        expected: usize,
        got: usize,
    },
}

/// Borrowed Mono8 image with packed rows (stride == width).
#[derive(Clone, Copy, Debug)]
pub struct GrayView<'a> {
    width: usize,
    height: usize,
    data: &'a [u8],
}

impl<'a> GrayView<'a> {
    pub fn new(width: usize, height: usize, data: &'a [u8]) -> Result<Self, ImageError> {
        if data.len() != width * height {
            return Err(ImageError::BadLength {
                width,
                height,
                expected: width * height,
                got: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }
    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    pub fn data(&self) -> &'a [u8] {
        self.data
    }
    pub fn row(&self, y: usize) -> &'a [u8] {
        &self.data[y * self.width..(y + 1) * self.width]
    }
}

/// Owned Mono8 image with packed rows.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GrayImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

impl GrayImage {
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0; width * height],
        }
    }
    pub fn from_vec(width: usize, height: usize, data: Vec<u8>) -> Result<Self, ImageError> {
        GrayView::new(width, height, &data)?;
        Ok(Self {
            width,
            height,
            data,
        })
    }
    pub fn view(&self) -> GrayView<'_> {
        GrayView {
            width: self.width,
            height: self.height,
            data: &self.data,
        }
    }
}

/// 2x2 box downsampling into a preallocated `(w/2)x(h/2)` buffer (odd last row/column dropped).
pub(crate) fn downsample2(src: GrayView<'_>, dst: &mut [u8]) {
    let (w2, h2) = (src.width() / 2, src.height() / 2);
    debug_assert_eq!(dst.len(), w2 * h2);
    use rayon::prelude::*;
    let rows = dst.par_chunks_exact_mut(w2.max(1)).enumerate().take(h2);
    rows.for_each(|(y, drow)| {
        let r0 = src.row(2 * y);
        let r1 = src.row(2 * y + 1);
        for (x, o) in drow.iter_mut().enumerate() {
            let s =
                r0[2 * x] as u16 + r0[2 * x + 1] as u16 + r1[2 * x] as u16 + r1[2 * x + 1] as u16;
            *o = ((s + 2) >> 2) as u8;
        }
    });
}
