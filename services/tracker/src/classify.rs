//! Contact classifier: Gaussian naive Bayes over a few shape features of a detection. Trained
//! offline (`train.rs`, `--example train`) and stored as JSON; loading checks every field, so a
//! missing or corrupt model stops the service at start-up with the reason.

use crate::detect::Detection;
use messages::contact_class;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Feature names, in order; the model file must list the same.
pub const FEATURES: [&str; 5] = [
    "ln_area_m2",
    "height_m",
    "ln_elongation",
    "ln_max_extent_m",
    "mean_hazard",
];

/// The classes the model must cover.
pub const CLASSES: [u8; 4] = [
    contact_class::BOAT,
    contact_class::CHANNEL_MARKER,
    contact_class::EXTENDED,
    contact_class::FALSE_ALARM,
];

pub fn features(d: &Detection) -> [f64; 5] {
    [
        d.area.max(1e-3).ln(),
        d.height,
        d.elongation.max(1.0).ln(),
        d.extent[0].max(d.extent[1]).max(1e-3).ln(),
        d.mean_hazard,
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
    pub var: Vec<f64>,
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
    pub const VERSION: u32 = 1;

    pub fn load(path: &Path) -> Result<Model, ModelError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Read {
            path: p.clone(),
            source,
        })?;
        Self::parse(&text, &p)
    }

    pub fn parse(text: &str, origin: &str) -> Result<Model, ModelError> {
        let model: Model = serde_json::from_str(text).map_err(|e| ModelError::Parse {
            path: origin.to_string(),
            message: e.to_string(),
        })?;
        model.validate().map_err(|message| ModelError::Invalid {
            path: origin.to_string(),
            message,
        })?;
        Ok(model)
    }

    pub fn validate(&self) -> Result<(), String> {
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
        for c in &self.classes {
            let n = FEATURES.len();
            if c.mean.len() != n || c.var.len() != n {
                return Err(format!("class {}: {} features expected", c.name, n));
            }
            if !(c.prior.is_finite() && c.prior > 0.0 && c.prior <= 1.0) {
                return Err(format!("class {}: prior must be in (0, 1]", c.name));
            }
            if c.mean.iter().any(|v| !v.is_finite())
                || c.var.iter().any(|v| !(v.is_finite() && *v > 0.0))
            {
                return Err(format!(
                    "class {}: non-finite mean or non-positive variance",
                    c.name
                ));
            }
        }
        Ok(())
    }

    /// Most probable class and its posterior probability.
    pub fn classify(&self, d: &Detection) -> (u8, f32) {
        let x = features(d);
        let mut best = (contact_class::UNKNOWN, f64::NEG_INFINITY);
        let mut logs = [f64::NEG_INFINITY; 8];
        for (k, c) in self.classes.iter().enumerate().take(8) {
            let mut lp = c.prior.ln();
            for ((xj, m), v) in x.iter().zip(&c.mean).zip(&c.var) {
                let dv = xj - m;
                lp -= 0.5 * (dv * dv / v + (2.0 * std::f64::consts::PI * v).ln());
            }
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

    fn model() -> Model {
        let class = |class, name: &str, mean: [f64; 5]| ClassModel {
            class,
            name: name.into(),
            prior: 0.25,
            mean: mean.to_vec(),
            var: vec![0.1; 5],
        };
        Model {
            version: 1,
            features: FEATURES.iter().map(|s| s.to_string()).collect(),
            classes: vec![
                class(contact_class::BOAT, "boat", [2.5, 1.5, 0.8, 1.8, 0.8]),
                class(
                    contact_class::CHANNEL_MARKER,
                    "marker",
                    [0.0, 2.5, 0.1, 0.3, 0.8],
                ),
                class(
                    contact_class::EXTENDED,
                    "extended",
                    [5.0, 3.0, 1.0, 3.5, 0.8],
                ),
                class(
                    contact_class::FALSE_ALARM,
                    "false-alarm",
                    [-1.0, 0.2, 0.2, -0.3, 0.5],
                ),
            ],
            provenance: String::new(),
        }
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
            ..Default::default()
        };
        let (class, p) = m.classify(&boat);
        assert_eq!(class, contact_class::BOAT);
        assert!(p > 0.9 && p <= 1.0);
    }

    #[test]
    fn corrupt_or_incomplete_models_are_refused_with_the_reason() {
        let text = serde_json::to_string(&model()).unwrap();
        assert!(Model::parse(&text, "m.json").is_ok());
        let e = Model::parse(&text[..text.len() / 2], "m.json").unwrap_err();
        assert!(matches!(e, ModelError::Parse { .. }), "{e}");
        let mut m = model();
        m.classes.retain(|c| c.class != contact_class::FALSE_ALARM);
        let e = Model::parse(&serde_json::to_string(&m).unwrap(), "m.json").unwrap_err();
        assert!(e.to_string().contains("false-alarm missing"), "{e}");
        let mut m = model();
        m.classes[0].var[2] = 0.0;
        assert!(Model::parse(&serde_json::to_string(&m).unwrap(), "m.json").is_err());
        let e = Model::load(Path::new("/nonexistent/contact.json")).unwrap_err();
        assert!(matches!(e, ModelError::Read { .. }), "{e}");
    }
}
