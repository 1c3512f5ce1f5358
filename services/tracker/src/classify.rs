//! Contact classifier: one Gaussian per class with a full covariance (quadratic discriminant)
//! over shape features of a detection, two of them its spread along and across the line of sight
//! from the own vessel, where stereo's range smear and the object's own width part. The range
//! itself is no feature: in the training runs a shore is mostly seen far off in fragments, and a
//! model given the range called anything within 50 m a boat or a marker. Trained offline
//! (`train.rs`, `--example train`) and stored as JSON; loading checks every field, so a missing or
//! corrupt model stops the service at start-up with the reason.

use crate::detect::Detection;
use messages::contact_class;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Feature names, in order; the model file must list the same.
pub const FEATURES: [&str; 7] = [
    "ln_area_m2",
    "height_m",
    "ln_elongation",
    "ln_max_extent_m",
    "mean_hazard",
    "ln_along_sd_m",
    "ln_across_sd_m",
];

/// The number of features.
pub const N_FEATURES: usize = FEATURES.len();

/// The classes the model must cover.
pub const CLASSES: [u8; 4] = [
    contact_class::BOAT,
    contact_class::CHANNEL_MARKER,
    contact_class::EXTENDED,
    contact_class::FALSE_ALARM,
];

pub fn features(d: &Detection) -> [f64; N_FEATURES] {
    [
        d.area.max(1e-3).ln(),
        d.height,
        d.elongation.max(1.0).ln(),
        d.extent[0].max(d.extent[1]).max(1e-3).ln(),
        d.mean_hazard,
        d.along_sd_m.max(1e-2).ln(),
        d.across_sd_m.max(1e-2).ln(),
    ]
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ClassModel {
    /// See [`messages::contact_class`].
    pub class: u8,
    pub name: String,
    pub prior: f64,
    pub mean: Vec<f64>,
    /// Covariance of the features, row by row ([`N_FEATURES`] squared numbers).
    pub cov: Vec<f64>,
    /// The covariance's inverse and the log of the class's normalising constant, from
    /// [`Model::prepare`].
    #[serde(skip)]
    precision: Vec<f64>,
    #[serde(skip)]
    log_norm: f64,
}

impl ClassModel {
    pub fn new(class: u8, prior: f64, mean: Vec<f64>, cov: Vec<f64>) -> ClassModel {
        ClassModel {
            class,
            name: contact_class::name(class).to_string(),
            prior,
            mean,
            cov,
            precision: Vec::new(),
            log_norm: 0.0,
        }
    }

    /// Log prior plus log density of `x`.
    fn log_score(&self, x: &[f64; N_FEATURES]) -> f64 {
        let d: [f64; N_FEATURES] = std::array::from_fn(|i| x[i] - self.mean[i]);
        let mut q = 0.0;
        for i in 0..N_FEATURES {
            for j in 0..N_FEATURES {
                q += d[i] * self.precision[i * N_FEATURES + j] * d[j];
            }
        }
        self.prior.ln() + self.log_norm - 0.5 * q
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Model {
    pub version: u32,
    pub features: Vec<String>,
    pub classes: Vec<ClassModel>,
    /// How the model was made (data, counts, held-out accuracy): for people, not read.
    #[serde(default)]
    pub provenance: String,
}

#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("cannot read contact model {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("contact model {path} is not valid JSON for the model format: {message}")]
    Parse { path: String, message: String },
    #[error("contact model {path} is invalid: {message}")]
    Invalid { path: String, message: String },
}

impl Model {
    /// Version 2: full covariances and the line-of-sight spreads (version 1 was naive Bayes over
    /// the first five features).
    pub const VERSION: u32 = 2;

    pub fn load(path: &Path) -> Result<Model, ModelError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Read {
            path: p.clone(),
            source,
        })?;
        Self::parse(&text, &p)
    }

    pub fn parse(text: &str, origin: &str) -> Result<Model, ModelError> {
        let mut model: Model = serde_json::from_str(text).map_err(|e| ModelError::Parse {
            path: origin.to_string(),
            message: e.to_string(),
        })?;
        model.prepare().map_err(|message| ModelError::Invalid {
            path: origin.to_string(),
            message,
        })?;
        Ok(model)
    }

    /// Checks every field and inverts the covariances; a model must be prepared before it
    /// classifies.
    pub fn prepare(&mut self) -> Result<(), String> {
        if self.version != Self::VERSION {
            return Err(format!(
                "version {} (expected {})",
                self.version,
                Self::VERSION
            ));
        }
        if self.features != FEATURES {
            return Err(format!(
                "features {:?} (expected {FEATURES:?})",
                self.features
            ));
        }
        for class in CLASSES {
            if !self.classes.iter().any(|c| c.class == class) {
                return Err(format!("class {} missing", contact_class::name(class)));
            }
        }
        for c in &mut self.classes {
            let n = N_FEATURES;
            if c.mean.len() != n || c.cov.len() != n * n {
                return Err(format!(
                    "class {}: {n} means and {} covariances expected",
                    c.name,
                    n * n
                ));
            }
            if !(c.prior.is_finite() && c.prior > 0.0 && c.prior <= 1.0) {
                return Err(format!("class {}: prior must be in (0, 1]", c.name));
            }
            if c.mean.iter().chain(&c.cov).any(|v| !v.is_finite()) {
                return Err(format!("class {}: non-finite mean or covariance", c.name));
            }
            let cov = DMatrix::from_row_slice(n, n, &c.cov);
            if (cov.clone() - cov.transpose()).amax() > 1e-9 * cov.amax().max(1.0) {
                return Err(format!("class {}: covariance not symmetric", c.name));
            }
            let chol = cov
                .cholesky()
                .ok_or_else(|| format!("class {}: covariance not positive definite", c.name))?;
            let log_det: f64 = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
            let precision = chol.inverse();
            c.precision = precision.transpose().iter().copied().collect();
            c.log_norm = -0.5 * (log_det + n as f64 * (2.0 * std::f64::consts::PI).ln());
        }
        Ok(())
    }

    /// Most probable class and its posterior probability.
    pub fn classify(&self, d: &Detection) -> (u8, f32) {
        let x = features(d);
        let mut best = (contact_class::UNKNOWN, f64::NEG_INFINITY);
        let mut logs = [f64::NEG_INFINITY; 8];
        for (k, c) in self.classes.iter().enumerate().take(8) {
            let lp = c.log_score(&x);
            logs[k] = lp;
            if lp > best.1 {
                best = (c.class, lp);
            }
        }
        let norm: f64 = logs.iter().map(|l| (l - best.1).exp()).sum();
        (best.0, (1.0 / norm) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A covariance with `var` on the diagonal and `(i, j, c)` off it.
    fn cov(var: f64, off: &[(usize, usize, f64)]) -> Vec<f64> {
        let mut m = vec![0.0; N_FEATURES * N_FEATURES];
        for j in 0..N_FEATURES {
            m[j * N_FEATURES + j] = var;
        }
        for &(i, j, c) in off {
            m[i * N_FEATURES + j] = c;
            m[j * N_FEATURES + i] = c;
        }
        m
    }

    fn model() -> Model {
        let class = |class, mean: [f64; N_FEATURES]| {
            ClassModel::new(class, 0.25, mean.to_vec(), cov(0.1, &[]))
        };
        let mut m = Model {
            version: Model::VERSION,
            features: FEATURES.iter().map(|s| s.to_string()).collect(),
            classes: vec![
                class(contact_class::BOAT, [2.5, 1.5, 0.8, 1.8, 0.8, 0.5, 0.3]),
                class(
                    contact_class::CHANNEL_MARKER,
                    [0.0, 2.5, 0.1, 0.3, 0.8, -0.5, -0.5],
                ),
                class(contact_class::EXTENDED, [5.0, 3.0, 1.0, 3.5, 0.8, 1.5, 1.5]),
                class(
                    contact_class::FALSE_ALARM,
                    [-1.0, 0.2, 0.2, -0.3, 0.5, -1.0, -1.0],
                ),
            ],
            provenance: String::new(),
        };
        m.prepare().unwrap();
        m
    }

    #[test]
    fn classifies_by_the_nearest_class_in_feature_space() {
        let m = model();
        let boat = Detection {
            area: 12.0,
            height: 1.4,
            elongation: 2.3,
            extent: [6.0, 2.5],
            mean_hazard: 0.8,
            along_sd_m: 1.6,
            across_sd_m: 1.3,
            ..Default::default()
        };
        let (class, p) = m.classify(&boat);
        assert_eq!(class, contact_class::BOAT);
        assert!(p > 0.9 && p <= 1.0);
    }

    #[test]
    fn the_covariance_between_features_tells_classes_apart() {
        // Two classes alike feature by feature: for one, the spreads along and across the line of
        // sight grow together; for the other, one grows as the other shrinks.
        let mut m = model();
        let (along, across) = (5, 6);
        m.classes[0].mean = vec![0.0; N_FEATURES];
        m.classes[0].cov = cov(1.0, &[(along, across, 0.9)]);
        m.classes[1].mean = vec![0.0; N_FEATURES];
        m.classes[1].cov = cov(1.0, &[(along, across, -0.9)]);
        m.prepare().unwrap();
        let at = |along_sd: f64, across_sd: f64| Detection {
            area: 1.0,
            elongation: 1.0,
            extent: [1.0, 1.0],
            along_sd_m: along_sd,
            across_sd_m: across_sd,
            ..Default::default()
        };
        let e = std::f64::consts::E;
        assert_eq!(m.classify(&at(e, e)).0, contact_class::BOAT);
        assert_eq!(m.classify(&at(e, 1.0 / e)).0, contact_class::CHANNEL_MARKER);
    }

    #[test]
    fn corrupt_or_incomplete_models_are_refused_with_the_reason() {
        let text = serde_json::to_string(&model()).unwrap();
        assert!(Model::parse(&text, "m.json").is_ok());
        let e = Model::parse(&text[..text.len() / 2], "m.json").unwrap_err();
        assert!(matches!(e, ModelError::Parse { .. }), "{e}");
        let refused = |change: &dyn Fn(&mut Model)| {
            let mut m = model();
            change(&mut m);
            Model::parse(&serde_json::to_string(&m).unwrap(), "m.json")
                .unwrap_err()
                .to_string()
        };
        let e = refused(&|m| m.classes.retain(|c| c.class != contact_class::FALSE_ALARM));
        assert!(e.contains("false-alarm missing"), "{e}");
        let e = refused(&|m| m.classes[0].cov[2 * N_FEATURES + 2] = 0.0);
        assert!(e.contains("not positive definite"), "{e}");
        let e = refused(&|m| m.classes[0].cov[1] = 0.05);
        assert!(e.contains("not symmetric"), "{e}");
        let e = refused(&|m| m.classes[0].cov.pop().map_or((), drop));
        assert!(e.contains("covariances expected"), "{e}");
        let e = refused(&|m| m.version = 1);
        assert!(e.contains("version 1"), "{e}");
        let e = Model::load(Path::new("/nonexistent/contact.json")).unwrap_err();
        assert!(matches!(e, ModelError::Read { .. }), "{e}");
    }
}
