//! Stereo pipeline algorithms: rectification, disparity matching (block matching or SGM), water-plane
//! fit and range. Everything here is pure and deterministic: no IPC, no clock, no file I/O inside the
//! algorithms. Matchers own their scratch memory so steady-state frames allocate nothing.

pub mod bm;
pub mod calib;
pub mod disparity;
pub mod eval;
pub mod image;
pub mod pipeline;
pub mod plane;
pub mod range;
pub mod sgm;
mod simd;

pub use disparity::{build_matcher, DisparityMap, DisparityMatcher, MatchError, MatcherConfig};
pub use image::{GrayImage, GrayView, ImageError};
