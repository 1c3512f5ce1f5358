//! The per-cell hazard classifier: logistic regression over a few physical cell features.
//!
//! Why logistic regression: the features are already physical and monotone in "how much solid
//! surface stands above the water here" (height, spread, vertical extent, persistence), so a linear
//! decision surface on standardized features separates hazard from wave and matcher noise well; the
//! output is a calibrated probability (what `MapCell::hazard` means); the model is a weight per
//! feature and a bias in a reviewable JSON file; training is convex and deterministic (same data,
//! same model) and takes seconds. Where one feature matters in a way a line cannot express, a hinge
//! of it is a feature of its own ([`LIFT_HINGE_M`]). A tree ensemble would fit the training
//! scenarios more closely but is larger, less calibrated, and harder to check by eye with the
//! little labelled data the simulator gives.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// Cell features in model order. See [`crate::hazard`] for how each is computed. Range is
/// deliberately not a feature: in the labelled scenarios most distant hazards are shores, and a
/// model that learns "far and high is hazard" fails on open water; range enters only through the
/// normalisations (expected point density and range smear).
pub const FEATURES: [&str; N_FEATURES] = [
    "max_height_m",
    "mean_height_m",
    "height_spread_m",
    "elevated_extent_m",
    "elevated_fraction",
    "min_height_m",
    "history",
    "neighbour_support",
    "water_margin_px",
    "lifted_height_m",
];
pub const N_FEATURES: usize = 10;

/// `lifted_height_m` is how far a cell's lowest point stands above this height (m), 0 below it.
/// Waves and matcher noise always leave some points near the water; a cell whose every point is
/// this high is a surface standing clear of it (a hull side, a superstructure, a pylon). A linear
/// model cannot say "min height matters a lot above 1 m and little below", and without this hinge
/// it traded that evidence away against `water_margin_px`, rating a boat 15-25 m ahead below 0.5.
pub const LIFT_HINGE_M: f32 = 1.0;

/// `water_margin_px` of a model file that does not name its cap (px): the models trained before
/// the cap was a model setting.
pub const UNCAPPED_WATER_MARGIN_PX: f32 = 40.0;

fn uncapped_water_margin() -> f32 {
    UNCAPPED_WATER_MARGIN_PX
}

pub type Features = [f32; N_FEATURES];

/// Model file format version.
pub const MODEL_VERSION: u32 = 1;

#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("cannot read hazard model {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("hazard model {path} is not a valid model file: {source}")]
    Parse {
        path: String,
        source: serde_json::Error,
    },
    #[error("hazard model {path}: {reason}")]
    Invalid { path: String, reason: String },
}

/// Held-out figures recorded with the model so the file says how good it is.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ModelMetrics {
    pub train_scenarios: Vec<String>,
    pub test_scenarios: Vec<String>,
    pub train_cells: usize,
    pub test_cells: usize,
    pub test_precision: f64,
    pub test_recall: f64,
    pub train_precision: f64,
    pub train_recall: f64,
    /// Features whose weights were held at >= 0 in the fit (`perception train --non-negative`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub non_negative: Vec<String>,
    /// The `water_margin_px` cap the weights were fitted with, where the model applies another
    /// (`perception train --evaluate MODEL --water-margin-cap PX --out F`). The test figures are
    /// then the applied cap's, the training figures the fit's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted_water_margin_cap_px: Option<f32>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HazardModel {
    pub version: u32,
    /// Must equal [`FEATURES`]: a model is only valid for the features it was trained on.
    pub features: Vec<String>,
    /// Points higher than this above the water count as elevated (m); part of the features.
    pub elevated_height_m: f32,
    /// `water_margin_px` is capped at this (px). The feature tells the "walls" a pixel or two of
    /// mismatch builds from far water apart from real surfaces; beyond a few pixels it says no
    /// more than "not such a wall", yet uncapped it grows with nearness (a 0.4 m wave crest at
    /// 9 m, a 6 m pylon at 30 m), and with near objects rare in training it took a weight against
    /// near, tall cells (ARCHITECTURE.md, the water margin). The cap may be lower than the one the
    /// weights were fitted with ([`ModelMetrics::fitted_water_margin_cap_px`]): the weights then
    /// hold where the training data had the feature, and its extrapolation beyond the cap is cut.
    #[serde(default = "uncapped_water_margin")]
    pub water_margin_cap_px: f32,
    pub mean: Vec<f32>,
    pub std: Vec<f32>,
    pub weights: Vec<f32>,
    pub bias: f32,
    #[serde(default)]
    pub metrics: ModelMetrics,
}

