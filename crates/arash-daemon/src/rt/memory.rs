//! The daemon's memory budget: what `mlockall` keeps resident, kept small on purpose.
//!
//! With `MCL_CURRENT | MCL_FUTURE` every page the process maps stays locked in RAM. On a rig's
//! single-board computer, that memory is taken from everything else. Before this budget, an idle
//! daemon held 100 MB resident and 296 MB locked (docs/daemon.md, "Memory"). Most of it was
//! not the daemon's own:
//! - libzstd's compression workers, made with C's default 8 MB stacks (now compressed on the
//!   logger thread: `flightlog::write_options`);
//! - one malloc arena per thread, each reserving 64 MB of address space ([`one_malloc_arena`]);
//! - Rust's default 2 MB thread stacks ([`CONTROL_STACK_BYTES`], [`LOGGER_STACK_BYTES`]).

/// The control thread's stack. Its deepest call is one cycle: the controller's fixed-size
/// matrices and the link's frame buffers, tens of kB. The daemon's tests run every controller
/// and link on it, and a stack overflow would abort them.
pub const CONTROL_STACK_BYTES: usize = 256 * 1024;

/// The logger thread's stack: MCAP's writer and the protobuf encoder, and the black box
/// written from the heap.
pub const LOGGER_STACK_BYTES: usize = 512 * 1024;

/// Let every thread allocate from the main arena. glibc gives each thread that allocates an arena
/// of its own and reserves 64 MB of address space for it. Under `MCL_FUTURE` the reservation
/// counts as locked memory (VmLck), which was 190 MB of the daemon's 296 MB. The control thread
/// does not allocate in its cycle, so the arenas' lock is never waited for there.
///
/// And keep blocks of [`MMAP_THRESHOLD_BYTES`] or more out of the heap. By default glibc raises
/// its mmap threshold to the size of each large block freed, so the next compression context
/// (one per log file: a run's log beside the daemon's segment) comes from the heap, and the
/// heap's top stays resident: a run under load then added 3.8 MB to the peak, at times and not
/// others (21.2 → 25.0 MB). A fixed threshold gives such blocks their own mapping, returned when
/// freed. Call it before any thread is started. Elsewhere than glibc it does nothing.
pub fn one_malloc_arena() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt takes two integers. Called before other threads exist, it races nothing.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES);
    }
}

/// Blocks this large or larger get a mapping of their own (glibc's default start, 128 kB, held).
pub const MMAP_THRESHOLD_BYTES: libc::c_int = 128 * 1024;

/// The process's memory as the kernel counts it (`/proc/self/status`), in kB.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct MemoryUse {
    /// Resident now (VmRSS).
    pub resident_kb: u64,
    /// Resident at most, since start (VmHWM).
    pub peak_resident_kb: u64,
    /// Locked by `mlockall` (VmLck).
    pub locked_kb: u64,
}

impl MemoryUse {
    /// This process's figures. `None` where /proc is not mounted.
    pub fn of_self() -> Option<Self> {
        std::fs::read_to_string("/proc/self/status").ok().map(|s| Self::parse(&s))
    }

    /// The figures of a `/proc/<pid>/status` text. A field that is missing reads 0.
    pub fn parse(status: &str) -> Self {
        let field = |name: &str| -> u64 {
            status
                .lines()
                .find_map(|l| l.strip_prefix(name)?.strip_prefix(':'))
                .and_then(|v| v.split_whitespace().next()?.parse().ok())
                .unwrap_or(0)
        };
        Self { resident_kb: field("VmRSS"), peak_resident_kb: field("VmHWM"), locked_kb: field("VmLck") }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_status_fields_are_read_in_kb() {
        let status = "Name:\tarash\nVmHWM:\t   21912 kB\nVmRSS:\t   20100 kB\nVmLck:\t   30000 kB\n";
        let m = MemoryUse::parse(status);
        assert_eq!(m, MemoryUse { resident_kb: 20_100, peak_resident_kb: 21_912, locked_kb: 30_000 });
        assert_eq!(MemoryUse::parse("Name:\tx\n"), MemoryUse::default());
    }

    #[test]
    fn this_process_has_resident_memory() {
        let m = MemoryUse::of_self().expect("/proc is mounted on Linux");
        assert!(m.resident_kb > 0 && m.peak_resident_kb >= m.resident_kb, "{m:?}");
    }
}
