//! The shipped systemd unit: rated by systemd's own checker, and the daemon run under the same
//! privileges it grants (an unprivileged user holding only CAP_SYS_NICE and CAP_IPC_LOCK, no new
//! privileges), against the mock motor.

use std::io::{BufRead, BufReader};
use std::os::unix::net::UnixDatagram;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;

use common::Scratch;

const ARASH: &str = env!("CARGO_BIN_EXE_arash");
/// The unit's binary, `arash-daemon`, built beside `arash` by `cargo test --workspace`.
fn daemon_binary() -> std::path::PathBuf {
    let path = Path::new(ARASH).with_file_name("arash-daemon");
    assert!(path.exists(), "{} is not built: run `cargo build --release -p arash-daemon` first", path.display());
    path
}
const UNIT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../deploy/arash.service");
/// The user the test runs the daemon as (`nobody` on Debian).
const UID: u32 = 65534;

fn have(tool: &str) -> bool {
    Command::new("sh").arg("-c").arg(format!("command -v {tool}")).output().is_ok_and(|o| o.status.success())
}

#[test]
fn systemd_analyze_rates_the_unit_ok() {
    if !have("systemd-analyze") {
        eprintln!("SKIPPED: systemd-analyze is not installed (Debian's `systemd` package has it)");
        return;
    }
    let out = Command::new("systemd-analyze").args(["security", "--offline=true", UNIT]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().find(|l| l.contains("Overall exposure level")).unwrap_or_else(|| panic!("{text}"));
    let score: f64 = line.split(':').nth(1).unwrap().split_whitespace().next().unwrap().parse().unwrap();
    eprintln!("{line}");
    assert!(score <= 2.0, "exposure {score} > 2.0:\n{text}");
    let unit = std::fs::read_to_string(UNIT).unwrap();
    for needed in [
        "User=arash",
        "CapabilityBoundingSet=CAP_SYS_NICE CAP_IPC_LOCK",
        "ProtectSystem=strict",
        "DevicePolicy=closed",
        "RestrictAddressFamilies=AF_UNIX",
    ] {
        assert!(unit.lines().any(|l| l == needed), "the unit lost `{needed}`");
    }
    // The real-time set-up needs these calls; the filter must leave them in.
    let filter: String = unit.lines().filter(|l| l.starts_with("SystemCallFilter=") && !l.contains('~')).collect();
    for call in ["sched_setscheduler", "mlockall", "@system-service"] {
        assert!(filter.contains(call), "SystemCallFilter does not allow {call}");
    }
}

/// A child process killed when dropped.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn ctl(dir: &Path, args: &[&str]) -> String {
    let out = Command::new(ARASH).arg("ctl").arg("--socket").arg(dir.join("s.sock")).args(args).output().unwrap();
    assert!(out.status.success(), "ctl {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn chown(path: &Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: chown on a path we own, as root.
    assert_eq!(unsafe { libc::chown(c.as_ptr(), UID, UID) }, 0, "chown {}", path.display());
}

#[test]
fn the_daemon_runs_a_trajectory_as_an_unprivileged_user_with_only_two_capabilities() {
    // SAFETY: geteuid has no preconditions.
    if unsafe { libc::geteuid() } != 0 || !have("setpriv") {
        eprintln!("SKIPPED: needs root and util-linux's setpriv to drop to an unprivileged user");
        return;
    }
    let dir = Scratch::new("deploy", "setpriv");
    chown(&dir);
    // The simulated drive serves at SCHED_FIFO, as a real drive runs on its own processor: the
    // host's load (the rest of the suite) otherwise starved it past the link's 20 ms timeout.
    let mut mock = Command::new(ARASH)
        .args(["mock-motor", "--rt", "require"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut pty = String::new();
    BufReader::new(mock.stdout.take().unwrap()).read_line(&mut pty).unwrap();
    let _mock = Proc(mock);
    let pty = pty.trim().to_string();
    // udev's job on the rig (deploy/udev/60-arash.rules): the port belongs to the daemon's user.
    chown(Path::new(&pty));
    let notify = UnixDatagram::bind(dir.join("notify.sock")).unwrap();
    chown(&dir.join("notify.sock"));
    notify.set_read_timeout(Some(Duration::from_millis(100))).unwrap();
    let err = std::fs::File::create(dir.join("daemon.err")).unwrap();
    let daemon = Command::new("setpriv")
        .args([
            &format!("--reuid={UID}"),
            &format!("--regid={UID}"),
            "--clear-groups",
            "--inh-caps=-all,+sys_nice,+ipc_lock",
            "--ambient-caps=-all,+sys_nice,+ipc_lock",
            "--bounding-set=-all,+sys_nice,+ipc_lock",
            "--no-new-privs",
        ])
        .arg(daemon_binary())
        .args(["--rt", "require", "--port", &pty])
        .arg("--socket")
        .arg(dir.join("s.sock"))
        .arg("--log-dir")
        .arg(dir.join("logs"))
        .env("NOTIFY_SOCKET", dir.join("notify.sock"))
        .stderr(err)
        .spawn()
        .unwrap();
    let pid = daemon.id();
    let mut daemon = Proc(daemon);
    let log = || std::fs::read_to_string(dir.join("daemon.err")).unwrap_or_default();
    let started = Instant::now();
    let mut buf = [0u8; 256];
    loop {
        if let Ok(n) = notify.recv(&mut buf) {
            if String::from_utf8_lossy(&buf[..n]).contains("READY=1") {
                break;
            }
        }
        assert!(started.elapsed() < Duration::from_secs(10), "no READY=1; daemon:\n{}", log());
    }
    assert!(log().contains("SCHED_FIFO priority 80, memory locked"), "{}", log());
    // The process holds exactly the two capabilities, and runs as the unprivileged user.
    let proc_status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let field = |name: &str| proc_status.lines().find(|l| l.starts_with(name)).unwrap().to_string();
    // Capability numbers from <linux/capability.h>: CAP_IPC_LOCK 14, CAP_SYS_NICE 23.
    let two = (1u64 << 14) | (1u64 << 23);
    let eff = u64::from_str_radix(field("CapEff:").split_whitespace().nth(1).unwrap(), 16).unwrap();
    assert_eq!(eff, two, "{}", field("CapEff:"));
    assert!(field("Uid:").split_whitespace().skip(1).all(|u| u == UID.to_string()), "{}", field("Uid:"));
    assert!(field("NoNewPrivs:").ends_with('1'));

    ctl(&dir, &["enable"]);
    // The daemon reads the file as its own user, as it reads /etc/arash on a rig: a copy it may
    // read (the checkout may sit in a directory only root can enter).
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../../trajectories/paper_validation_0.9.json");
    let trajectory = dir.file("validation.json", &std::fs::read_to_string(shipped).unwrap());
    let written = ctl(&dir, &["run", trajectory.to_str().unwrap(), "--duration", "2", "--wait"]);
    let flight = arash_core::flightlog::read_log(Path::new(written.trim())).unwrap();
    assert_eq!(flight.len(), 2000, "one record per cycle of the 2 s run");
    assert!(flight.cycles.faults.iter().all(|&f| f == 0), "faults during the run");
    // SAFETY: SIGTERM to our own child.
    unsafe { libc::kill(pid as i32, libc::SIGTERM) };
    assert!(daemon.0.wait().unwrap().success(), "{}", log());
}
