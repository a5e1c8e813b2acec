//! Every OS call of the shared-memory layer: POSIX shared memory, mapping, futexes,
//! process identity and clocks. Nothing else in the crate talks to the OS.

use std::fs::File;
use std::io;
use std::os::fd::OwnedFd;
use std::sync::atomic::AtomicU32;
use std::time::Duration;

use memmap2::MmapRaw;
use rustix::fs::Mode;
use rustix::shm;
use rustix::thread::futex;

/// Directory where POSIX shared-memory objects appear on Linux.
pub const SHM_DIR: &str = "/dev/shm";

/// Opens a shared-memory object; `create` makes a new one (failing if it exists).
pub fn shm_open(name: &str, create: bool, mode: u32) -> io::Result<File> {
    let flags = if create { shm::OFlags::CREATE | shm::OFlags::EXCL | shm::OFlags::RDWR } else { shm::OFlags::RDWR };
    let fd: OwnedFd = shm::open(format!("/{name}").as_str(), flags, Mode::from_bits_truncate(mode))?;
    if create {
        // shm_open applies the umask; set the requested mode exactly.
        rustix::fs::fchmod(&fd, Mode::from_bits_truncate(mode))?;
    }
    Ok(File::from(fd))
}

/// Removes a shared-memory object by name.
pub fn shm_unlink(name: &str) -> io::Result<()> {
    shm::unlink(format!("/{name}").as_str()).map_err(io::Error::from)
}

/// Maps a whole file read-write and shared.
pub fn map(file: &File) -> io::Result<MmapRaw> {
    MmapRaw::map_raw(file)
}

/// Waits while `word` holds `expected`, at most `timeout`. Returns on wake-up, timeout,
/// signal or when the value already differs; callers re-check their condition.
pub fn futex_wait(word: &AtomicU32, expected: u32, timeout: Duration) {
    let ts = rustix::time::Timespec {
        tv_sec: timeout.as_secs().min(i64::MAX as u64) as i64,
        tv_nsec: i64::from(timeout.subsec_nanos()),
    };
    // Shared (not PRIVATE) futex: the word lives in memory mapped by several processes.
    let _ = futex::wait(word, futex::Flags::empty(), expected, Some(&ts));
}

/// Wakes every waiter on `word`.
pub fn futex_wake_all(word: &AtomicU32) {
    // The kernel reads the count as an int: u32::MAX would be -1, which wakes only one.
    let _ = futex::wake(word, futex::Flags::empty(), i32::MAX as u32);
}

/// A process identity that survives pid reuse: the pid and its start time (clock ticks
/// since boot, field 22 of `/proc/PID/stat`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProcessId {
    pub pid: u32,
    pub start_time: u64,
}

/// This process's identity.
pub fn current_process() -> ProcessId {
    let pid = rustix::process::getpid().as_raw_nonzero().get() as u32;
    ProcessId { pid, start_time: start_time(pid).unwrap_or(0) }
}

/// The start time of `pid`, or `None` if no such process is running (zombies count as dead).
pub fn start_time(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name may contain spaces and parentheses: fields start after the last ')'.
    let rest = &stat[stat.rfind(')')? + 1..];
    let mut fields = rest.split_whitespace();
    let state = fields.next()?;
    if state == "Z" || state == "X" {
        return None;
    }
    // `rest` starts at field 3 (state); the start time is field 22.
    fields.nth(18)?.parse().ok()
}

/// Whether the process `id` is still the one running under its pid.
pub fn is_alive(id: ProcessId) -> bool {
    if id.pid == 0 {
        return false;
    }
    match start_time(id.pid) {
        None => false,
        // A start time of 0 means it was not recorded: the pid alone decides.
        Some(t) => id.start_time == 0 || t == id.start_time,
    }
}

/// Wall-clock time in nanoseconds since the Unix epoch.
pub fn now_ns() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_nanos() as u64).unwrap_or(0)
}

/// The names of the shared-memory objects in [`SHM_DIR`] that start with `prefix`.
pub fn list_shm(prefix: &str) -> io::Result<Vec<String>> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(SHM_DIR)? {
        let name = entry?.file_name().to_string_lossy().into_owned();
        if name.starts_with(prefix) {
            out.push(name);
        }
    }
    out.sort();
    Ok(out)
}

/// Pins the calling thread to `cpu`.
pub fn pin_to_cpu(cpu: usize) -> io::Result<()> {
    let mut set = rustix::thread::CpuSet::new();
    set.set(cpu);
    rustix::thread::sched_setaffinity(None, &set).map_err(io::Error::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn own_process_is_alive_and_a_fake_start_time_is_not() {
        let me = current_process();
        assert!(me.start_time > 0);
        assert!(is_alive(me));
        assert!(!is_alive(ProcessId { pid: me.pid, start_time: me.start_time + 1 }));
        assert!(!is_alive(ProcessId { pid: 0, start_time: 0 }));
    }
}
