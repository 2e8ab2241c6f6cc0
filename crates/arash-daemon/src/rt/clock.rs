//! Absolute-deadline sleeping and the real-time set-up of the control thread.
//!
//! Sleeping to absolute deadlines (`clock_nanosleep(TIMER_ABSTIME)` on `CLOCK_MONOTONIC`) keeps
//! the period from drifting by the cycle's own execution time, which a relative sleep or an
//! async interval would add.

use std::time::Duration;

/// Monotonic time (ns).
pub fn now_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes the timespec we pass.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Sleep until the monotonic clock reads `deadline_ns`.
pub fn sleep_until(deadline_ns: u64) {
    let ts = libc::timespec {
        tv_sec: (deadline_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (deadline_ns % 1_000_000_000) as libc::c_long,
    };
    // SAFETY: an absolute sleep on a valid timespec; EINTR just wakes us early, and the loop
    // checks the clock anyway.
    while unsafe { libc::clock_nanosleep(libc::CLOCK_MONOTONIC, libc::TIMER_ABSTIME, &ts, std::ptr::null_mut()) }
        == libc::EINTR
    {}
}

/// A fixed-rate schedule that skips missed periods instead of bursting to catch up.
pub struct Schedule {
    period_ns: u64,
    next_ns: u64,
}

impl Schedule {
    pub fn new(period: Duration, start_ns: u64) -> Self {
        let period_ns = period.as_nanos() as u64;
        Self { period_ns, next_ns: start_ns + period_ns }
    }

    pub fn next_deadline(&self) -> u64 {
        self.next_ns
    }

    /// Advance past a cycle that finished at `now_ns`; returns how many periods were missed
    /// (deadlines already in the past, which are skipped).
    pub fn advance(&mut self, now_ns: u64) -> u64 {
        self.next_ns += self.period_ns;
        if now_ns < self.next_ns {
            return 0;
        }
        let missed = (now_ns - self.next_ns) / self.period_ns + 1;
        self.next_ns += missed * self.period_ns;
        missed
    }
}

/// How to treat a refusal of real-time scheduling.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RtPolicy {
    /// SCHED_FIFO and mlockall, or refuse to start.
    Require,
    /// Try them; run with ordinary scheduling if refused (logged).
    Ignore,
}

impl std::str::FromStr for RtPolicy {
    type Err = String;

    /// `require` or `ignore`, as the configuration's `rt.policy` and `--rt` spell them.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "require" => Ok(Self::Require),
            "ignore" => Ok(Self::Ignore),
            other => Err(format!("real-time policy must be `require` or `ignore`, not `{other}`")),
        }
    }
}

/// What sets the pace of the control cycles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Pace {
    /// One cycle per period, to absolute deadlines: the rig.
    #[default]
    Deadline,
    /// A simulated rig's pace: each cycle as soon as the link has answered the last one (or a
    /// period has passed without an answer, which counts as a cycle without telemetry). The
    /// simulated rig advances one period per command, so the run is the same run, only as fast
    /// as the host goes; tests and demos whose property is not wall-clock timing use it.
    Lockstep,
}

impl std::str::FromStr for Pace {
    type Err = String;

    /// `deadline` or `lockstep`, as `rt.pace` and `--pace` spell them.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "deadline" => Ok(Self::Deadline),
            "lockstep" => Ok(Self::Lockstep),
            other => Err(format!("the pace must be `deadline` or `lockstep`, not `{other}`")),
        }
    }
}

/// What the real-time set-up achieved.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RtStatus {
    pub fifo: bool,
    pub mlocked: bool,
    /// Why anything was refused.
    pub problems: Vec<String>,
}

/// Lock all memory and switch the calling thread to SCHED_FIFO at `priority`.
pub fn setup_realtime(priority: i32, policy: RtPolicy) -> Result<RtStatus, String> {
    let mut status = RtStatus { fifo: false, mlocked: false, problems: Vec::new() };
    // SAFETY: mlockall and sched_setscheduler take plain integers and a param struct.
    if unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0 {
        status.mlocked = true;
    } else {
        status.problems.push(format!("mlockall: {}", std::io::Error::last_os_error()));
    }
    let param = libc::sched_param { sched_priority: priority };
    if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } == 0 {
        status.fifo = true;
    } else {
        status.problems.push(format!("SCHED_FIFO priority {priority}: {}", std::io::Error::last_os_error()));
    }
    if policy == RtPolicy::Require && !status.problems.is_empty() {
        return Err(format!(
            "real-time set-up refused ({}); run with CAP_SYS_NICE and CAP_IPC_LOCK (see deploy/arash.service), \
             or pass --rt=ignore to run without",
            status.problems.join("; ")
        ));
    }
    Ok(status)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_overrun_skips_the_missed_deadlines() {
        let mut s = Schedule::new(Duration::from_millis(1), 0);
        assert_eq!(s.next_deadline(), 1_000_000);
        assert_eq!(s.advance(1_500_000), 0, "finished before the next deadline");
        assert_eq!(s.next_deadline(), 2_000_000);
        assert_eq!(s.advance(4_200_000), 2, "deadlines 3 and 4 ms are gone");
        assert_eq!(s.next_deadline(), 5_000_000);
        assert_eq!(s.advance(5_999_999), 0);
        assert_eq!(s.advance(7_000_000), 1, "exactly on a deadline counts it as missed");
    }

    #[test]
    fn sleeping_reaches_the_deadline() {
        let deadline = now_ns() + 2_000_000;
        sleep_until(deadline);
        assert!(now_ns() >= deadline);
    }
}
