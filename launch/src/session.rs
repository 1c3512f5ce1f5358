//! A process set run by a tool (`usv demo`, `usv eval`): `usv up` in a child process, in a domain and
//! run directory of its own, with its output in a log file; queried over the control socket and
//! always taken down, even when the tool fails half-way.

use crate::control::{self, Reply, Request, ServiceStatus};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub struct Session {
    pub domain: String,
    pub log: PathBuf,
    run_dir: PathBuf,
    supervisor: Child,
    down: bool,
}

impl Session {
    /// Starts `usv up set`; `tag` names the domain and the log file in `out_dir`. The domain becomes
    /// this process's domain too, so tool nodes created afterwards see the set's topics.
    pub fn start(set: &Path, out_dir: &Path, tag: &str) -> anyhow::Result<Self> {
        std::fs::create_dir_all(out_dir)?;
        let domain = format!("{tag}{}", std::process::id());
        let run_dir = std::env::temp_dir().join(format!("usv-{domain}"));
        std::env::set_var(runtime::domain::DOMAIN_ENV, &domain);
        std::env::set_var("USV_RUN_DIR", &run_dir);
        let log = out_dir.join(format!("{tag}.log"));
        let file = std::fs::File::create(&log)?;
        let supervisor = Command::new(usv_program()?)
            .arg("up")
            .arg(set)
            .stdout(file.try_clone()?)
            .stderr(file)
            .stdin(Stdio::null())
            .spawn()?;
        let mut session = Self {
            domain,
            log,
            run_dir,
            supervisor,
            down: false,
        };
        let deadline = Instant::now() + Duration::from_secs(30);
        while session.ps().is_err() {
            session.check_alive()?;
            anyhow::ensure!(
                Instant::now() < deadline,
                "the process set did not come up: see {}",
                session.log.display()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok(session)
    }

    pub fn ps(&self) -> anyhow::Result<Vec<ServiceStatus>> {
        match control::call(Some(&self.domain), &Request::Ps, Duration::from_secs(5))? {
            Reply::Ps { services, .. } => Ok(services),
            other => anyhow::bail!("unexpected reply {other:?}"),
        }
    }

    /// Fails if the supervisor has exited.
    pub fn check_alive(&mut self) -> anyhow::Result<()> {
        if let Some(status) = self.supervisor.try_wait()? {
            anyhow::bail!(
                "the supervisor exited early ({status}): see {}",
                self.log.display()
            );
        }
        Ok(())
    }

    /// `usv down` and wait for the supervisor.
    pub fn down(mut self) -> anyhow::Result<()> {
        self.down = true;
        let reply = control::call(Some(&self.domain), &Request::Down, Duration::from_secs(30));
        let _ = self.supervisor.wait();
        let _ = std::fs::remove_dir_all(&self.run_dir);
        // The supervisor keeps what is in use by live nodes (this tool's); drop those nodes first.
        runtime::cleanup::remove_domain_leftovers(&self.domain)?;
        match reply? {
            Reply::Error { message } => anyhow::bail!(message),
            _ => Ok(()),
        }
    }
}

/// True once the service `name` has exited (a source whose scenario or log is over).
pub fn has_stopped(services: &[ServiceStatus], name: &str) -> bool {
    services
        .iter()
        .any(|s| s.name == name && s.state.starts_with("stopped"))
}

impl Drop for Session {
    fn drop(&mut self) {
        if !self.down {
            let _ = control::call(Some(&self.domain), &Request::Down, Duration::from_secs(10));
            if self.supervisor.try_wait().ok().flatten().is_none() {
                std::thread::sleep(Duration::from_secs(1));
                // Children die with it (PR_SET_PDEATHSIG).
                let _ = self.supervisor.kill();
                let _ = self.supervisor.wait();
            }
            let _ = std::fs::remove_dir_all(&self.run_dir);
        }
    }
}

/// Value at quantile `q` (nearest rank) of unsorted values.
pub fn percentile(values: &[f64], q: f64) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[((v.len() - 1) as f64 * q).round() as usize])
}

/// A file of this checkout: beside the build output (`<checkout>/target/release/usv`) or under the
/// current directory.
pub fn checkout_file(relative: &str) -> anyhow::Result<PathBuf> {
    let relative = Path::new(relative);
    let from_exe = std::env::current_exe()?
        .ancestors()
        .nth(3)
        .map(|repo| repo.join(relative));
    from_exe
        .into_iter()
        .chain([relative.to_path_buf()])
        .find(|p| p.exists())
        .ok_or_else(|| anyhow::anyhow!("{} not found in this checkout", relative.display()))
}

/// The stack's programs that process sets run.
const STACK_PROGRAMS: [&str; 8] = [
    "sim",
    "stereo",
    "perception",
    "mapper",
    "tracker",
    "sequencer",
    "recorder",
    "sensors",
];

/// Makes sure the stack's programs are built next to `usv`. `cargo run -p launch` builds only `usv`;
/// when run that way (cargo sets `CARGO` and `CARGO_MANIFEST_DIR`), build the rest of the workspace's
/// programs too (a no-op when they are fresh, and it keeps them from going stale beside a new `usv`);
/// otherwise say what to do when one is missing.
/// This program's path for starting another `usv`. When run through `cargo run`, the build in
/// [`ensure_stack_built`] may relink `usv` itself (the workspace build unifies features differently
/// from `-p launch`); Linux then reports the running image as "<path> (deleted)", while the fresh
/// binary sits at the original path.
pub fn usv_program() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe()?;
    Ok(
        match exe.to_str().and_then(|s| s.strip_suffix(" (deleted)")) {
            Some(path) => PathBuf::from(path),
            None => exe,
        },
    )
}

pub fn ensure_stack_built() -> anyhow::Result<()> {
    let exe_dir = std::env::current_exe()?
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let missing: Vec<_> = STACK_PROGRAMS
        .iter()
        .filter(|p| !exe_dir.join(p).exists())
        .collect();
    let (Some(cargo), Some(manifest_dir)) = (
        std::env::var_os("CARGO"),
        std::env::var_os("CARGO_MANIFEST_DIR"),
    ) else {
        if missing.is_empty() {
            return Ok(());
        }
        anyhow::bail!(
            "programs {missing:?} are not built next to {}: run `cargo build --release --workspace`",
            exe_dir.display()
        );
    };
    let workspace = Path::new(&manifest_dir)
        .parent()
        .ok_or_else(|| anyhow::anyhow!("no workspace above {manifest_dir:?}"))?
        .join("Cargo.toml");
    let profile = if exe_dir.ends_with("debug") {
        None
    } else {
        Some("--release")
    };
    if !missing.is_empty() {
        println!("building the stack's programs (first run only): {missing:?}");
    }
    let status = Command::new(cargo)
        .args(["build", "--workspace", "--bins", "--manifest-path"])
        .arg(&workspace)
        .args(profile)
        .status()?;
    anyhow::ensure!(status.success(), "building the stack's programs failed");
    Ok(())
}
