//! Detector parameters. Pixel sizes are for 512x384 images, the resolution the paper runs at; scale
//! them with the image for other sizes. Every struct denies unknown fields so a service config with a
//! typo fails to load.

use serde::Deserialize;

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct WaterConfig {
    pub color: ColorParams,
    pub texture: TextureParams,
    pub zero_disparity: ZeroDisparityParams,
    pub reflection: ReflectionParams,
    /// Radius (px) of the closing that joins close regions of one cue before fusion (section 2,
    /// figure 4). 0 disables it.
    pub join_radius_px: usize,
    /// Whether texture and zero disparity alone form candidate regions. Off: regions grow from the
    /// water-specific cues (colour, reflection) and the other two only count as support inside them,
    /// because smooth, poorly matched dry ground (a dirt trail, short grass) fires both widely and
    /// would merge everything below the horizon into one region.
    pub weak_cues_form_regions: bool,
    pub rules: RuleParams,
    pub ground: GroundParams,
    pub map: MapParams,
}

impl Default for WaterConfig {
    fn default() -> Self {
        Self {
            color: ColorParams::default(),
            texture: TextureParams::default(),
            zero_disparity: ZeroDisparityParams::default(),
            reflection: ReflectionParams::default(),
            join_radius_px: 3,
            weak_cues_form_regions: false,
            rules: RuleParams::default(),
            ground: GroundParams::default(),
            map: MapParams::default(),
        }
    }
}

/// Colour cue: hue, saturation and brightness thresholds tuned to sky reflections. The sky's colour
/// is measured each frame at the top of the image (above the horizon).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct ColorParams {
    pub enabled: bool,
    /// Sky reference = mean colour of the above-horizon pixels at or above this brightness quantile
    /// (clouds and sky are the brightest things up there; tree tops are not).
    pub sky_quantile: f64,
    /// Rows just above the horizon are skipped for the sky reference (tree lines, haze).
    pub sky_margin_px: usize,
    /// Used when too little sky is in view (RGB, 0..=255), or when what was measured is not sky.
    pub default_sky_rgb: [u8; 3],
    /// Hues (deg, from..=to) a saturated daytime sky can have. A measured reference that is
    /// saturated (at least `hue_min_saturation`) with a hue outside is foliage filling the upper
    /// image (a tree line close ahead), not sky: the default sky is used instead, or green ground
    /// would look like its reflection.
    pub sky_hue_range_deg: [f32; 2],
    /// Saturation (0..=1) may exceed the sky's by this much...
    pub saturation_margin: f32,
    /// ...but never this absolute value (saturated pixels also need the sky's hue, below).
    pub max_saturation: f32,
    /// Brightness (HSV value) relative to the sky's: a reflection is dimmer than the sky (Fresnel).
    pub min_value_rel: f32,
    pub max_value_rel: f32,
    /// Hue must be within this of the sky's when both are saturated enough to have a hue.
    pub hue_tolerance_deg: f32,
    pub hue_min_saturation: f32,
}

impl Default for ColorParams {
    fn default() -> Self {
        Self {
            enabled: true,
            sky_quantile: 0.6,
            sky_margin_px: 6,
            default_sky_rgb: [170, 190, 220],
            sky_hue_range_deg: [170.0, 270.0],
            saturation_margin: 0.12,
            max_saturation: 0.6,
            min_value_rel: 0.30,
            max_value_rel: 1.15,
            hue_tolerance_deg: 50.0,
            hue_min_saturation: 0.12,
        }
    }
}

/// Texture cue: low local intensity variance (box filter over integral images).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct TextureParams {
    /// Box half-size (px): the window is `2r+1` square.
    pub radius_px: usize,
    /// Standard deviation of intensity (grey levels) at or below which a pixel is smooth.
    pub max_std: f32,
}

impl Default for TextureParams {
    fn default() -> Self {
        Self {
            radius_px: 3,
            max_std: 3.0,
        }
    }
}

/// Zero-disparity cue: pixels below the horizon with no or near-zero disparity, i.e. reflections of
/// far things (sky, clouds, tree lines).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct ZeroDisparityParams {
    /// Disparities below this (px) count as zero.
    pub max_disparity: f32,
    /// Whether pixels without a disparity count (a correlator rejects featureless sky reflections).
    pub count_invalid: bool,
    /// Columns at the left edge that never carry evidence. Beyond it, a pixel counts only where
    /// the ground's disparity would keep its match inside the right image (see
    /// `ReflectionParams::edge_margin_px`): further left the matcher is blind.
    pub left_margin_px: usize,
    /// Only this far below the horizon (px) and further down.
    pub horizon_margin_px: usize,
}

impl Default for ZeroDisparityParams {
    fn default() -> Self {
        Self {
            max_disparity: 0.5,
            count_invalid: true,
            left_margin_px: 0,
            horizon_margin_px: 2,
        }
    }
}

