//! Starting and signalling child processes. Each child gets its own process group (so a signal
//! reaches anything it started) and is killed by the kernel when the supervisor dies, even by
//! SIGKILL (PR_SET_PDEATHSIG): no orphans.

use crate::launchfile::ServiceSpec;
use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, Command, Stdio};

/// Starts a service. Its stdout and stderr lines are copied to ours with a `[name]` prefix.
pub fn spawn(spec: &ServiceSpec, dir: &Path, domain: Option<&str>) -> std::io::Result<Child> {
    let mut cmd = Command::new(&spec.program);
    cmd.args(&spec.args)
        .current_dir(dir)
        .envs(&spec.env)
        .env(runtime::SERVICE_NAME_ENV, &spec.name)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    match domain {
        Some(d) => cmd.env(runtime::domain::DOMAIN_ENV, d),
        None => cmd.env_remove(runtime::domain::DOMAIN_ENV),
    };
    // SAFETY: getpid/setpgid/prctl/getppid are async-signal-safe and touch no shared state.
    let supervisor = unsafe { libc::getpid() };
    unsafe {
        cmd.pre_exec(move || {
            if libc::setpgid(0, 0) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            if libc::prctl(
                libc::PR_SET_PDEATHSIG,
                libc::SIGKILL as libc::c_ulong,
                0,
                0,
                0,
            ) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            // The supervisor may have died between fork and prctl: then nobody would kill us.
            if libc::getppid() != supervisor {
                libc::_exit(1);
            }
            Ok(())
        });
    }
    let mut child = cmd.spawn()?;
    let name = spec.name.clone();
    if let Some(out) = child.stdout.take() {
        forward_lines(name.clone(), out);
    }
    if let Some(err) = child.stderr.take() {
        forward_lines(name, err);
    }
    Ok(child)
}

fn forward_lines(name: String, pipe: impl std::io::Read + Send + 'static) {
    std::thread::spawn(move || {
        for line in BufReader::new(pipe).lines() {
            let Ok(line) = line else { break };
            let _ = writeln!(std::io::stderr().lock(), "[{name}] {line}");
        }
    });
}

/// Sends `signal` to the child's whole process group.
pub fn signal_group(pid: u32, signal: libc::c_int) {
    // SAFETY: plain syscall; a stale pid at worst yields ESRCH.
    unsafe {
        libc::kill(-(pid as libc::pid_t), signal);
    }
}
