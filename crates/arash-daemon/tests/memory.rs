//! The rig's memory budget (rt/memory.rs, docs/daemon.md "Memory"): the `arash-daemon` binary,
//! as systemd runs it, with its memory locked, idle and through every operator command: a short
//! run, hold, disable, reset, and model switches to each controller with a model file that holds
//! only base parameters (the costly kind to check). Resident memory stays within 24 MB at its
//! peak and locked memory within 48 MB, after every command.
//!
//! Locking is the point: the test fails, saying so, where `mlockall` is refused (no
//! CAP_IPC_LOCK and a `ulimit -l` below the budget), rather than pass on unlocked memory.

// The consistent fit's SDP calls BLAS and LAPACK: arash's own, linked by naming the crate.
use arash_blas_lapack as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use arash_core::base_parameters::BaseParameterOptions;
use arash_core::control::{standard_controller, ControllerKind, RobustGains, Trajectory};
use arash_core::identify::{identify, Declared, IdentifyOptions, Log};
use arash_core::model_file::IdentifyMethod;
use arash_core::sim::{Rig, Scenario};
use arash_core::{BaseParameters, ARASH_ASIST_URDF};
use arash_daemon::ctl::{call, wait_for_run, CtlRequest};
use arash_daemon::rt::memory::MemoryUse;

const DAEMON: &str = env!("CARGO_BIN_EXE_arash-daemon");
const TRAJECTORY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../trajectories/paper_validation_0.9.json");
const EXCITATION: &str = include_str!("../../../trajectories/excitation_L5_T15.json");
/// The budget (rt/memory.rs).
const MOST_RESIDENT_KB: u64 = 24 * 1024;
const MOST_LOCKED_KB: u64 = 48 * 1024;

struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The mock motor on a pseudo-terminal, served from a thread of this process until `stop`.
fn mock_motor(stop: Arc<AtomicBool>) -> (String, std::thread::JoinHandle<()>) {
    let (master, slave, path) = arash_mock::pseudo_terminal().unwrap();
    let serving = std::thread::spawn(move || {
        let model = arash_core::arash_asist();
        let scenario = arash_core::sim::Scenario::default();
        let mut motor = arash_mock::MockMotor::new(&model, &scenario, Default::default(), Default::default())
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

/// A model file holding only base parameters, physically consistent (those of CAD): the
/// identification of two periods of the excitation on the simulated rig, its β then set to CAD's.
fn base_only_model_file(dir: &Path) -> PathBuf {
    let model = arash_core::arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let trajectory = Trajectory::from_json(EXCITATION, 3).unwrap();
    let gains = RobustGains::paper(&model).unwrap();
    let controller = standard_controller(ControllerKind::Idc, &model, &model.cad_parameters(), Some(&gains)).unwrap();
    let mut rig = Rig::new(&model, &Scenario::default(), trajectory, controller).unwrap();
    let (mut t, mut q, mut tau) = (vec![], vec![], vec![]);
    for _ in 0..31_000 {
        rig.step().unwrap();
        let r = rig.record();
        t.push(r.t);
        q.extend_from_slice(&r.q);
        tau.extend_from_slice(&r.tau_meas);
    }
    let declared = Declared { model: &model, base: &base, urdf: ARASH_ASIST_URDF };
    let log = Log { t: &t, q: &q, tau: &tau };
    let mut file = identify(declared, log, IdentifyMethod::Ols, &IdentifyOptions::default()).unwrap();
    base.project(&model.cad_parameters(), &mut file.fitted.beta);
    file.fitted.params = None;
    let path = dir.join("base_only.json");
    file.save(&path).unwrap();
    path
}

#[test]
fn the_daemon_stays_within_its_memory_budget_locked_idle_and_through_every_command() {
    let dir = scratch();
    let model_file = base_only_model_file(&dir);
    let stop = Arc::new(AtomicBool::new(false));
    let (pty, serving) = mock_motor(stop.clone());
    let socket = dir.join("s.sock");
    let err = std::fs::File::create(dir.join("daemon.err")).unwrap();
    // `--rt ignore` still locks the memory where it may (and SCHED_FIFO is not what is tested).
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
    assert!(
        idle.locked_kb >= idle.resident_kb * 9 / 10,
        "the daemon's memory is not locked ({idle:?}): mlockall was refused here, and this test measures locked \
         memory. Run it with CAP_IPC_LOCK (as root) or `ulimit -l` of at least {MOST_LOCKED_KB} kB.\n{}",
        stderr()
    );
    let model = Some(model_file.display().to_string());
    let controller = |kind: &str, model: Option<String>| CtlRequest::Controller { kind: kind.into(), model };
    let run = CtlRequest::Run { trajectory: TRAJECTORY.into(), duration_s: Some(8.0), label: Some("memory".into()) };
    let steps = [
        ("idle", None),
        ("status", Some(CtlRequest::Status)),
        ("enable", Some(CtlRequest::Enable)),
        ("run", Some(run)),
        ("hold", Some(CtlRequest::Hold)),
        ("controller robust, base-only model", Some(controller("robust", model.clone()))),
        ("controller idc, base-only model", Some(controller("idc", model.clone()))),
        ("controller pd, base-only model", Some(controller("pd", model.clone()))),
        ("controller robust, CAD", Some(controller("robust", None))),
        ("disable", Some(CtlRequest::Disable)),
        ("reset", Some(CtlRequest::Reset)),
        ("status", Some(CtlRequest::Status)),
    ];
    let mut seen = Vec::new();
    for (name, request) in steps {
        if let Some(request) = request {
            let is_run = matches!(request, CtlRequest::Run { .. });
            let answer = call(&socket, &request).unwrap_or_else(|e| panic!("{name}: {e}\n{}", stderr()));
            if is_run {
                let id = answer["run_id"].as_u64().expect("a run's id");
                wait_for_run(&socket, id, Duration::from_millis(200), |_| Ok(())).unwrap();
            }
        }
        let m = memory_of(pid);
        eprintln!("{name}: {m:?}");
        seen.push((name, m));
    }
    for (name, m) in &seen {
        assert!(m.peak_resident_kb <= MOST_RESIDENT_KB, "after {name}: peak resident {m:?} > {MOST_RESIDENT_KB} kB");
        assert!(m.locked_kb <= MOST_LOCKED_KB, "after {name}: locked {m:?} > {MOST_LOCKED_KB} kB");
    }
    let status = call(&socket, &CtlRequest::Status).unwrap();
    assert_eq!(status["controller"], "robust", "the last switch took");
    assert_eq!(status["memory"]["peak_resident_kb"].as_u64().map(|kb| kb <= MOST_RESIDENT_KB), Some(true));
    drop(daemon);
    stop.store(true, Ordering::Relaxed);
    serving.join().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
