//! `arash daemon`: run the rig (see docs/daemon.md), with the same arguments as the
//! `arash-daemon` binary that systemd runs.
//!
//! It runs that binary when it sits beside this one (cargo builds both into one directory; the
//! install puts both in /usr/local/bin). Under `mlockall` every page of a binary's code is locked
//! and resident, and this binary carries the tools too (identification, reports, figures): twice
//! the rig's code, 29 MB locked at idle against its 20 (docs/daemon.md, "Memory"). Without it
//! beside, the daemon runs here, and says what that costs.

use std::os::unix::process::CommandExt;

pub use arash_daemon::daemon::DaemonArgs as Args;

pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(rig) = rig_binary() {
        // `arash daemon ARGS…` becomes `arash-daemon ARGS…`, in this process (same PID, so that
        // signals and systemd see one daemon).
        let error = std::process::Command::new(&rig).args(std::env::args_os().skip(2)).exec();
        eprintln!("arash: could not run {} ({error}); running the daemon in this binary", rig.display());
    } else {
        eprintln!(
            "arash: arash-daemon is not beside this binary: running the daemon in it, which locks about 9 MB more \
             code than arash-daemon would"
        );
    }
    arash_daemon::daemon::run(arash_daemon::daemon::startup::options(args)?)
}

/// `arash-daemon` in this binary's own directory, if it is there.
fn rig_binary() -> Option<std::path::PathBuf> {
    let rig = std::env::current_exe().ok()?.with_file_name("arash-daemon");
    rig.is_file().then_some(rig)
}
