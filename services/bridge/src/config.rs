//! Configuration of `bridge run`.
//!
//! ```toml
//! listen = "0.0.0.0:8765"          # Foxglove WebSocket server ("" = no server)
//! topics = []                      # topics shown live (empty: every topic that has a view)
//! client_backlog = 16              # messages queued per client before the oldest is dropped
//!
//! [image]
//! max_hz = 5.0                     # per stereo head
//! downscale = 2                    # integer factor (1 = full size)
//!
//! [max_hz]                         # other topics' rate limits (unlimited if absent)
//! "usv/mapper/world_map" = 2.0
//!
//! [zenoh]                          # cross-host link (binary built with feature `zenoh`)
//! mode = "peer"
//! listen = ["tcp/0.0.0.0:7447"]
//! connect = []
//! scouting = false
//! key_prefix = ""                  # key of a topic: "<key_prefix>/<topic>" or the topic name
//! publish = ["usv/sensors/ins"]    # local topics sent out
//! subscribe = []                   # remote topics republished here
//! ```

use messages::topics;
use serde::Deserialize;
use std::collections::BTreeMap;

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Address of the Foxglove WebSocket server; empty for none (a link-only bridge).
    #[serde(default = "default_listen")]
    pub listen: String,
    /// Topics shown live; empty means every topic that has a Foxglove view.
    #[serde(default)]
    pub topics: Vec<String>,
    /// Messages queued per client; when full the oldest is dropped (and counted).
    #[serde(default = "default_backlog")]
    pub client_backlog: usize,
    #[serde(default)]
    pub image: ImageConfig,
    /// Rate limits (Hz) of other topics, by topic name.
    #[serde(default)]
    pub max_hz: BTreeMap<String, f64>,
    pub zenoh: Option<ZenohConfig>,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ImageConfig {
    /// Highest image rate per stereo head (Hz).
    #[serde(default = "default_image_hz")]
    pub max_hz: f64,
    /// Integer downscale factor: 2 sends a quarter of the pixels (2x2 box average).
    #[serde(default = "default_downscale")]
    pub downscale: u32,
}

