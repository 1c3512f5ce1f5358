//! Process sets: the launch file format and its validation. A launch file that fails validation
//! starts nothing.
//!
//! ```toml
//! name = "demo"                    # optional, defaults to the file stem
//! heartbeat_timeout_ms = 2000      # defaults for every service
//!
//! [[service]]
//! name = "stereo"
//! program = "stereo"               # next to `usv`, a path relative to this file, or on PATH
//! args = ["run", "--config", "stereo.toml"]
//! env = { USV_LOG = "debug" }
//! restart = "on-failure"           # never | on-failure | always
//! depends_on = ["sim"]
//! ```

use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RestartPolicy {
    Never,
    OnFailure,
    Always,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSet {
    name: Option<String>,
    heartbeat_timeout_ms: Option<u64>,
    startup_timeout_ms: Option<u64>,
    stop_grace_ms: Option<u64>,
    #[serde(default, rename = "service")]
    services: Vec<RawService>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawService {
    name: String,
    program: String,
    #[serde(default)]
    args: Vec<String>,
    #[serde(default)]
    env: BTreeMap<String, String>,
    restart: Option<RestartPolicy>,
    heartbeat_timeout_ms: Option<u64>,
    startup_timeout_ms: Option<u64>,
    backoff_initial_ms: Option<u64>,
    backoff_max_ms: Option<u64>,
    #[serde(default)]
    depends_on: Vec<String>,
    /// Services that publish no heartbeat (foreign programs) are supervised by exit status only.
    #[serde(default = "yes")]
    heartbeat: bool,
}

fn yes() -> bool {
    true
}

/// One service of a validated process set.
#[derive(Debug, Clone, PartialEq)]
pub struct ServiceSpec {
    pub name: String,
    /// Resolved executable path.
    pub program: PathBuf,
    pub args: Vec<String>,
    pub env: BTreeMap<String, String>,
    pub restart: RestartPolicy,
    /// `None`: the service is not expected to publish heartbeats.
    pub heartbeat_timeout_ms: Option<u64>,
    pub startup_timeout_ms: u64,
    pub backoff_initial_ms: u64,
    pub backoff_max_ms: u64,
    pub depends_on: Vec<String>,
}

/// A validated process set, services in start order (dependencies first).
#[derive(Debug, Clone)]
pub struct ProcessSet {
    pub name: String,
    /// Working directory of the children: the launch file's directory.
    pub dir: PathBuf,
    pub stop_grace_ms: u64,
    pub services: Vec<ServiceSpec>,
}

#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    #[error("cannot read launch file {0}: {1}")]
    Read(String, std::io::Error),
    #[error("invalid launch file {file}: {message}")]
    Syntax { file: String, message: String },
    #[error("{file}: service '{service}': {message}")]
    Service {
        file: String,
        service: String,
        message: String,
    },
    #[error("{file}: {message}")]
    Set { file: String, message: String },
}

const DEFAULT_HEARTBEAT_TIMEOUT_MS: u64 = 2000;
const DEFAULT_STARTUP_TIMEOUT_MS: u64 = 10_000;
const DEFAULT_STOP_GRACE_MS: u64 = 3000;
const DEFAULT_BACKOFF_INITIAL_MS: u64 = 50;
const DEFAULT_BACKOFF_MAX_MS: u64 = 5000;

impl ProcessSet {
    pub fn load(path: &Path) -> Result<Self, LaunchError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| LaunchError::Read(path.display().to_string(), e))?;
        let dir = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let dir = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("set");
        Self::parse(&text, &path.display().to_string(), stem, &dir)
    }

    /// Parses and validates launch file text; `file` names it in errors, `dir` resolves relative paths.
    pub fn parse(
        text: &str,
        file: &str,
        default_name: &str,
        dir: &Path,
    ) -> Result<Self, LaunchError> {
        let raw: RawSet = toml::from_str(text).map_err(|e| LaunchError::Syntax {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let set_err = |message: String| LaunchError::Set {
            file: file.to_string(),
            message,
        };
        let svc_err = |service: &str, message: String| LaunchError::Service {
            file: file.to_string(),
            service: service.to_string(),
            message,
        };
        if raw.services.is_empty() {
            return Err(set_err("no [[service]] entries".into()));
        }
        let name = raw.name.clone().unwrap_or_else(|| default_name.to_string());
        validate_name(&name).map_err(|m| set_err(format!("set name: {m}")))?;

        let mut index = HashMap::new();
        for (i, s) in raw.services.iter().enumerate() {
            validate_name(&s.name).map_err(|m| svc_err(&s.name, m))?;
            if index.insert(s.name.as_str(), i).is_some() {
                return Err(svc_err(&s.name, "duplicate service name".into()));
            }
        }
        for s in &raw.services {
            for dep in &s.depends_on {
                if !index.contains_key(dep.as_str()) {
                    return Err(svc_err(
                        &s.name,
                        format!("depends_on names unknown service '{dep}'"),
                    ));
                }
            }
        }
        let order = start_order(&raw.services, &index).map_err(set_err)?;

        let mut services = Vec::with_capacity(order.len());
        for i in order {
            let s = &raw.services[i];
            let program = resolve_program(&s.program, dir).ok_or_else(|| {
                svc_err(
                    &s.name,
                    format!(
                        "program '{}' not found (looked next to usv, relative to {}, and on PATH)",
                        s.program,
                        dir.display()
                    ),
                )
            })?;
            let heartbeat_timeout = s
                .heartbeat_timeout_ms
                .or(raw.heartbeat_timeout_ms)
                .unwrap_or(DEFAULT_HEARTBEAT_TIMEOUT_MS);
            services.push(ServiceSpec {
                name: s.name.clone(),
                program,
                args: s.args.clone(),
                env: s.env.clone(),
                restart: s.restart.unwrap_or(RestartPolicy::OnFailure),
                heartbeat_timeout_ms: s.heartbeat.then_some(heartbeat_timeout),
                startup_timeout_ms: s
                    .startup_timeout_ms
                    .or(raw.startup_timeout_ms)
                    .unwrap_or(DEFAULT_STARTUP_TIMEOUT_MS),
                backoff_initial_ms: s.backoff_initial_ms.unwrap_or(DEFAULT_BACKOFF_INITIAL_MS),
                backoff_max_ms: s.backoff_max_ms.unwrap_or(DEFAULT_BACKOFF_MAX_MS),
                depends_on: s.depends_on.clone(),
            });
        }
        Ok(Self {
            name,
            dir: dir.to_path_buf(),
            stop_grace_ms: raw.stop_grace_ms.unwrap_or(DEFAULT_STOP_GRACE_MS),
            services,
        })
    }
}

fn validate_name(name: &str) -> Result<(), String> {
    let ok = !name.is_empty()
        && name.len() <= 32
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(format!(
            "invalid name '{name}': use 1-32 letters, digits, '-' or '_'"
        ))
    }
}

