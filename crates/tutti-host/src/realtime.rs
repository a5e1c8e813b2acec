//! Real-time scheduling of the stepping thread: SCHED_FIFO, locked memory and a pinned CPU,
//! as far as the machine allows; what it refuses is a warning, never an error.

use tutti_core::shm::os;

/// What `--realtime` asks for.
#[derive(Debug, Clone, Copy, Default)]
pub struct RealtimeRequest {
    /// Pin the stepping thread to this CPU.
    pub cpu: Option<usize>,
    /// SCHED_FIFO priority (default: the middle of the range, 50 on Linux).
    pub priority: Option<i32>,
}

/// What could be applied: each entry is a line for the user.
#[derive(Debug, Default)]
pub struct RealtimeOutcome {
    /// What was applied, one line each.
    pub applied: Vec<String>,
    /// What was refused, one line each, naming the missing privilege or limit.
    pub warnings: Vec<String>,
}

/// Applies `req` to the calling thread, as far as the machine allows: memory locking
/// (mlockall), CPU pinning, SCHED_FIFO. Nothing here is fatal: what fails becomes a warning
/// naming the privilege or limit that is missing, and the loop runs with normal scheduling.
pub fn enter_realtime(req: &RealtimeRequest) -> RealtimeOutcome {
    let mut out = RealtimeOutcome::default();
    match os::lock_memory() {
        Ok(()) => out.applied.push("memory locked (mlockall)".into()),
        Err(e) => out.warnings.push(format!(
            "memory not locked: mlockall failed ({e}); needs CAP_IPC_LOCK or a larger RLIMIT_MEMLOCK (ulimit -l)"
        )),
    }
    if let Some(cpu) = req.cpu {
        let allowed = os::allowed_cpus().unwrap_or_default();
        if !allowed.is_empty() && !allowed.contains(&cpu) {
            out.warnings.push(format!("not pinned: CPU {cpu} is not one of the allowed CPUs {allowed:?}"));
        } else {
            match os::pin_to_cpu(cpu) {
                Ok(()) => out.applied.push(format!("pinned to CPU {cpu}")),
                Err(e) => out.warnings.push(format!("not pinned to CPU {cpu}: {e}")),
            }
        }
    }
    let (lo, hi) = os::fifo_priority_range();
    let prio = req.priority.unwrap_or((lo + hi) / 2).clamp(lo, hi);
    if req.priority.is_some_and(|p| p != prio) {
        out.warnings.push(format!("priority clamped to {prio} (SCHED_FIFO allows {lo}..{hi})"));
    }
    match os::set_fifo_priority(prio) {
        Ok(()) => out.applied.push(format!("SCHED_FIFO priority {prio}")),
        Err(e) => out.warnings.push(format!(
            "normal scheduling: SCHED_FIFO {prio} refused ({e}); needs root or CAP_SYS_NICE (e.g. sudo setcap \
             cap_sys_nice,cap_ipc_lock+ep $(which tutti)), or an RLIMIT_RTPRIO of at least {prio}; \
             containers usually forbid it"
        )),
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realtime_request_never_fails_only_warns() {
        // Whatever this machine allows, the outcome names every part: applied or a warning.
        let out = enter_realtime(&RealtimeRequest { cpu: Some(usize::MAX / 2), priority: Some(1000) });
        let all = [out.applied.clone(), out.warnings.clone()].concat().join("\n");
        assert!(all.contains("memory"), "{all}");
        assert!(all.contains("not pinned"), "{all}");
        assert!(all.contains("SCHED_FIFO"), "{all}");
        assert!(out.warnings.iter().any(|w| w.contains("clamped")), "{all}");
        // Back to normal scheduling so the other tests are not affected.
        let _ = os::set_normal_scheduling();
        let _ = os::unlock_memory();
    }
}
