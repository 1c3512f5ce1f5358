use serde::Deserialize;
use crate::disparity::*;
use crate::image::GrayView;
#[derive(Clone, Debug, Deserialize, PartialEq, Default)]
#[serde(default, deny_unknown_fields)]
pub struct SgmParams { pub num_disparities: usize }
pub struct SgmMatcher;
impl SgmMatcher { pub fn new(_p: SgmParams, _w: usize, _h: usize) -> Result<Self, MatchError> { Ok(Self) } }
impl DisparityMatcher for SgmMatcher {
    fn compute(&mut self, _l: GrayView<'_>, _r: GrayView<'_>, _o: &mut DisparityMap) -> Result<(), MatchError> { Ok(()) }
    fn num_disparities(&self) -> usize { 0 }
    fn name(&self) -> &'static str { "sgm" }
}
