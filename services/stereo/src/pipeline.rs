//! One stereo head's per-frame work, independent of where frames come from: rectify the raw pair,
//! match, and fit the water plane on the lower image rows. Buffers are allocated once, at the
//! calibration's size, and reused for every frame.

use crate::calib::{CalibError, Calibration, RectifiedCamera, Rectifier, RectifyError};
use crate::disparity::{build_matcher, DisparityMap, DisparityMatcher, MatchError, MatcherConfig};
use crate::image::{GrayImage, GrayView, ImageError};
use crate::plane::{PlaneError, PlaneFitter, PlaneParams, WaterPlane};
use crate::range::collect_points;
use nalgebra::Vector3;
use serde::Deserialize;

/// Where the water plane is looked for.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct PlaneSearch {
    /// Fraction of the image height, from the bottom, whose points feed the fit.
    pub lower_fraction: f64,
    /// Points farther than this are too noisy for the fit (m).
    pub max_range_m: f64,
    /// Use every n-th pixel in both directions.
    pub step: usize,
    pub fit: PlaneParams,
}

impl Default for PlaneSearch {
    fn default() -> Self {
        Self {
            lower_fraction: 0.3,
            max_range_m: 40.0,
            step: 4,
            fit: PlaneParams::default(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error(transparent)]
    Rectify(#[from] RectifyError),
    #[error(transparent)]
    Match(#[from] MatchError),
}

pub struct FramePipeline {
    rectifier: Rectifier,
    matcher: Box<dyn DisparityMatcher>,
    fitter: PlaneFitter,
    search: PlaneSearch,
    raw_size: (usize, usize),
    left: GrayImage,
    right: GrayImage,
    disparity: DisparityMap,
    points: Vec<Vector3<f32>>,
}

/// What one frame produced.
pub struct FrameResult<'a> {
    pub disparity: &'a DisparityMap,
    /// `Err` when no plane was found in this frame (not a frame error: open water far away, say).
    pub plane: Result<WaterPlane, PlaneError>,
}

impl FramePipeline {
    pub fn new(
        calibration: &Calibration,
        matcher: &MatcherConfig,
        search: PlaneSearch,
    ) -> Result<Self, PipelineSetupError> {
        let rectifier = Rectifier::new(calibration)?;
        let cam = rectifier.camera();
        let matcher = build_matcher(matcher, cam.width, cam.height)?;
        Ok(Self {
            fitter: PlaneFitter::new(search.fit.clone()),
            search,
            raw_size: (calibration.width, calibration.height),
            left: GrayImage::new(cam.width, cam.height),
            right: GrayImage::new(cam.width, cam.height),
            disparity: DisparityMap::new(cam.width, cam.height),
            points: Vec::new(),
            rectifier,
            matcher,
        })
    }

    /// The rectified camera the disparity refers to.
    pub fn camera(&self) -> RectifiedCamera {
        self.rectifier.camera()
    }

    /// Raw frame size the calibration expects (width, height).
    pub fn raw_size(&self) -> (usize, usize) {
        self.raw_size
    }

    pub fn num_disparities(&self) -> usize {
        self.matcher.num_disparities()
    }

    /// Processes one raw Mono8 pair (rows packed, `width` bytes each).
    pub fn process(
        &mut self,
        width: usize,
        height: usize,
        left: &[u8],
        right: &[u8],
    ) -> Result<FrameResult<'_>, FrameError> {
        let left_view = GrayView::new(width, height, left)?;
        let right_view = GrayView::new(width, height, right)?;
        self.rectifier
            .rectify_left_into(left_view, &mut self.left)?;
        self.rectifier
            .rectify_right_into(right_view, &mut self.right)?;
        self.matcher
            .compute(self.left.view(), self.right.view(), &mut self.disparity)?;
        let cam = self.rectifier.camera();
        let h = self.disparity.height;
        let first_row = ((1.0 - self.search.lower_fraction.clamp(0.0, 1.0)) * h as f64) as usize;
        collect_points(
            &cam,
            &self.disparity,
            first_row..h,
            self.search.step,
            self.search.max_range_m,
            &mut self.points,
        );
        let plane = self.fitter.fit(&self.points);
        Ok(FrameResult {
            disparity: &self.disparity,
            plane,
        })
    }
}

#[derive(Debug, thiserror::Error)]
pub enum PipelineSetupError {
    #[error(transparent)]
    Calibration(#[from] CalibError),
    #[error(transparent)]
    Matcher(#[from] MatchError),
}