impl Default for ImageConfig {
    fn default() -> Self {
        Self {
            max_hz: default_image_hz(),
            downscale: default_downscale(),
        }
    }
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ZenohConfig {
    /// Zenoh session mode: "peer" or "client".
    #[serde(default = "default_zenoh_mode")]
    pub mode: String,
    /// Endpoints to listen on, e.g. "tcp/0.0.0.0:7447".
    #[serde(default)]
    pub listen: Vec<String>,
    /// Endpoints to connect to, e.g. "tcp/192.0.2.1:7447".
    #[serde(default)]
    pub connect: Vec<String>,
    /// Multicast scouting (finding peers on the LAN); off so only the endpoints above are used.
    #[serde(default)]
    pub scouting: bool,
    /// Prepended to topic names to form keys ("boat1" -> "boat1/usv/sensors/ins").
    #[serde(default)]
    pub key_prefix: String,
    /// Local topics published to Zenoh (raw bytes: user header + payload).
    #[serde(default)]
    pub publish: Vec<String>,
    /// Remote topics received from Zenoh and republished into the local domain.
    #[serde(default)]
    pub subscribe: Vec<String>,
}

impl ZenohConfig {
    /// The Zenoh key of `topic`.
    pub fn key(&self, topic: &str) -> String {
        if self.key_prefix.is_empty() {
            topic.to_string()
        } else {
            format!("{}/{topic}", self.key_prefix.trim_end_matches('/'))
        }
    }
}

fn default_listen() -> String {
    "0.0.0.0:8765".into()
}
fn default_backlog() -> usize {
    16
}
fn default_image_hz() -> f64 {
    5.0
}
fn default_downscale() -> u32 {
    1
}
fn default_zenoh_mode() -> String {
    "peer".into()
}

impl Default for Config {
    fn default() -> Self {
        Self {
            listen: default_listen(),
            topics: Vec::new(),
            client_backlog: default_backlog(),
            image: ImageConfig::default(),
            max_hz: BTreeMap::new(),
            zenoh: None,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ConfigError {
    #[error("unknown topic '{0}'")]
    UnknownTopic(String),
    #[error("topic '{0}' has no Foxglove view (only its raw bytes can be forwarded over zenoh)")]
    NoView(String),
    #[error("{what} must be a finite rate above 0 Hz, got {value}")]
    Rate { what: String, value: f64 },
    #[error("image.downscale must be 1..=16, got {0}")]
    Downscale(u32),
    #[error("client_backlog must be at least 1")]
    Backlog,
    #[error("zenoh.mode must be \"peer\" or \"client\", got '{0}'")]
    ZenohMode(String),
    #[error("topic '{0}' is both published to and subscribed from zenoh: it would loop")]
    ZenohLoop(String),
    #[error("the [zenoh] section has neither publish nor subscribe topics")]
    ZenohEmpty,
    #[error("nothing to do: no listen address and no [zenoh] section")]
    Idle,
}

/// Whether topic `name` has a Foxglove view (is shown live).
pub fn has_view(name: &str) -> bool {
    fn schemas<P: ?Sized, H: views::View<P>>(
        _: &messages::Topic<P, H>,
    ) -> &'static [views::Schema] {
        H::schemas()
    }
    messages::with_topic!(name, t => !schemas(t).is_empty()).unwrap_or(false)
}

fn known(name: &str) -> bool {
    topics::ALL.iter().any(|t| t.name == name)
}

impl Config {
    /// Checks everything that can be checked before any port is opened. `has_view` says whether a
    /// topic has a Foxglove view (the binary knows the types).
    pub fn validate(&self, has_view: impl Fn(&str) -> bool) -> Result<(), ConfigError> {
        for t in &self.topics {
            if !known(t) {
                return Err(ConfigError::UnknownTopic(t.clone()));
            }
            if !has_view(t) {
                return Err(ConfigError::NoView(t.clone()));
            }
        }
        for (t, hz) in &self.max_hz {
            if !known(t) {
                return Err(ConfigError::UnknownTopic(t.clone()));
            }
            check_rate(&format!("max_hz.\"{t}\""), *hz)?;
        }
        check_rate("image.max_hz", self.image.max_hz)?;
        if !(1..=16).contains(&self.image.downscale) {
            return Err(ConfigError::Downscale(self.image.downscale));
        }
        if self.client_backlog == 0 {
            return Err(ConfigError::Backlog);
        }
        if let Some(z) = &self.zenoh {
            if z.mode != "peer" && z.mode != "client" {
                return Err(ConfigError::ZenohMode(z.mode.clone()));
            }
            for t in z.publish.iter().chain(&z.subscribe) {
                if !known(t) {
                    return Err(ConfigError::UnknownTopic(t.clone()));
                }
            }
            if let Some(t) = z.publish.iter().find(|t| z.subscribe.contains(t)) {
                return Err(ConfigError::ZenohLoop(t.clone()));
            }
            if z.publish.is_empty() && z.subscribe.is_empty() {
                return Err(ConfigError::ZenohEmpty);
            }
        } else if self.listen.is_empty() {
            return Err(ConfigError::Idle);
        }
        Ok(())
    }

    /// Topics shown live, in pipeline order.
    pub fn live_topics(&self, has_view: impl Fn(&str) -> bool) -> Vec<&'static str> {
        if self.listen.is_empty() {
            return Vec::new();
        }
        topics::ALL
            .iter()
            .map(|t| t.name)
            .filter(|n| has_view(n))
            .filter(|n| self.topics.is_empty() || self.topics.iter().any(|t| t == n))
            .collect()
    }

    /// Rate limit of a topic (Hz); the image limit for stereo frames.
    pub fn rate_of(&self, topic: &str) -> Option<f64> {
        if topic == topics::STEREO_FRAME.name {
            Some(self.image.max_hz)
        } else {
            self.max_hz.get(topic).copied()
        }
    }
}

fn check_rate(what: &str, value: f64) -> Result<(), ConfigError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ConfigError::Rate {
            what: what.into(),
            value,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Config, runtime::config::ConfigError> {
        runtime::config::parse(text, "bridge.toml")
    }

    fn views(t: &str) -> bool {
        t != topics::DISPARITY.name
    }

    #[test]
    fn defaults_show_every_viewable_topic() {
        let c = parse("").unwrap();
        assert_eq!(c, Config::default());
        c.validate(views).unwrap();
        let live = c.live_topics(views);
        assert!(live.contains(&topics::STEREO_FRAME.name));
        assert!(!live.contains(&topics::DISPARITY.name));
        assert_eq!(c.rate_of(topics::STEREO_FRAME.name), Some(5.0));
        assert_eq!(c.rate_of(topics::INS.name), None);
    }

    #[test]
    fn typos_and_bad_values_are_errors() {
        let e = parse("listne = \"x\"").unwrap_err().to_string();
        assert!(e.contains("listne"), "{e}");
        let c = parse("topics = [\"usv/nope\"]").unwrap();
        assert_eq!(
            c.validate(views),
            Err(ConfigError::UnknownTopic("usv/nope".into()))
        );
        let c = parse("topics = [\"usv/stereo/disparity\"]").unwrap();
        assert!(matches!(c.validate(views), Err(ConfigError::NoView(_))));
        let c = parse("[image]\nmax_hz = 0.0").unwrap();
        assert!(matches!(c.validate(views), Err(ConfigError::Rate { .. })));
        let c = parse("[image]\ndownscale = 0").unwrap();
        assert_eq!(c.validate(views), Err(ConfigError::Downscale(0)));
        let c = parse("[max_hz]\n\"usv/mapper/world_map\" = -1.0").unwrap();
        assert!(matches!(c.validate(views), Err(ConfigError::Rate { .. })));
        let c = parse("listen = \"\"").unwrap();
        assert_eq!(c.validate(views), Err(ConfigError::Idle));
    }

    #[test]
    fn demo_set_config_is_valid() {
        let text = include_str!("../../../launch/sets/bridge.toml");
        let c = parse(text).unwrap();
        c.validate(has_view).unwrap();
        assert!(c.live_topics(has_view).contains(&topics::WORLD_MAP.name));
        assert!(has_view(topics::HEARTBEAT.name) && !has_view(topics::DISPARITY.name));
    }

    #[test]
    fn zenoh_section() {
        let c = parse(
            "listen = \"\"\n[zenoh]\nkey_prefix = \"boat1/\"\npublish = [\"usv/sensors/ins\"]\nsubscribe = [\"usv/mapper/world_map\"]\n",
        )
        .unwrap();
        c.validate(views).unwrap();
        assert!(c.live_topics(views).is_empty());
        let z = c.zenoh.unwrap();
        assert_eq!(z.mode, "peer");
        assert!(!z.scouting);
        assert_eq!(z.key("usv/sensors/ins"), "boat1/usv/sensors/ins");
        let c =
            parse("[zenoh]\npublish = [\"usv/sensors/ins\"]\nsubscribe = [\"usv/sensors/ins\"]\n")
                .unwrap();
        assert!(matches!(c.validate(views), Err(ConfigError::ZenohLoop(_))));
        let c = parse("[zenoh]\nmode = \"router\"\npublish = [\"usv/sensors/ins\"]").unwrap();
        assert!(matches!(c.validate(views), Err(ConfigError::ZenohMode(_))));
        let c = parse("[zenoh]\n").unwrap();
        assert_eq!(c.validate(views), Err(ConfigError::ZenohEmpty));
    }
}
