//! Service configuration files. Config structs use `#[serde(deny_unknown_fields)]` so that a typo is an
//! error at start-up instead of a silently ignored setting.

use serde::de::DeserializeOwned;
use std::path::Path;

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config file {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("invalid config file {path}: {message}")]
    Parse { path: String, message: String },
}

/// Parses TOML text; `origin` names the text in errors (a path, or "<inline>").
pub fn parse<T: DeserializeOwned>(text: &str, origin: &str) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| ConfigError::Parse {
        path: origin.to_string(),
        message: e.to_string().trim_end().to_string(),
    })
}

/// Reads and parses a TOML file.
pub fn load<T: DeserializeOwned>(path: &Path) -> Result<T, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
        path: path.display().to_string(),
        source,
    })?;
    parse(&text, &path.display().to_string())
}

/// Loads `path` if given, otherwise returns the defaults.
pub fn load_or_default<T: DeserializeOwned + Default>(
    path: Option<&Path>,
) -> Result<T, ConfigError> {
    path.map_or_else(|| Ok(T::default()), load)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize, PartialEq)]
    #[serde(deny_unknown_fields)]
    struct Example {
        rate_hz: f64,
    }

    #[test]
    fn unknown_field_is_named_in_the_error() {
        let err = parse::<Example>("rate_hz = 1.0\nrtae = 2", "example.toml").unwrap_err();
        let text = err.to_string();
        assert!(text.contains("example.toml"), "{text}");
        assert!(text.contains("rtae"), "{text}");
        assert!(text.contains("line 2"), "{text}");
        assert_eq!(
            parse::<Example>("rate_hz = 1.0", "x").unwrap(),
            Example { rate_hz: 1.0 }
        );
    }
}
