//! For process tests: a service started as a child in a domain of its own, stopped with SIGTERM (so
//! it leaves no shared memory behind) and its domain's files removed when the guard drops.

use std::ffi::OsStr;
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};

/// Holds the lock that makes timing-sensitive process tests of one test program run one at a
/// time (exact counts through shallow subscriber buffers; the machine may have only two cores).
pub fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

pub struct ServiceProcess {
    child: Child,
    domain: String,
}

impl ServiceProcess {
    /// Starts `program run --config <config>` in `domain`, and makes `domain` this process's domain
    /// too, so tool nodes the test creates afterwards see the service's topics.
    pub fn run(program: &str, config: &OsStr, domain: &str) -> Self {
        std::env::set_var(crate::domain::DOMAIN_ENV, domain);
        let child = Command::new(program)
            .args(["run".as_ref(), "--config".as_ref(), config])
            .env(crate::domain::DOMAIN_ENV, domain)
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {program}: {e}"));
        Self {
            child,
            domain: domain.to_string(),
        }
    }
}

impl Drop for ServiceProcess {
    fn drop(&mut self) {
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
        let _ = self.child.wait();
        let _ = crate::cleanup::remove_domain_leftovers(&self.domain);
    }
}