impl HazardModel {
    /// Loads and validates a model file.
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            path: p.clone(),
            source,
        })?;
        let model: HazardModel =
            serde_json::from_str(&text).map_err(|source| ModelError::Parse {
                path: p.clone(),
                source,
            })?;
        model
            .validate()
            .map_err(|reason| ModelError::Invalid { path: p, reason })?;
        Ok(model)
    }

    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        std::fs::write(path, text + "\n")
    }

    pub fn validate(&self) -> Result<(), String> {
        if self.version != MODEL_VERSION {
            return Err(format!(
                "version {} (this build reads {MODEL_VERSION})",
                self.version
            ));
        }
        if self.features.iter().map(String::as_str).ne(FEATURES) {
            return Err(format!(
                "features {:?} differ from this build's {FEATURES:?}",
                self.features
            ));
        }
        for (name, v) in [
            ("mean", &self.mean),
            ("std", &self.std),
            ("weights", &self.weights),
        ] {
            if v.len() != N_FEATURES {
                return Err(format!(
                    "{name} has {} values, expected {N_FEATURES}",
                    v.len()
                ));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Err(format!("{name} has a non-finite value"));
            }
        }
        if self.std.iter().any(|s| *s <= 0.0) {
            return Err("std must be > 0".into());
        }
        if !self.bias.is_finite() {
            return Err("bias is not finite".into());
        }
        if !(self.elevated_height_m.is_finite() && self.elevated_height_m > 0.0) {
            return Err("elevated_height_m must be > 0".into());
        }
        if !(self.water_margin_cap_px.is_finite() && self.water_margin_cap_px > 0.0) {
            return Err("water_margin_cap_px must be > 0".into());
        }
        Ok(())
    }

    /// Each feature's term in the log-odds (its standardized value times its weight).
    #[inline]
    pub fn terms(&self, x: &Features) -> Features {
        let mut t = [0.0; N_FEATURES];
        for (i, t) in t.iter_mut().enumerate() {
            *t = self.weights[i] * (x[i] - self.mean[i]) / self.std[i];
        }
        t
    }

    /// Log-odds of a hazard: the bias plus the features' terms.
    #[inline]
    pub fn logit(&self, x: &Features) -> f32 {
        self.terms(x).iter().fold(self.bias, |z, t| z + t)
    }

    /// Hazard probability of a cell.
    #[inline]
    pub fn probability(&self, x: &Features) -> f32 {
        1.0 / (1.0 + (-self.logit(x)).exp())
    }

    /// Applies another `water_margin_px` cap to the fitted weights, remembering the cap they were
    /// fitted with (the first one, if applied more than once).
    pub fn apply_water_margin_cap(&mut self, cap_px: f32) -> Result<(), String> {
        if !(cap_px.is_finite() && cap_px > 0.0) {
            return Err(format!("cap {cap_px} px must be > 0"));
        }
        if cap_px != self.water_margin_cap_px && self.metrics.fitted_water_margin_cap_px.is_none() {
            self.metrics.fitted_water_margin_cap_px = Some(self.water_margin_cap_px);
        }
        self.water_margin_cap_px = cap_px;
        Ok(())
    }

    /// Fits a model by full-batch gradient descent on the class-weighted log loss with a small L2
    /// penalty. Deterministic: same samples in the same order give the same model.
    ///
    /// Features flagged in `non_negative` may only count towards hazard (their weight is projected
    /// onto >= 0 after every step): correlated features otherwise let one of them carry a proxy
    /// for what the training scenarios happen to share (a weight against `water_margin_px` that
    /// stood for "near", see ARCHITECTURE.md, the water margin).
    pub fn fit(
        samples: &[(Features, bool)],
        elevated_height_m: f32,
        water_margin_cap_px: f32,
        non_negative: &[bool; N_FEATURES],
        iterations: usize,
    ) -> Self {
        let n = samples.len().max(1) as f64;
        let mut mean = [0f64; N_FEATURES];
        let mut var = [0f64; N_FEATURES];
        for (x, _) in samples {
            for i in 0..N_FEATURES {
                mean[i] += x[i] as f64 / n;
            }
        }
        for (x, _) in samples {
            for i in 0..N_FEATURES {
                var[i] += (x[i] as f64 - mean[i]).powi(2) / n;
            }
        }
        let std: Vec<f64> = var.iter().map(|v| v.sqrt().max(1e-3)).collect();
        let z: Vec<([f64; N_FEATURES], f64)> = samples
            .iter()
            .map(|(x, y)| {
                let mut s = [0f64; N_FEATURES];
                for i in 0..N_FEATURES {
                    s[i] = (x[i] as f64 - mean[i]) / std[i];
                }
                (s, if *y { 1.0 } else { 0.0 })
            })
            .collect();
        // Hazard cells are rare: weight the classes equally so the rare one is not ignored.
        let positives = z.iter().filter(|(_, y)| *y > 0.5).count().max(1) as f64;
        let negatives = (z.len() as f64 - positives).max(1.0);
        let (wp, wn) = (n / (2.0 * positives), n / (2.0 * negatives));
        let l2 = 1e-3;
        let mut w = [0f64; N_FEATURES];
        let mut b = 0f64;
        let rate = 0.5;
        for _ in 0..iterations {
            let mut gw = [0f64; N_FEATURES];
            let mut gb = 0f64;
            for (x, y) in &z {
                let logit = b + (0..N_FEATURES).map(|i| w[i] * x[i]).sum::<f64>();
                let p = 1.0 / (1.0 + (-logit).exp());
                let weight = if *y > 0.5 { wp } else { wn };
                let e = weight * (p - y);
                for i in 0..N_FEATURES {
                    gw[i] += e * x[i];
                }
                gb += e;
            }
            for i in 0..N_FEATURES {
                w[i] -= rate * (gw[i] / n + l2 * w[i]);
                if non_negative[i] {
                    w[i] = w[i].max(0.0);
                }
            }
            b -= rate * gb / n;
        }
        HazardModel {
            version: MODEL_VERSION,
            features: FEATURES.iter().map(|s| s.to_string()).collect(),
            elevated_height_m,
            water_margin_cap_px,
            mean: mean.iter().map(|v| *v as f32).collect(),
            std: std.iter().map(|v| *v as f32).collect(),
            weights: w.iter().map(|v| *v as f32).collect(),
            bias: b as f32,
            metrics: ModelMetrics::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model fitted to nothing, with this `water_margin_px` cap.
    fn blank(cap_px: f32) -> HazardModel {
        HazardModel::fit(
            &[([0.0; N_FEATURES], false)],
            0.3,
            cap_px,
            &[false; N_FEATURES],
            1,
        )
    }

    #[test]
    fn fit_separates_a_threshold_on_one_feature() {
        let mut samples = Vec::new();
        for k in 0..200 {
            let h = k as f32 * 0.02;
            let mut x = [0f32; N_FEATURES];
            x[0] = h;
            x[5] = (k % 7) as f32 * 0.1;
            samples.push((x, h > 1.5));
        }
        let m = HazardModel::fit(&samples, 0.3, 4.0, &[false; N_FEATURES], 2000);
        m.validate().unwrap();
        let mut lo = [0f32; N_FEATURES];
        lo[0] = 0.5;
        let mut hi = lo;
        hi[0] = 3.0;
        assert!(m.probability(&lo) < 0.1, "{}", m.probability(&lo));
        assert!(m.probability(&hi) > 0.9, "{}", m.probability(&hi));
    }

    #[test]
    fn a_non_negative_feature_never_counts_against_hazard() {
        // Hazard when feature 0 exceeds feature 1: a free fit weighs feature 1 against hazard.
        let mut samples = Vec::new();
        for k in 0..400 {
            let mut x = [0f32; N_FEATURES];
            x[0] = (k % 20) as f32 * 0.1;
            x[1] = (k / 20) as f32 * 0.1;
            samples.push((x, x[0] > x[1]));
        }
        let free = HazardModel::fit(&samples, 0.3, 4.0, &[false; N_FEATURES], 500);
        assert!(free.weights[1] < -0.5, "{:?}", free.weights);
        let mut non_negative = [false; N_FEATURES];
        non_negative[1] = true;
        let held = HazardModel::fit(&samples, 0.3, 4.0, &non_negative, 500);
        assert!(held.weights[1] >= 0.0, "{:?}", held.weights);
        assert!(held.weights[0] > 0.5, "{:?}", held.weights);
    }

    #[test]
    fn a_cap_applied_after_the_fit_keeps_the_fitted_one_on_record() {
        let mut m = blank(40.0);
        m.apply_water_margin_cap(10.0).unwrap();
        m.apply_water_margin_cap(12.0).unwrap();
        assert_eq!(m.water_margin_cap_px, 12.0);
        assert_eq!(m.metrics.fitted_water_margin_cap_px, Some(40.0));
        assert!(m.apply_water_margin_cap(0.0).is_err());
        assert!(m.apply_water_margin_cap(f32::NAN).is_err());
        assert_eq!(m.water_margin_cap_px, 12.0);
        // The record survives a save and a load.
        let path = std::env::temp_dir().join(format!("usv-capped-{}.json", std::process::id()));
        m.save(&path).unwrap();
        let loaded = HazardModel::load(&path).unwrap();
        std::fs::remove_file(&path).ok();
        assert_eq!(loaded.metrics.fitted_water_margin_cap_px, Some(40.0));
        assert_eq!(loaded.water_margin_cap_px, 12.0);
    }

    #[test]
    fn a_model_file_without_a_margin_cap_keeps_the_features_it_was_trained_on() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.json");
        let m = blank(4.0);
        let mut json: serde_json::Value = serde_json::to_value(&m).unwrap();
        json.as_object_mut().unwrap().remove("water_margin_cap_px");
        std::fs::write(&path, json.to_string()).unwrap();
        let loaded = HazardModel::load(&path).unwrap();
        assert_eq!(loaded.water_margin_cap_px, UNCAPPED_WATER_MARGIN_PX);
        m.save(&path).unwrap();
        assert_eq!(HazardModel::load(&path).unwrap().water_margin_cap_px, 4.0);
        let mut bad = m.clone();
        bad.water_margin_cap_px = 0.0;
        bad.save(&path).unwrap();
        let e = HazardModel::load(&path).unwrap_err().to_string();
        assert!(e.contains("water_margin_cap_px"), "{e}");
    }

    #[test]
    fn corrupt_or_mismatched_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.json");
        assert!(matches!(
            HazardModel::load(&path),
            Err(ModelError::Io { .. })
        ));
        std::fs::write(&path, "{ not json").unwrap();
        assert!(matches!(
            HazardModel::load(&path),
            Err(ModelError::Parse { .. })
        ));
        let mut m = blank(4.0);
        m.weights.pop();
        m.save(&path).unwrap();
        let e = HazardModel::load(&path).unwrap_err().to_string();
        assert!(e.contains("weights"), "{e}");
        let mut m = blank(4.0);
        m.features[0] = "height".into();
        m.save(&path).unwrap();
        assert!(HazardModel::load(&path).is_err());
    }
}
