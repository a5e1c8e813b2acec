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
///
/// This is `shm_open` done by hand, because the C library's and rustix's follow a symbolic
/// link planted at the object's path: the object is opened with `O_NOFOLLOW`, so a link is
/// refused (`ELOOP`) whatever `fs.protected_symlinks` says (see docs/security.md).
pub fn shm_open(name: &str, create: bool, mode: u32) -> io::Result<File> {
    use rustix::fs::OFlags;
    if name.is_empty() || name.contains('/') || name == "." || name == ".." || name.len() > 255 {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, format!("invalid shared-memory name '{name}'")));
    }
    let flags = OFlags::RDWR | OFlags::NOFOLLOW | OFlags::CLOEXEC;
    let flags = if create { flags | OFlags::CREATE | OFlags::EXCL } else { flags };
    let fd: OwnedFd = rustix::fs::open(format!("{SHM_DIR}/{name}").as_str(), flags, Mode::from_bits_truncate(mode))?;
    if create {
        // open applies the umask; set the requested mode exactly.
        rustix::fs::fchmod(&fd, Mode::from_bits_truncate(mode))?;
    }
    Ok(File::from(fd))
}

/// Who owns an open file, and whether it is a regular file (a shared-memory object is).
pub fn owner_of(file: &File) -> io::Result<(u32, bool)> {
    let st = rustix::fs::fstat(file)?;
    Ok((st.st_uid, rustix::fs::FileType::from_raw_mode(st.st_mode) == rustix::fs::FileType::RegularFile))
}

/// The effective user id of this process.
pub fn euid() -> u32 {
    rustix::process::geteuid().as_raw()
}

/// Removes a shared-memory object by name.
pub fn shm_unlink(name: &str) -> io::Result<()> {
    shm::unlink(format!("/{name}").as_str()).map_err(io::Error::from)
}

/// Maps a whole file read-write and shared, guarded against the file shrinking under it
/// (see [`SharedMap`]).
pub fn map(file: &File) -> io::Result<SharedMap> {
    let map = MmapRaw::map_raw(file)?;
    let slot = guard::register(map.as_mut_ptr() as usize, map.len());
    Ok(SharedMap { map, slot })
}

/// A shared mapping of a segment.
///
/// Another process can shrink the file under a live mapping (`ftruncate`); touching a page
/// past the new end then raises SIGBUS, which would kill the process. While a mapping is
/// registered here, the process's SIGBUS handler replaces the pages from the faulting one to
/// the mapping's end with private zero pages, marks the mapping truncated and lets the
/// access go on. Callers check [`SharedMap::truncated`] at their safe points and end with
/// a clean error. Nothing is added to the access path itself. This is what Wayland
/// compositors do for client-provided shared memory (`wl_shm_buffer_begin_access`).
#[derive(Debug)]
pub struct SharedMap {
    map: MmapRaw,
    /// Registry slot, `None` when the registry was full (the mapping is then unguarded).
    slot: Option<usize>,
}

impl SharedMap {
    pub fn as_mut_ptr(&self) -> *mut u8 {
        self.map.as_mut_ptr()
    }

    /// Whether another process shrank the file under this mapping (a page past its end was
    /// touched, and replaced by zeros).
    pub fn truncated(&self) -> bool {
        self.slot.is_some_and(guard::hit)
    }
}

impl Drop for SharedMap {
    fn drop(&mut self) {
        // Deregister before the mapping goes (the field drops after this).
        if let Some(slot) = self.slot {
            guard::deregister(slot);
        }
    }
}

/// The registry of guarded mappings and the SIGBUS handler that reads it. Lock-free: the
/// handler may run at any point of any thread.
mod guard {
    use std::ffi::c_void;
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::sync::OnceLock;

    /// Mappings guarded at once; a process with more (over 4,096 domains) leaves the rest
    /// unguarded.
    const SLOTS: usize = 4096;

    struct Entry {
        claimed: AtomicBool,
        start: AtomicUsize,
        len: AtomicUsize,
        hit: AtomicBool,
    }

    #[allow(clippy::declare_interior_mutable_const)]
    const EMPTY: Entry = Entry {
        claimed: AtomicBool::new(false),
        start: AtomicUsize::new(0),
        len: AtomicUsize::new(0),
        hit: AtomicBool::new(false),
    };
    static ENTRIES: [Entry; SLOTS] = [EMPTY; SLOTS];
    static PAGE: AtomicUsize = AtomicUsize::new(4096);
    /// The SIGBUS disposition found when the handler was installed, to pass foreign faults to.
    static PREVIOUS: OnceLock<libc::sigaction> = OnceLock::new();

    pub(super) fn register(start: usize, len: usize) -> Option<usize> {
        install();
        let i = ENTRIES
            .iter()
            .position(|e| e.claimed.compare_exchange(false, true, Ordering::AcqRel, Ordering::Relaxed).is_ok())?;
        let e = &ENTRIES[i];
        e.hit.store(false, Ordering::Relaxed);
        e.len.store(len, Ordering::Relaxed);
        e.start.store(start, Ordering::Release);
        Some(i)
    }

