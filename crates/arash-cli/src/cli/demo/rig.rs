//! The rig the demo drives: `arash mock-motor` on a pseudo-terminal (arash's serial protocol),
//! `python -m arash.cia402_sim` on one (the same simulated rig behind CiA 402 drives, reached
//! as an slcan adapter), or a real port; and `arash daemon` on it. Both are child processes of
//! the demo, commanded over the daemon's socket exactly as `arash ctl` does.
//!
//! The children run in their own process groups, so a Ctrl-C at the terminal reaches only the
//! demo: it then disables the motors through the daemon, stops the daemon with SIGTERM (which
//! closes its logs cleanly) and only then stops the mock.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use arash_daemon::ctl::{call, wait_for_run, CtlRequest};
use arash_daemon::rt::clock::{Pace, RtPolicy};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// Route SIGINT and SIGTERM to a flag the demo polls between (and during) its steps.
pub fn catch_interrupts() {
    let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
    unsafe {
        libc::signal(libc::SIGINT, handler);
        libc::signal(libc::SIGTERM, handler);
    }
}

/// Fail with "interrupted" once Ctrl-C was pressed.
pub fn check_interrupt() -> anyhow::Result<()> {
    anyhow::ensure!(!INTERRUPTED.load(Ordering::SeqCst), "interrupted (Ctrl-C)");
    Ok(())
}

/// Where the motors are: a simulated rig (scenario file and seed) or a real port.
pub enum Motors<'a> {
    Mock { scenario: &'a Path, seed: u64 },
    Port(&'a str),
}

/// The motor link the daemon speaks (`arash daemon --link`), and with it the simulator a mock
/// rig is served by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Link {
    /// arash's own protocol on a serial line; the simulated rig is `arash mock-motor`.
    Serial,
    /// CiA 402 drives over CANopen through an slcan adapter; the simulated rig is
    /// `python -m arash.cia402_sim` (Python with arash, python-can and canopen: `ARASH_PYTHON`,
    /// default `python3`).
    Canopen,
}

impl Link {
    fn daemon_flag(self) -> &'static str {
        match self {
            Link::Serial => "serial",
            Link::Canopen => "canopen",
        }
    }

    /// The command that serves the simulated rig on a pseudo-terminal and prints its path.
    fn simulator(self, exe: &Path, scenario: &Path, seed: u64, rt: &str, pace: Pace) -> Command {
        match self {
            Link::Serial => {
                let mut c = Command::new(exe);
                c.arg("mock-motor").arg("--scenario").arg(scenario).args(["--seed", &seed.to_string(), "--rt", rt]);
                if pace == Pace::Lockstep {
                    c.args(["--watchdog-ms", &LOCKSTEP_DRIVE_WATCHDOG_MS.to_string()]);
                }
                c
            }
            Link::Canopen => {
                let python = std::env::var_os("ARASH_PYTHON").unwrap_or_else(|| "python3".into());
                let mut c = Command::new(python);
                c.args(["-m", "arash.cia402_sim", "--scenario"]).arg(scenario).args(["--seed", &seed.to_string()]);
                c
            }
        }
    }
}

/// The simulated drive's watchdog in lockstep. The mock advances its plant one period per host
/// command, so a host that stalls freezes the simulated rig with it and nothing moves unwatched;
/// a wall-clock watchdog of a real drive's 100 ms then only latches the host's stalls (103 ms
/// seen in CI, behind the logger's disk writes). A host that died still stops the drive.
const LOCKSTEP_DRIVE_WATCHDOG_MS: u64 = 2000;

pub struct Rig {
    socket: PathBuf,
    daemon: Option<Child>,
    mock: Option<Child>,
    /// The motor port the daemon drives.
    pub port: String,
}

