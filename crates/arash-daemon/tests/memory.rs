//! The rig's memory budget (rt/memory.rs, docs/daemon.md "Memory"): the `arash-daemon` binary,
//! as systemd runs it, plays a 30 s trajectory against the mock motor. Its peak resident and
//! locked memory must stay within twice the budget (24 MB resident, 48 MB locked). Before the
//! budget, the idle daemon alone held 102 MB resident and 298 MB locked.

use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use arash_daemon::ctl::{call, wait_for_run, CtlRequest};
use arash_daemon::rt::memory::MemoryUse;

const DAEMON: &str = env!("CARGO_BIN_EXE_arash-daemon");
const TRAJECTORY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../trajectories/paper_validation_0.9.json");
/// Twice the budget: generous, so that a busy CI machine does not fail it, and still far below
/// the 102 MB and 298 MB that the budget replaced.
const MOST_RESIDENT_KB: u64 = 2 * 24 * 1024;
const MOST_LOCKED_KB: u64 = 2 * 48 * 1024;

struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The mock motor on a pseudo-terminal, served from a thread of this process until `stop`.
fn mock_motor(stop: Arc<AtomicBool>) -> (String, std::thread::JoinHandle<()>) {
    let (master, slave, path) = arash_daemon::mock::pseudo_terminal().unwrap();
    let serving = std::thread::spawn(move || {
        let model = arash_core::arash_asist();
        let scenario = arash_core::sim::Scenario::default();
        let mut motor = arash_daemon::mock::MockMotor::new(&model, &scenario, Default::default(), Default::default())
            .expect("the mock motor");
        motor.serve(master, &stop).unwrap();
        drop(slave);
    });
    (path, serving)
}

fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("arash-memory-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn memory_of(pid: u32) -> MemoryUse {
    MemoryUse::parse(&std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap())
}

#[test]
fn a_30_s_run_stays_within_the_memory_budget() {
    let dir = scratch();
    let stop = Arc::new(AtomicBool::new(false));
    let (pty, serving) = mock_motor(stop.clone());
    let socket = dir.join("s.sock");
    let err = std::fs::File::create(dir.join("daemon.err")).unwrap();
    // `--rt ignore`: without CAP_IPC_LOCK the bound on resident memory is still tested.
    let daemon = Command::new(DAEMON)
        .args(["--rt", "ignore", "--port", &pty])
        .arg("--socket")
        .arg(&socket)
        .arg("--log-dir")
        .arg(dir.join("logs"))
        .stderr(err)
        .spawn()
        .unwrap();
    let pid = daemon.id();
    let daemon = Killed(daemon);
    let stderr = || std::fs::read_to_string(dir.join("daemon.err")).unwrap_or_default();
    let started = Instant::now();
    while call(&socket, &CtlRequest::Status).is_err() {
        assert!(started.elapsed() < Duration::from_secs(10), "the daemon did not start:\n{}", stderr());
        std::thread::sleep(Duration::from_millis(50));
    }
    let idle = memory_of(pid);
    call(&socket, &CtlRequest::Enable).unwrap_or_else(|e| panic!("enable: {e}\n{}", stderr()));
    let run = CtlRequest::Run { trajectory: TRAJECTORY.into(), duration_s: Some(30.0), label: Some("memory".into()) };
    let id = call(&socket, &run).unwrap()["run_id"].as_u64().unwrap();
    let log = wait_for_run(&socket, id, Duration::from_millis(500), |_| Ok(())).unwrap();
    let after = memory_of(pid);
    let status = call(&socket, &CtlRequest::Status).unwrap();
    eprintln!(
        "idle: {idle:?}; after the 30 s run: {after:?}; missed cycles {}, log dropped {}",
        status["missed_cycles"], status["log_dropped"]
    );
    assert_eq!(status["memory"]["peak_resident_kb"].as_u64().map(|kb| kb >= after.resident_kb), Some(true));
    assert!(Path::new(&log).exists());
    assert!(
        after.peak_resident_kb <= MOST_RESIDENT_KB,
        "peak resident {} kB > {MOST_RESIDENT_KB} kB",
        after.peak_resident_kb
    );
    assert!(after.locked_kb <= MOST_LOCKED_KB, "locked {} kB > {MOST_LOCKED_KB} kB", after.locked_kb);
    drop(daemon);
    stop.store(true, Ordering::Relaxed);
    serving.join().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