    pub(super) fn deregister(i: usize) {
        ENTRIES[i].start.store(0, Ordering::Release);
        ENTRIES[i].claimed.store(false, Ordering::Release);
    }

    pub(super) fn hit(i: usize) -> bool {
        ENTRIES[i].hit.load(Ordering::Relaxed)
    }

    fn install() {
        PREVIOUS.get_or_init(|| {
            // sysconf, not rustix's page size: rustix reads the vDSO's ELF header from the
            // auxiliary vector, which valgrind does not map (a client under valgrind crashed).
            // SAFETY: sysconf has no preconditions.
            let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
            PAGE.store(usize::try_from(page).ok().filter(|p| p.is_power_of_two()).unwrap_or(4096), Ordering::Relaxed);
            // SAFETY: plain sigaction calls with zero-initialised structs (a valid
            // `sigaction` value); the handler is an `extern "C"` fn of the SA_SIGINFO shape.
            unsafe {
                let mut previous: libc::sigaction = std::mem::zeroed();
                let mut action: libc::sigaction = std::mem::zeroed();
                let handler: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut c_void) = on_sigbus;
                action.sa_sigaction = handler as usize;
                action.sa_flags = libc::SA_SIGINFO | libc::SA_NODEFER | libc::SA_ONSTACK;
                libc::sigemptyset(&mut action.sa_mask);
                if libc::sigaction(libc::SIGBUS, &action, &mut previous) != 0 {
                    previous.sa_sigaction = libc::SIG_DFL;
                }
                previous
            }
        });
    }

    extern "C" fn on_sigbus(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut c_void) {
        // SAFETY: the kernel passes a valid siginfo for a SA_SIGINFO handler.
        let addr = unsafe { (*info).si_addr() } as usize;
        let page = PAGE.load(Ordering::Relaxed);
        for e in &ENTRIES {
            let start = e.start.load(Ordering::Acquire);
            let len = e.len.load(Ordering::Relaxed);
            if start == 0 || addr < start || addr >= start + len {
                continue;
            }
            let from = addr & !(page - 1);
            let to = (start + len).div_ceil(page) * page;
            // SAFETY: [from, to) lies within a live mapping of ours (registered until just
            // before it is unmapped); it is replaced by private zero pages of the same
            // protection, so every pointer into it stays valid. mmap is a plain system call.
            let r = unsafe {
                libc::mmap(
                    from as *mut c_void,
                    to - from,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_FIXED,
                    -1,
                    0,
                )
            };
            if r != libc::MAP_FAILED {
                e.hit.store(true, Ordering::Relaxed);
                return;
            }
            break;
        }
        // Not ours (or the remap failed): what would have happened without us.
        match PREVIOUS.get() {
            Some(prev) if prev.sa_sigaction != libc::SIG_DFL && prev.sa_sigaction != libc::SIG_IGN => {
                if prev.sa_flags & libc::SA_SIGINFO != 0 {
                    // SAFETY: the previous handler was installed as a SA_SIGINFO handler.
                    let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut c_void) =
                        unsafe { std::mem::transmute(prev.sa_sigaction) };
                    f(sig, info, ctx);
                } else {
                    // SAFETY: the previous handler was installed as a plain handler.
                    let f: extern "C" fn(libc::c_int) = unsafe { std::mem::transmute(prev.sa_sigaction) };
                    f(sig);
                }
            }
            _ => {
                // SAFETY: restoring the default disposition; the faulting access runs again
                // and the kernel delivers SIGBUS with its default action.
                unsafe { libc::signal(libc::SIGBUS, libc::SIG_DFL) };
            }
        }
    }
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
/// Allocates nothing (the path and the file are read into buffers on the stack): the
/// participant's liveness checks run on the real-time path.
pub fn start_time(pid: u32) -> Option<u64> {
    use std::io::{Read, Write};
    use std::os::unix::ffi::OsStrExt;
    let mut path = [0u8; 32];
    let path_len = {
        let mut w = &mut path[..];
        write!(w, "/proc/{pid}/stat").ok()?;
        32 - w.len()
    };
    let mut file = File::open(std::ffi::OsStr::from_bytes(&path[..path_len])).ok()?;
    // A stat line is a few hundred bytes: the command name (at most 64 bytes) and 50 numbers.
    let mut buf = [0u8; 2048];
    let mut len = 0;
    while len < buf.len() {
        match file.read(&mut buf[len..]) {
            Ok(0) => break,
            Ok(n) => len += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => return None,
        }
    }
    let stat = &buf[..len];
    // The command name may contain spaces, parentheses and any byte: fields start after the
    // last ')', and are ASCII.
    let rest = std::str::from_utf8(&stat[stat.iter().rposition(|&b| b == b')')? + 1..]).ok()?;
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
    if cpu >= rustix::thread::CpuSet::MAX_CPU {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, format!("CPU {cpu} is out of range")));
    }
    let mut set = rustix::thread::CpuSet::new();
    set.set(cpu);
    rustix::thread::sched_setaffinity(None, &set).map_err(io::Error::from)
}

