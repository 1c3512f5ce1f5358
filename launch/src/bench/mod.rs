//! `usv bench <name>`: the one place where the project's performance figures are reproduced on the
//! user's hardware. Every benchmark prints a table, or with `--json` one JSON object per figure.

pub mod ipc;

use serde_json::json;

/// One named figure of a benchmark.
pub struct Figure {
    pub name: String,
    pub value: f64,
    pub unit: &'static str,
    /// Extra labels (size, mode ...), printed as JSON fields.
    pub labels: Vec<(&'static str, serde_json::Value)>,
}

impl Figure {
    pub fn new(name: impl Into<String>, value: f64, unit: &'static str) -> Self {
        Self {
            name: name.into(),
            value,
            unit,
            labels: Vec::new(),
        }
    }

    pub fn label(mut self, key: &'static str, value: impl Into<serde_json::Value>) -> Self {
        self.labels.push((key, value.into()));
        self
    }

    pub fn json_line(&self, bench: &str) -> String {
        let mut obj =
            json!({"bench": bench, "figure": self.name, "value": self.value, "unit": self.unit});
        for (k, v) in &self.labels {
            obj[*k] = v.clone();
        }
        obj.to_string()
    }
}

pub const NAMES: &[&str] = &["ipc", "recorder"];

/// `usv bench recorder`: the recorder's MCAP writer against a plain file write of the same bytes.
pub fn recorder(quick: bool) -> Vec<Figure> {
    recorder::bench::run(quick)
        .into_iter()
        .map(|(name, value, unit)| Figure::new(name, value, unit))
        .collect()
}

/// Prints figures as `name: value unit` lines.
pub fn print_plain(figures: &[Figure]) {
    for f in figures {
        println!("{:<40} {:>12.2} {}", f.name, f.value, f.unit);
    }
}
