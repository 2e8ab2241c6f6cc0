//! `arash daemon`: run the rig (see docs/daemon.md). The same library code as the
//! `arash-daemon` binary that systemd runs, with the same arguments.

pub use arash_daemon::daemon::DaemonArgs as Args;

pub fn run(args: Args) -> anyhow::Result<()> {
    arash_daemon::daemon::run(arash_daemon::daemon::startup::options(args)?)
}