impl Rig {
    /// Start the motors and the daemon (idc with CAD, motors disabled) with its logs in
    /// `dir/logs` and its standard error in `dir/daemon.log`; `live` streams it (an address, or
    /// the daemon's default).
    pub fn start(
        dir: &Path,
        motors: Motors,
        link: Link,
        (rt, pace): (RtPolicy, Pace),
        live: Option<&Option<String>>,
    ) -> anyhow::Result<Self> {
        let rt = match rt {
            RtPolicy::Require => "require",
            RtPolicy::Ignore => "ignore",
        };
        let pace_flag = match pace {
            Pace::Deadline => "deadline",
            Pace::Lockstep => "lockstep",
        };
        let exe = std::env::current_exe().context("locating the arash executable")?;
        let mut rig = Rig { socket: dir.join("arash.sock"), daemon: None, mock: None, port: String::new() };
        rig.port = match motors {
            Motors::Port(port) => port.to_string(),
            Motors::Mock { scenario, seed } => {
                let log = std::fs::File::create(dir.join("mock-motor.log"))?;
                let mut simulator = link.simulator(&exe, scenario, seed, rt, pace);
                let mut child = simulator
                    .stdout(Stdio::piped())
                    .stderr(log)
                    .process_group(0)
                    .spawn()
                    .with_context(|| format!("starting {:?}", simulator.get_program()))?;
                let mut line = String::new();
                BufReader::new(child.stdout.take().expect("piped")).read_line(&mut line)?;
                rig.mock = Some(child);
                if line.trim().is_empty() {
                    let log = std::fs::read_to_string(dir.join("mock-motor.log")).unwrap_or_default();
                    let last = log.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("").trim();
                    anyhow::bail!("the simulated rig did not start: {last} (see {}/mock-motor.log)", dir.display());
                }
                line.trim().to_string()
            }
        };
        let config = dir.join("daemon.toml");
        std::fs::write(&config, "# The demo's daemon: the paper's baseline first.\n[control]\ncontroller = \"idc\"\n")?;
        let _ = std::fs::remove_file(&rig.socket);
        let log = std::fs::File::create(dir.join("daemon.log"))?;
        let mut daemon = Command::new(&exe);
        daemon.args(["daemon", "--rt", rt, "--pace", pace_flag, "--link", link.daemon_flag(), "--port", &rig.port]);
        daemon.arg("--config").arg(&config);
        if let Some(address) = live {
            daemon.arg("--live").args(address.iter());
        }
        let child = daemon
            .arg("--socket")
            .arg(&rig.socket)
            .arg("--log-dir")
            .arg(dir.join("logs"))
            .stdout(Stdio::null())
            .stderr(log)
            .process_group(0)
            .spawn()
            .context("starting arash daemon")?;
        rig.daemon = Some(child);
        let started = Instant::now();
        while call(&rig.socket, &CtlRequest::Status).is_err() {
            check_interrupt()?;
            if let Some(status) = rig.daemon.as_mut().and_then(|d| d.try_wait().ok().flatten()) {
                let log = std::fs::read_to_string(dir.join("daemon.log")).unwrap_or_default();
                let last = log.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("").trim();
                anyhow::bail!("the daemon exited ({status}): {last} (see {}/daemon.log)", dir.display());
            }
            anyhow::ensure!(
                started.elapsed() < Duration::from_secs(15),
                "the daemon did not open its socket within 15 s; see {}/daemon.log",
                dir.display()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        Ok(rig)
    }

    pub fn call(&self, request: &CtlRequest) -> anyhow::Result<serde_json::Value> {
        call(&self.socket, request)
    }

    /// Switch the control law, with a model file or the CAD parameters.
    pub fn controller(&self, kind: &str, model: Option<&Path>) -> anyhow::Result<()> {
        let model = model.map(|m| m.display().to_string());
        self.call(&CtlRequest::Controller { kind: kind.into(), model }.absolute()?)
            .with_context(|| format!("switching to the {kind} controller"))?;
        Ok(())
    }

    /// Enable the motors, unless they already are.
    pub fn enable(&self) -> anyhow::Result<()> {
        if self.call(&CtlRequest::Status)?["mode"] != "enabled" {
            self.call(&CtlRequest::Enable).context("enabling the motors")?;
        }
        Ok(())
    }

    /// Play `trajectory` for `duration_s` (its natural length if `None`), showing progress, and
    /// return the run's log file once it is finished.
    pub fn run(&self, trajectory: &Path, duration_s: Option<f64>, label: &str) -> anyhow::Result<PathBuf> {
        let request =
            CtlRequest::Run { trajectory: trajectory.display().to_string(), duration_s, label: Some(label.into()) };
        let answer = self.call(&request.absolute()?)?;
        let id = answer["run_id"].as_u64().unwrap_or(0);
        let total = answer["duration_s"].as_f64().unwrap_or(0.0);
        let mut running_since: Option<Instant> = None;
        let mut shown = String::new();
        let log = wait_for_run(&self.socket, id, Duration::from_millis(100), |status| {
            check_interrupt()?;
            let ours = status["run_id"].as_u64() == Some(id);
            if ours && status["phase"] == "run" && running_since.is_none() {
                running_since = Some(Instant::now());
            }
            let done = running_since.map_or(0.0, |s| s.elapsed().as_secs_f64().min(total));
            let what = if running_since.is_some() { "running" } else { "approaching the start" };
            let line = format!("\r    {label}: {what}, {:.0} / {total:.0} s   ", done.floor());
            if line != shown {
                eprint!("{line}");
                let _ = std::io::stderr().flush();
                shown = line;
            }
            Ok(())
        })
        .with_context(|| label.to_string())?;
        eprintln!("\r    {label}: {total:.1} / {total:.1} s, logged to {}", log.display());
        Ok(log)
    }

    /// Disable the motors, stop the daemon (its logs are closed on SIGTERM) and the mock.
    pub fn stop(&mut self) -> anyhow::Result<()> {
        let disabled = self.call(&CtlRequest::Disable);
        if let Some(mut daemon) = self.daemon.take() {
            // SAFETY: signalling our own child.
            unsafe { libc::kill(daemon.id() as i32, libc::SIGTERM) };
            let started = Instant::now();
            while daemon.try_wait()?.is_none() {
                if started.elapsed() > Duration::from_secs(10) {
                    let _ = daemon.kill();
                    break;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = daemon.wait();
        }
        if let Some(mut mock) = self.mock.take() {
            let _ = mock.kill();
            let _ = mock.wait();
        }
        disabled.map(|_| ()).context("disabling the motors")
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        let _ = self.stop();
    }
}
