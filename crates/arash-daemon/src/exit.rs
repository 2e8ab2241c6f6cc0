//! How the binaries (`arash-daemon`, `arash`) end: an error for the person at the rig on one line,
//! and a panic reported as a bug.

/// The exit code of `result`, with an error printed as its message and causes on one line,
/// without the backtrace anyhow would add under `RUST_BACKTRACE`. Causes whose text the message
/// already quotes are not repeated.
pub fn exit_code(result: anyhow::Result<()>) -> std::process::ExitCode {
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

fn one_line(e: &anyhow::Error) -> String {
    let mut message = e.to_string();
    for cause in e.chain().skip(1).map(|c| c.to_string()) {
        if !message.contains(&cause) {
            message = format!("{message}: {cause}");
        }
    }
    message
}

/// Report a panic as a bug in arash, not the user's mistake: one line with where it happened,
/// without a backtrace (set `ARASH_BACKTRACE=1` to get one for a bug report).
pub fn report_panics_as_bugs() {
    std::panic::set_hook(Box::new(report_bug));
}

fn report_bug(info: &std::panic::PanicHookInfo) {
    let message = info
        .payload()
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| info.payload().downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown cause".into());
    let place = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
    let thread = std::thread::current().name().unwrap_or("main").to_string();
    eprintln!("error: internal error in arash (thread `{thread}`{place}): {message}. This is a bug; please report it with the command line.");
    if std::env::var_os("ARASH_BACKTRACE").is_some() {
        eprintln!("{}", std::backtrace::Backtrace::force_capture());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context;

    #[test]
    fn causes_are_joined_once() {
        let inner: anyhow::Result<()> = Err(anyhow::anyhow!("no such file"));
        let e = inner.context("reading x.toml").context("invalid configuration").unwrap_err();
        assert_eq!(one_line(&e), "invalid configuration: reading x.toml: no such file");
        let quoted = anyhow::anyhow!("disk full").context("logging stopped: disk full");
        assert_eq!(one_line(&quoted), "logging stopped: disk full");
    }
}