/// The CPUs the calling thread may run on.
pub fn allowed_cpus() -> io::Result<Vec<usize>> {
    let set = rustix::thread::sched_getaffinity(None)?;
    Ok((0..rustix::thread::CpuSet::MAX_CPU).filter(|&c| set.is_set(c)).collect())
}

/// The priority range of `SCHED_FIFO` (1..=99 on Linux).
pub fn fifo_priority_range() -> (i32, i32) {
    // SAFETY: both calls take a policy number and touch no memory.
    let (lo, hi) =
        unsafe { (libc::sched_get_priority_min(libc::SCHED_FIFO), libc::sched_get_priority_max(libc::SCHED_FIFO)) };
    if lo < 0 || hi < 0 {
        (1, 99)
    } else {
        (lo, hi)
    }
}

/// Puts the calling thread under `SCHED_FIFO` at `priority`. Fails with `PermissionDenied`
/// without `CAP_SYS_NICE` (or an `RLIMIT_RTPRIO` that allows the priority), and inside most
/// containers.
///
/// rustix 1.x has no wrapper for `sched_setscheduler`, so this one call goes through the
/// `libc` crate.
pub fn set_fifo_priority(priority: i32) -> io::Result<()> {
    let param = libc::sched_param { sched_priority: priority };
    // SAFETY: `param` is a valid, initialised sched_param that outlives the call; pid 0 is
    // the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Puts the calling thread back under normal (`SCHED_OTHER`) scheduling.
pub fn set_normal_scheduling() -> io::Result<()> {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: as in `set_fifo_priority`.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_OTHER, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Locks every current and future page of the process in RAM (no page faults in the loop).
/// Fails without `CAP_IPC_LOCK` when `RLIMIT_MEMLOCK` is smaller than the process.
pub fn lock_memory() -> io::Result<()> {
    rustix::mm::mlockall(rustix::mm::MlockAllFlags::CURRENT | rustix::mm::MlockAllFlags::FUTURE)
        .map_err(io::Error::from)
}

/// Asks the kernel to send SIGTERM to the calling process when its parent dies, so that a
/// helper process never outlives a launcher that was killed. Async-signal-safe: may be
/// called between fork and exec.
pub fn die_with_parent() -> io::Result<()> {
    rustix::process::set_parent_process_death_signal(Some(rustix::process::Signal::TERM)).map_err(io::Error::from)
}

/// Sets `cmd` up so that the process it starts dies with this one ([`die_with_parent`]),
/// runs under normal scheduling (a real-time parent's `SCHED_FIFO` is not inherited) and, with
/// `cpu`, is pinned to that CPU. What the child cannot apply fails its spawn (pinning) or is
/// ignored (normal scheduling). The one place where a child is prepared between fork and exec.
pub fn die_with_parent_on_spawn(cmd: &mut std::process::Command, cpu: Option<usize>) {
    use std::os::unix::process::CommandExt;
    // SAFETY: the closure runs between fork and exec and only makes system calls (prctl,
    // sched_setscheduler, sched_setaffinity), which are async-signal-safe; it allocates
    // nothing (pin_to_cpu allocates only for an error about a CPU past the kernel's limit).
    unsafe {
        cmd.pre_exec(move || {
            let _ = set_normal_scheduling();
            if let Some(c) = cpu {
                pin_to_cpu(c)?;
            }
            die_with_parent()
        });
    }
}

/// Undoes [`lock_memory`].
pub fn unlock_memory() -> io::Result<()> {
    rustix::mm::munlockall().map_err(io::Error::from)
}

/// Sends signal `sig` (a `libc::SIG*` number) to process `pid`. Used by the demo to steer
/// its child processes.
pub fn send_signal(pid: u32, sig: i32) -> io::Result<()> {
    let pid = rustix::process::Pid::from_raw(pid as i32)
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "pid 0"))?;
    if !(1..=64).contains(&sig) {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, format!("no signal {sig}")));
    }
    // SAFETY: `Signal::from_raw_unchecked` requires a non-zero signal number (checked above);
    // kill(2) rejects one the kernel does not know with EINVAL.
    let sig = unsafe { rustix::process::Signal::from_raw_unchecked(sig) };
    rustix::process::kill_process(pid, sig).map_err(io::Error::from)
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

    #[test]
    fn fifo_range_and_affinity_are_sane() {
        let (lo, hi) = fifo_priority_range();
        assert!(lo >= 1 && hi >= lo);
        let cpus = allowed_cpus().unwrap();
        assert!(!cpus.is_empty());
        assert!(pin_to_cpu(usize::MAX).is_err());
        assert!(send_signal(std::process::id(), 0).is_err());
    }
}