/// Topological order of the services (Kahn's algorithm, ties broken by file order so the order is
/// stable); a cycle is an error that names the services on it.
fn start_order(
    services: &[RawService],
    index: &HashMap<&str, usize>,
) -> Result<Vec<usize>, String> {
    let mut missing_deps: Vec<usize> = services.iter().map(|s| s.depends_on.len()).collect();
    let mut order = Vec::with_capacity(services.len());
    let mut placed = vec![false; services.len()];
    while order.len() < services.len() {
        let Some(next) = (0..services.len()).find(|&i| !placed[i] && missing_deps[i] == 0) else {
            let on_cycle: Vec<_> = (0..services.len())
                .filter(|&i| !placed[i])
                .map(|i| services[i].name.as_str())
                .collect();
            return Err(format!(
                "cycle in depends_on among services: {}",
                on_cycle.join(", ")
            ));
        };
        placed[next] = true;
        order.push(next);
        for (i, s) in services.iter().enumerate() {
            missing_deps[i] -= s
                .depends_on
                .iter()
                .filter(|d| index[d.as_str()] == next)
                .count();
        }
    }
    Ok(order)
}

/// Finds a program: a path (absolute, or relative to the launch file) if it contains '/', otherwise
/// next to the running `usv` binary (the workspace's build output) and then on PATH.
pub fn resolve_program(program: &str, dir: &Path) -> Option<PathBuf> {
    let is_exec = |p: &Path| {
        use std::os::unix::fs::PermissionsExt;
        p.metadata()
            .map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
            .unwrap_or(false)
    };
    if program.contains('/') {
        let p = dir.join(program);
        return is_exec(&p).then_some(p);
    }
    let beside_usv = std::env::current_exe()
        .ok()
        .and_then(|exe| exe.parent().map(|d| d.join(program)));
    let on_path = std::env::var_os("PATH")
        .into_iter()
        .flat_map(|paths| std::env::split_paths(&paths).collect::<Vec<_>>())
        .map(|d| d.join(program));
    beside_usv.into_iter().chain(on_path).find(|p| is_exec(p))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<ProcessSet, LaunchError> {
        ProcessSet::parse(text, "set.toml", "set", Path::new("/"))
    }

    #[test]
    fn valid_set_is_ordered_by_dependencies() {
        let set = parse(
            r#"
            [[service]]
            name = "b"
            program = "/bin/sh"
            depends_on = ["a"]
            [[service]]
            name = "a"
            program = "/bin/sh"
            restart = "always"
            heartbeat = false
            "#,
        )
        .unwrap();
        let names: Vec<_> = set.services.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(set.services[0].restart, RestartPolicy::Always);
        assert_eq!(set.services[0].heartbeat_timeout_ms, None);
        assert_eq!(set.services[1].restart, RestartPolicy::OnFailure);
        assert_eq!(set.services[1].heartbeat_timeout_ms, Some(2000));
    }

    #[test]
    fn unknown_field_is_named_with_its_line() {
        let err =
            parse("[[service]]\nname = \"a\"\nprogram = \"/bin/sh\"\nrestart_policy = \"never\"\n")
                .unwrap_err()
                .to_string();
        assert!(err.contains("restart_policy"), "{err}");
        assert!(err.contains("line 4"), "{err}");
    }

    #[test]
    fn bad_restart_value_is_named() {
        let err =
            parse("[[service]]\nname = \"a\"\nprogram = \"/bin/sh\"\nrestart = \"sometimes\"\n")
                .unwrap_err()
                .to_string();
        assert!(
            err.contains("sometimes") && err.contains("on-failure"),
            "{err}"
        );
    }

    #[test]
    fn missing_program_names_service_and_program() {
        let err = parse("[[service]]\nname = \"a\"\nprogram = \"no-such-program-xyz\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("'a'") && err.contains("no-such-program-xyz"),
            "{err}"
        );
        let err = parse("[[service]]\nname = \"a\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("program"), "{err}");
    }

    #[test]
    fn cycle_is_reported_with_its_members() {
        let err = parse(
            r#"
            [[service]]
            name = "a"
            program = "/bin/sh"
            depends_on = ["c"]
            [[service]]
            name = "b"
            program = "/bin/sh"
            depends_on = ["a"]
            [[service]]
            name = "c"
            program = "/bin/sh"
            depends_on = ["b"]
            [[service]]
            name = "free"
            program = "/bin/sh"
            "#,
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("cycle") && err.contains("a, b, c"), "{err}");
        assert!(!err.contains("free"), "{err}");
    }

    #[test]
    fn duplicate_and_unknown_dependency_are_errors() {
        let dup = "[[service]]\nname = \"a\"\nprogram = \"/bin/sh\"\n[[service]]\nname = \"a\"\nprogram = \"/bin/sh\"\n";
        assert!(parse(dup)
            .unwrap_err()
            .to_string()
            .contains("duplicate service name"));
        let dep = "[[service]]\nname = \"a\"\nprogram = \"/bin/sh\"\ndepends_on = [\"ghost\"]\n";
        assert!(parse(dep).unwrap_err().to_string().contains("ghost"));
    }
}
