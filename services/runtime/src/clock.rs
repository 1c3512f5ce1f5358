//! The monotonic clock shared by all processes on the machine (CLOCK_MONOTONIC), in nanoseconds.
//! Used for heartbeats, watchdogs of live runs and latency measurements across processes; algorithms
//! never read it (they take the input stamp as "now").

pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime only writes the timespec we pass; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}