/// Stereo reflection cue: range points below the ground surface.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct ReflectionParams {
    /// A point must be this far below the ground (m)...
    pub margin_m: f32,
    /// ...plus this much per metre of range (ground extrapolation and stereo error grow with range).
    pub margin_per_m: f32,
    /// Points farther than this are not used (m).
    pub max_range_m: f32,
    /// A pixel must lie this far (px) right of the column where the ground's disparity would take
    /// its match out of the right image (the matcher's half block plus slack).
    pub edge_margin_px: usize,
}

impl Default for ReflectionParams {
    fn default() -> Self {
        Self {
            margin_m: 0.4,
            margin_per_m: 0.015,
            max_range_m: 80.0,
            edge_margin_px: 8,
        }
    }
}

/// Rule base for fusing the cues (section 2).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct RuleParams {
    /// Smaller regions are rejected (px).
    pub min_pixels: usize,
    /// Regions with more than this share of pixels above the horizon are rejected.
    pub max_above_horizon: f32,
    /// A stereo point this far above the ground (m) is "above the ground"...
    pub above_ground_m: f32,
    /// ...and a region with more than this share of its perimeter's range points above the ground
    /// is rejected (it lies on something standing up, not on the ground).
    pub max_above_ground: f32,
    /// A cue is present in a region when it covers at least this share of it.
    pub min_cue_share: f32,
    /// Valid combinations: colour covering this share with at least `min_cues` cues present...
    pub min_cues: usize,
    pub min_color_share: f32,
    /// ...or stereo reflections covering this share together with zero disparity.
    pub min_reflection_share: f32,
}

impl Default for RuleParams {
    fn default() -> Self {
        Self {
            min_pixels: 60,
            max_above_horizon: 0.1,
            above_ground_m: 0.4,
            max_above_ground: 0.3,
            min_cue_share: 0.1,
            min_cues: 2,
            min_color_share: 0.3,
            min_reflection_share: 0.15,
        }
    }
}

/// Ground detection (section 2): mode elevation with low variance per cell, close to the minimum
/// elevation of a radial swath map.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct GroundParams {
    /// Points farther than this do not feed the ground (m).
    pub max_range_m: f32,
    /// Width of the elevation window whose fullest position is the mode (m).
    pub mode_window_m: f32,
    /// Points within this of the mode form the variance test (m).
    pub close_band_m: f32,
    /// Standard deviation of those points at or below which the cell is flat (m).
    pub max_std_m: f32,
    pub min_points: usize,
    /// Nearer than this (m) only every other pixel in both directions feeds the cells.
    pub dense_range_m: f32,
    /// Width of a radial swath (m); the paper uses 2 m.
    pub swath_m: f32,
    /// The swath's "minimum" elevation is this quantile of its flat cells' modes (0 = the true
    /// minimum; a little above it ignores the mirror images of the ground seen in water).
    pub min_quantile: f32,
    /// Bearing sectors per full turn of the swath map (1 = whole rings).
    pub sectors: usize,
    /// The mode may be this far above its swath's minimum (m).
    pub max_above_min_m: f32,
    /// A swath minimum this far from the median of its neighbours along range is a spike (m).
    pub spike_m: f32,
    /// A perimeter point is on the ground when within this of its cell's ground (m).
    pub perimeter_tolerance_m: f32,
    /// Ring of pixels this far outside a region is its perimeter (px).
    pub perimeter_offset_px: usize,
}

impl Default for GroundParams {
    fn default() -> Self {
        Self {
            max_range_m: 40.0,
            mode_window_m: 0.2,
            close_band_m: 0.5,
            max_std_m: 0.12,
            min_points: 4,
            dense_range_m: 12.0,
            swath_m: 2.0,
            min_quantile: 0.25,
            sectors: 12,
            max_above_min_m: 0.5,
            spike_m: 0.6,
            perimeter_tolerance_m: 0.25,
            perimeter_offset_px: 2,
        }
    }
}

/// Instantaneous terrain map (section 3): vehicle-centred, ENU-aligned.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct MapParams {
    /// Edge length of the square map (m).
    pub size_m: f64,
    pub resolution_m: f64,
    /// Slope (deg) at which a cell becomes lethal; cost grows linearly up to it.
    pub max_slope_deg: f32,
    /// Step height (m) at which a cell becomes lethal.
    pub max_step_m: f32,
    /// Cost of a water cell (the world map decides; deep water is lethal for the vehicle).
    pub water_cost: u8,
}

impl Default for MapParams {
    fn default() -> Self {
        Self {
            size_m: 50.0,
            resolution_m: 0.5,
            max_slope_deg: 30.0,
            max_step_m: 0.5,
            water_cost: 200,
        }
    }
}
