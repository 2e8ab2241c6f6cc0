//! End to end: `arash mock-motor` on a pseudo-terminal, `arash daemon` against it, commanded
//! with `arash ctl`. No hardware and no root (`--rt ignore`).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use arash_core::control::ControllerKind;
use arash_core::flightlog::read_log;

mod common;

use common::Scratch;

const ARASH: &str = env!("CARGO_BIN_EXE_arash");

/// One test at a time: each runs a 1 kHz mock and a 1 kHz daemon under `--rt ignore`, and two
/// such pairs on a 2-core machine starve each other (CI once saw a velocity-limit fault from it).
fn serial() -> std::sync::MutexGuard<'static, ()> {
    static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());
    SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// `arash` for offline work (identification) while a mock rig and its daemon run: at the lowest
/// priority, as a lab would run it beside a rig. At normal priority a fit that takes both cores
/// starves the 1 kHz pair under `--rt ignore`, and the daemon latches a link timeout (CI on
/// 5162116 and a local run on 2879ac0).
fn offline() -> Command {
    let mut command = Command::new("nice");
    command.args(["-n", "19", ARASH]);
    command
}

/// A child process killed when dropped.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Start the mock motor with an optional fault plan; returns it and its pty.
fn mock(dir: &Scratch, faults: Option<&str>) -> (Proc, String) {
    mock_with(dir, faults, &[])
}

/// [`mock`] with more `arash mock-motor` arguments.
fn mock_with(dir: &Scratch, faults: Option<&str>, args: &[&str]) -> (Proc, String) {
    let mut cmd = Command::new(ARASH);
    cmd.arg("mock-motor").args(args).stdout(Stdio::piped()).stderr(Stdio::null());
    if let Some(f) = faults {
        cmd.arg("--faults").arg(dir.file("faults.toml", f));
    }
    let mut child = cmd.spawn().unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    (Proc(child), line.trim().to_string())
}

/// `arash daemon` on `pty` with `config` (TOML text), its socket and logs in `dir`.
fn daemon_command(dir: &Scratch, pty: &str, config: &str) -> Command {
    let config_path = dir.file("daemon.toml", config);
    let mut cmd = Command::new(ARASH);
    cmd.args(["daemon", "--rt", "ignore", "--port", pty, "--config"])
        .arg(&config_path)
        .arg("--socket")
        .arg(dir.join("s.sock"))
        .arg("--log-dir")
        .arg(dir.join("logs"));
    cmd
}

/// `config` with the daemon in lockstep with the mock (`rt.pace`): the same run as fast as the host
/// goes, and the same on a busy host. For the tests whose property is not wall-clock timing.
fn lockstep(config: &str) -> String {
    format!("[rt]\npace = \"lockstep\"\n{config}")
}

/// Start the daemon on `pty` and wait until its socket takes connections. The socket's file
/// appears at `bind`, before the daemon listens: a `ctl` in between is refused (seen in CI on a
/// loaded host).
fn daemon(dir: &Scratch, pty: &str, config: &str) -> Proc {
    let err = std::fs::OpenOptions::new().create(true).append(true).open(dir.join("daemon.err")).unwrap();
    let child = daemon_command(dir, pty, config).stderr(err).spawn().unwrap();
    let started = Instant::now();
    while std::os::unix::net::UnixStream::connect(dir.join("s.sock")).is_err() {
        assert!(started.elapsed() < Duration::from_secs(10), "no socket; daemon.err:\n{}", stderr(dir));
        std::thread::sleep(Duration::from_millis(20));
    }
    Proc(child)
}

fn stderr(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("daemon.err")).unwrap_or_default()
}

fn ctl(dir: &Path, args: &[&str]) -> Result<String, String> {
    let out = Command::new(ARASH).arg("ctl").arg("--socket").arg(dir.join("s.sock")).args(args).output().unwrap();
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    } else {
        Err(String::from_utf8_lossy(&out.stderr).into_owned())
    }
}

fn status(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&ctl(dir, &["status"]).unwrap()).unwrap()
}

/// Poll `status` until `condition` holds (or fail after `timeout`).
fn wait_until(dir: &Path, timeout: Duration, what: &str, condition: impl Fn(&serde_json::Value) -> bool) {
    let started = Instant::now();
    loop {
        let s = status(dir);
        if condition(&s) {
            return;
        }
        assert!(started.elapsed() < timeout, "timed out waiting for {what}; status {s}\n{}", stderr(dir));
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn terminate(p: &mut Proc) -> std::process::ExitStatus {
    // SAFETY: sending SIGTERM to our own child.
    unsafe { libc::kill(p.0.id() as i32, libc::SIGTERM) };
    p.0.wait().unwrap()
}

fn logs(dir: &Path, prefix: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> =
        std::fs::read_dir(dir.join("logs")).map(|r| r.flatten().map(|e| e.path()).collect()).unwrap_or_default();
    v.retain(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix));
    v.sort();
    v
}

#[test]
fn an_excitation_run_through_the_daemon_identifies_the_mock() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "identify");
    let excitation = dir.join("excitation.json");
    let out = Command::new(ARASH)
        .args(["excite", "--restarts", "1", "--rate", "10", "-o"])
        .arg(&excitation)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // A drive whose watchdog waits a second, not 100 ms: the lockstep daemon runs at ordinary
    // priority, and on CI's two cores, beside the other lane's identifications, the host held it
    // past 100 ms once in a 30 s run (host timeout at cycle 15607, run AZ). The watchdog itself
    // is `after_kill_9_the_log_is_recovered_and_the_daemon_comes_back_disabled`'s subject.
    let (_mock, pty) = mock_with(&dir, None, &["--watchdog-ms", "1000"]);
    let mut d = daemon(&dir, &pty, &lockstep("[control]\ncontroller = \"idc\"\n"));
    ctl(&dir, &["enable"]).unwrap();
    let log = ctl(&dir, &["run", excitation.to_str().unwrap(), "--duration", "30", "--label", "excitation", "--wait"])
        .unwrap_or_else(|e| panic!("{e}\n{}", stderr(&dir)));
    let log = PathBuf::from(log.trim());
    let flight = read_log(&log).unwrap();
    assert!(!flight.truncated);
    // The run lasts 30 s on the drive's clock. A measurement the mock's link repeats or skips
    // (a few dozen in 30,000 on a loaded host) holds or advances that clock by a cycle, so the
    // count of cycles may differ from 30,000 by as many; none may be lost (next assertion).
    let span = flight.cycles.t.last().unwrap() - flight.cycles.t[0];
    assert!((span - 30.0).abs() < 0.01, "the run spans {span} s of the drive's clock");
    assert!(flight.len().abs_diff(30_000) <= 100, "one message per cycle of the 30 s run: {}", flight.len());
    assert!(flight.cycles.cycle.windows(2).all(|w| w[1] == w[0] + 1), "consecutive cycles, none lost to the log");
    assert!(flight.cycles.faults.iter().all(|&f| f == 0));
    let timing = &flight.json["/arash/timing"];
    assert!(timing.len() >= 29, "timing statistics once a second: {}", timing.len());
    assert!(timing[0].1.contains("missed_cycles"));
    // The identifications below take both cores for a while: the motors are off meanwhile, so
    // that a daemon the host holds back cannot trip the drive's watchdog (issue 62).
    ctl(&dir, &["disable"]).unwrap();

    let model = dir.join("model.json");
    // The physically consistent fit: the robust controller below needs a positive-definite mass
    // matrix, which OLS on 30 s of closed-loop data does not guarantee.
    let out = offline()
        .arg("identify")
        .arg(&log)
        .args(["--periods", "2", "--method", "consistent", "-o"])
        .arg(&model)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let model: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    eprintln!("preprocessing: {}", model["settings"]["reasons"]);
    // OLS is the issue's criterion (≥ 90 %); the consistent fit trades a little fit for physical
    // parameters (91–95 % in repeated runs here).
    for (fit, bound) in [("training_ols", 90.0), ("training", 85.0)] {
        let fp: Vec<f64> = serde_json::from_value(model[fit]["fp_percent"].clone()).unwrap();
        eprintln!("FP% ({fit}) on the daemon's excitation log: {fp:?}");
        assert!(fp.iter().all(|&x| x >= bound), "{fit}: FP% {fp:?}");
    }

    // The run's log names the controller that ran it, so the closed-loop estimator (which
    // simulates the loop) needs nothing beyond the log.
    let named = flight.logged_controller().expect("a run's log names its controller").unwrap();
    assert!(
        matches!(
            named,
            arash_core::identify::closed_loop::LoggedController::Standard { kind: ControllerKind::Idc, .. }
        ),
        "{named:?}"
    );
    let iv = dir.join("iv.json");
    let out = offline()
        .arg("identify")
        .arg(&log)
        .args(["--periods", "2", "--method", "idim-iv", "-o"])
        .arg(&iv)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let iv: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&iv).unwrap()).unwrap();
    let reasons = iv["settings"]["reasons"].as_array().cloned().unwrap_or_default();
    let fp: Vec<f64> = serde_json::from_value(iv["training"]["fp_percent"].clone()).unwrap();
    eprintln!("IDIM-IV on the daemon's log: FP% {fp:?}; {reasons:?}");
    let simulated = |r: &serde_json::Value| r["code"] == "closed_loop" && r["estimator"] == "IDIM-IV";
    assert!(reasons.iter().any(simulated), "{reasons:?}");
    assert!(fp.iter().all(|&x| x >= 90.0), "IDIM-IV training FP% {fp:?}");

    // A model that is not physically consistent is refused for the model-based laws.
    let ols = dir.join("ols.json");
    let out = offline().arg("identify").arg(&log).args(["--periods", "2", "-o"]).arg(&ols).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let ols_model: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&ols).unwrap()).unwrap();
    let worst: f64 = serde_json::from_value::<Vec<f64>>(ols_model["min_pseudo_inertia_eigenvalue"].clone())
        .unwrap()
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    let answer = ctl(&dir, &["controller", "robust", "--model", ols.to_str().unwrap()]);
    eprintln!("OLS model: smallest pseudo-inertia eigenvalue {worst:.3e}; daemon: {answer:?}");
    assert_eq!(answer.is_ok(), worst >= -1e-9, "{answer:?}");
    if let Err(e) = answer {
        assert!(e.contains("not physically consistent"), "{e}");
    }

    // A consistent file edited by hand to a mass of −2 kg, still claiming to be consistent.
    let mut tampered = model.clone();
    tampered["params"][0] = (-2.0).into();
    let tampered_path = dir.file("tampered.json", &tampered.to_string());
    let err = ctl(&dir, &["controller", "robust", "--model", tampered_path.to_str().unwrap()]).unwrap_err();
    assert!(err.contains("not physically consistent") && err.contains("yaw_yoke"), "{err}");
    assert_eq!(status(&dir)["controller"], "idc", "a refused model changes nothing");

    // Close the loop: switch to the robust controller with the identified model and track the
    // paper's ω = 0.5 trajectory for 5 s.
    let model_path = dir.join("model.json");
    let s: serde_json::Value =
        serde_json::from_str(&ctl(&dir, &["controller", "robust", "--model", model_path.to_str().unwrap()]).unwrap())
            .unwrap();
    assert_eq!(s["controller"], "robust");
    ctl(&dir, &["enable"]).unwrap();
    let trajectory = concat!(env!("CARGO_MANIFEST_DIR"), "/../../trajectories/paper_validation_0.5.json");
    let log = ctl(&dir, &["run", trajectory, "--duration", "5", "--wait"]).unwrap();
    let tracked = read_log(Path::new(log.trim())).unwrap();
    assert!(tracked.cycles.faults.iter().all(|&f| f == 0));
    assert!(tracked.cycles.controller.iter().all(|&c| c == 3), "robust throughout");
    let worst = (0..tracked.len())
        .map(|i| (tracked.cycles.q[3 * i + 2] - tracked.cycles.q_des[3 * i + 2]).abs())
        .fold(0.0, f64::max);
    eprintln!("robust controller with the identified model: max insertion error {:.1} µm", worst * 1e6);
    assert!(worst < 500e-6, "insertion error {worst} m");
    assert!(terminate(&mut d).success());
}

#[test]
fn plans_beyond_the_limits_are_refused_before_anything_moves() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "plans");
    let (_mock, pty) = mock(&dir, None);
    let mut d = daemon(&dir, &pty, "");
    ctl(&dir, &["enable"]).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    let before = status(&dir);
    let yaw = dir.file("yaw.json", r#"{"format": "arash-trajectory/1", "kind": "hold", "q": [1.5, 0.2, 0.005]}"#);
    let err = ctl(&dir, &["run", yaw.to_str().unwrap()]).unwrap_err();
    assert!(err.contains("sample 0") && err.contains("joint 0 `yaw`") && err.contains("0.741765"), "{err}");
    // 12 rad/s on yaw (the limit is 3.49 rad/s), inside the position limits.
    let fast = dir.file(
        "fast.json",
        r#"{"kind": "fourier", "harmonics": 1, "period_s": 0.05235987755982988, "q0": [0, 0.2, 0.005],
            "a": [[12.0], [0], [0]], "b": [[0], [0], [0]], "condition_number": 1}"#,
    );
    let err = ctl(&dir, &["run", fast.to_str().unwrap()]).unwrap_err();
    assert!(err.contains("speed 12.0") && err.contains("3.490659"), "{err}");
    std::thread::sleep(Duration::from_millis(200));
    let after = status(&dir);
    assert_eq!(after["mode"], "enabled", "{after}");
    assert_eq!(after["phase"], "hold", "no approach started: {after}");
    assert_eq!(after["runs"], serde_json::json!({}), "no run registered: {after}");
    for k in 0..3 {
        let moved = (after["q"][k].as_f64().unwrap() - before["q"][k].as_f64().unwrap()).abs();
        assert!(moved < 2e-3, "joint {k} moved {moved}: {before} → {after}");
    }
    assert!(terminate(&mut d).success());
}

#[test]
fn the_control_socket_refuses_abuse_and_a_refused_request_changes_nothing() {
    use std::io::{Read, Write};
    use std::os::unix::net::UnixStream;
    let _serial = serial();
    let dir = Scratch::new("e2e", "socket");
    let (_mock, pty) = mock(&dir, None);
    let mut d = daemon(&dir, &pty, "");
    wait_until(&dir, Duration::from_secs(5), "telemetry", |s| s["telemetry"] == true);
    let connect = || {
        let c = UnixStream::connect(dir.join("s.sock")).unwrap();
        c.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        c
    };
    let answer = |c: &mut UnixStream| {
        let mut line = String::new();
        BufReader::new(c.try_clone().unwrap()).read_line(&mut line).unwrap();
        serde_json::from_str::<serde_json::Value>(&line).unwrap_or_else(|e| panic!("{e}: {line:?}"))
    };
    // Malformed, unknown, not UTF-8: each answered with an error naming it, on one connection.
    let mut c = connect();
    for (line, expect) in [
        (&b"{not json\n"[..], "bad request"),
        (b"{\"cmd\":\"self-destruct\"}\n", "unknown variant"),
        (b"\xff\xfe\n", "not UTF-8"),
        (b"{\"cmd\":\"run\",\"trajectory\":\"/dev/zero\"}\n", "enable the motors"),
    ] {
        c.write_all(line).unwrap();
        let a = answer(&mut c);
        assert_eq!(a["ok"], false, "{a}");
        assert!(a["error"].as_str().unwrap().contains(expect), "{a}");
    }
    // An oversized line: refused and the connection closed.
    let mut big = connect();
    let _ = big.write_all(&vec![b'x'; 100_000]);
    let a = answer(&mut big);
    assert!(a["error"].as_str().unwrap().contains("longer than"), "{a}");
    let mut rest = Vec::new();
    assert_eq!(big.read_to_end(&mut rest).unwrap_or(0), 0, "closed after the refusal");
    // A client that disconnects in the middle of `enable` has asked for nothing.
    let mut cut = connect();
    cut.write_all(b"{\"cmd\":\"enable\"}").unwrap();
    drop(cut);
    std::thread::sleep(Duration::from_millis(200));
    let s = status(&dir);
    assert_eq!(s["mode"], "disabled", "{s}");
    // A trajectory path that is a device is refused without stalling the daemon.
    ctl(&dir, &["enable"]).unwrap();
    let err = ctl(&dir, &["run", "/dev/zero"]).unwrap_err();
    assert!(err.contains("not a regular file"), "{err}");
    assert_eq!(status(&dir)["phase"], "hold");
    assert!(terminate(&mut d).success());
}

#[test]
fn link_faults_are_counted_logged_and_ridden_through() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "linkfaults");
    let (_mock, pty) =
        mock(&dir, Some("seed = 3\ncorrupt = 0.02\ndrop = 0.01\nreorder = 0.01\ndelay = 0.01\ndelay_frames = 3\n"));
    let mut d = daemon(&dir, &pty, "");
    ctl(&dir, &["enable"]).unwrap();
    std::thread::sleep(Duration::from_secs(3));
    let s = status(&dir);
    let link = &s["link"];
    assert_eq!(s["mode"], "enabled", "sporadic errors must not trip the link timeout: {s}");
    for key in ["crc_errors", "lost", "stale"] {
        assert!(link[key].as_u64().unwrap() > 0, "{key} not counted: {link}");
    }
    assert!(terminate(&mut d).success());
    let events: Vec<String> = logs(&dir, "daemon-")
        .iter()
        .flat_map(|p| read_log(p).unwrap().json.remove("/arash/event").unwrap_or_default())
        .map(|e| e.1)
        .collect();
    assert!(events.iter().any(|e| e.contains("link errors") && e.contains("CRC")), "{events:?}");
}

#[test]
fn silence_trips_the_link_timeout_ramps_down_and_writes_a_black_box() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "silence");
    let (_mock, pty) = mock(&dir, Some("silent_at_s = 3.0\n"));
    let mut d = daemon(&dir, &pty, "");
    ctl(&dir, &["enable"]).unwrap();
    wait_until(&dir, Duration::from_secs(5), "a fault", |s| s["mode"] == "faulted");
    let s = status(&dir);
    assert_eq!(s["faults"], serde_json::json!(["link timeout"]));
    assert!(ctl(&dir, &["enable"]).is_err(), "enabling over a latched fault is refused");
    std::thread::sleep(Duration::from_millis(300));
    let boxes = logs(&dir, "blackbox-");
    assert_eq!(boxes.len(), 1, "{boxes:?}");
    let bb = read_log(&boxes[0]).unwrap();
    assert!(bb.len() >= 1900 && bb.len() <= 2001, "about 2 s of cycles: {}", bb.len());
    assert_eq!(*bb.cycles.faults.last().unwrap(), 16, "ends on the faulting cycle");
    assert!(terminate(&mut d).success());
}

/// Play the ω = 0.5 validation trajectory with the mock's fault `plan` until the daemon faults;
/// return the faults it names.
fn faults_during_a_run(name: &str, plan: &str, config: &str) -> serde_json::Value {
    let dir = Scratch::new("e2e", name);
    let (_mock, pty) = mock(&dir, Some(plan));
    let _d = daemon(&dir, &pty, &lockstep(config));
    ctl(&dir, &["enable"]).unwrap();
    let trajectory = concat!(env!("CARGO_MANIFEST_DIR"), "/../../trajectories/paper_validation_0.5.json");
    ctl(&dir, &["run", trajectory]).unwrap();
    wait_until(&dir, Duration::from_secs(15), "a fault", |s| s["mode"] == "faulted");
    status(&dir)["faults"].clone()
}

#[test]
fn a_stuck_encoder_trips_the_following_error() {
    let _serial = serial();
    let faults = faults_during_a_run("stuck", "stuck_at_s = 4.0\nstuck_joint = 0\n", "");
    assert_eq!(faults, serde_json::json!(["following error"]));
}

#[test]
fn a_current_mismatch_trips() {
    let _serial = serial();
    let plan = "mismatch_at_s = 2.0\nmismatch_joint = 2\nmismatch_factor = 0.5\n";
    let faults = faults_during_a_run("mismatch", plan, "[safety]\nmismatch_fraction = 0.05\n");
    assert_eq!(faults, serde_json::json!(["current mismatch"]));
}

/// Pitch position (rad) in a status answer.
fn pitch(s: &serde_json::Value) -> f64 {
    s["q"][1].as_f64().unwrap()
}

#[test]
fn a_daemon_restarted_while_the_drive_is_still_powered_switches_it_off() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "restart");
    // A drive whose own watchdog is slower than the restart: it stays powered, holding the dead
    // daemon's last current.
    let (_mock, pty) = mock_with(&dir, None, &["--watchdog-ms", "60000"]);
    let mut d = daemon(&dir, &pty, "");
    ctl(&dir, &["enable"]).unwrap();
    let trajectory = concat!(env!("CARGO_MANIFEST_DIR"), "/../../trajectories/paper_validation_0.9.json");
    ctl(&dir, &["run", trajectory]).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    d.0.kill().unwrap();
    d.0.wait().unwrap();
    std::fs::remove_file(dir.join("s.sock")).unwrap();
    let _d = daemon(&dir, &pty, "");
    wait_until(&dir, Duration::from_secs(5), "telemetry", |s| s["telemetry"] == true);
    wait_until(&dir, Duration::from_secs(1), "the drive off", |s| s["drive"]["powered"] == false);
    let first = status(&dir);
    assert_eq!(first["mode"], "disabled", "{first}");
    std::thread::sleep(Duration::from_millis(500));
    let later = status(&dir);
    assert_eq!(later["drive"]["powered"], false, "the drive was powered again: {later}");
    assert!((pitch(&later) - pitch(&first)).abs() < 1e-3, "the pitch joint moved: {first} → {later}");
    ctl(&dir, &["enable"]).unwrap();
}

#[test]
fn a_drive_that_reports_power_on_at_start_up_is_switched_off() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "powered");
    let (_mock, pty) = mock_with(&dir, None, &["--watchdog-ms", "60000", "--powered", "0,0.5,0"]);
    let _d = daemon(&dir, &pty, "");
    wait_until(&dir, Duration::from_secs(5), "telemetry", |s| s["telemetry"] == true);
    wait_until(&dir, Duration::from_secs(1), "the drive off", |s| s["drive"]["powered"] == false);
    let s = status(&dir);
    assert_eq!(s["mode"], "disabled", "{s}");
    assert_eq!(s["faults"], serde_json::json!([]), "{s}");
}

#[test]
fn after_kill_9_the_log_is_recovered_and_the_daemon_comes_back_disabled() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "kill9");
    let (_mock, pty) = mock(&dir, None);
    // In lockstep: what is lost is counted in cycles, not in the host's wall-clock luck.
    let mut d = daemon(&dir, &pty, &lockstep(""));
    ctl(&dir, &["enable"]).unwrap();
    // Two and a half flush periods (1000 cycles each) logged, then the kill.
    wait_until(&dir, Duration::from_secs(30), "2,500 cycles", |s| s["cycle"].as_u64() >= Some(2500));
    let ran = status(&dir)["cycle"].as_u64().unwrap();
    d.0.kill().unwrap(); // SIGKILL: no chance to finish the file
    d.0.wait().unwrap();
    // Longer than the drive's 100 ms watchdog: it switches off and latches HOST_TIMEOUT.
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(logs(&dir, "daemon-").iter().filter(|p| p.to_string_lossy().ends_with(".part")).count(), 1);
    std::fs::remove_file(dir.join("s.sock")).unwrap();
    let _d = daemon(&dir, &pty, &lockstep(""));
    wait_until(&dir, Duration::from_secs(5), "telemetry", |s| s["telemetry"] == true);
    let err = stderr(&dir);
    assert!(err.contains("unfinished log from a crash"), "{err}");
    let recovered: Vec<PathBuf> =
        logs(&dir, "daemon-").into_iter().filter(|p| p.to_string_lossy().contains("recovered")).collect();
    assert_eq!(recovered.len(), 1);
    let log = read_log(&recovered[0]).unwrap();
    assert!(!log.truncated, "rewritten complete, with a footer");
    // At most what was written since the last flush is lost: one flush period (1000 cycles, a
    // second at 1 kHz), with a chunk's worth of slack.
    assert!(log.len() as u64 + 1100 >= ran, "at least its flushed cycles read back: {} of {ran}", log.len());
    // The MCAP library's seeking read (summary section, chunk indexes) opens it.
    let bytes = std::fs::read(&recovered[0]).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary section");
    let stats = summary.stats.expect("statistics");
    assert!(stats.message_count >= log.len() as u64, "{stats:?}");
    assert!(!summary.chunk_indexes.is_empty());
    let cut = recovered[0].to_string_lossy().replace(".recovered.mcap", ".mcap.part");
    assert!(!Path::new(&cut).exists(), "the cut original {cut} is gone");
    // The drive's own watchdog disabled it while no host was talking; the daemon starts with no
    // torque, and the drive's fault must be reset before enabling.
    let s = status(&dir);
    assert_eq!(s["mode"], "faulted", "{s}");
    assert_eq!(s["faults"], serde_json::json!(["motor"]));
    assert_eq!(s["drive"]["faults"], serde_json::json!(["host timeout"]));
    assert!(ctl(&dir, &["enable"]).is_err(), "no enabling over the drive's fault");
    ctl(&dir, &["reset"]).unwrap();
    wait_until(&dir, Duration::from_secs(2), "disabled", |s| s["mode"] == "disabled");
    wait_until(&dir, Duration::from_secs(1), "the drive's fault cleared", |s| {
        s["drive"]["faults"] == serde_json::json!([])
    });
    ctl(&dir, &["enable"]).unwrap();
    assert_eq!(status(&dir)["mode"], "enabled");
}

#[test]
fn systemd_hears_ready_after_telemetry_and_watchdog_while_running_and_sigterm_finishes_the_log() {
    let _serial = serial();
    use std::os::unix::net::UnixDatagram;
    let dir = Scratch::new("e2e", "systemd");
    let notify = UnixDatagram::bind(dir.join("notify.sock")).unwrap();
    notify.set_read_timeout(Some(Duration::from_millis(500))).unwrap();
    // A pty nobody answers yet: no telemetry, so no READY.
    let (master, slave, pty) = arash_mock::pseudo_terminal().unwrap();
    let err = std::fs::File::create(dir.join("daemon.err")).unwrap();
    let mut d = Proc(
        daemon_command(&dir, &pty, "[link]\nstartup_timeout_ms = 10000\n")
            .env("NOTIFY_SOCKET", dir.join("notify.sock"))
            .env("WATCHDOG_USEC", "200000")
            .stderr(err)
            .spawn()
            .unwrap(),
    );
    let mut buf = [0u8; 256];
    let mut received = Vec::new();
    let started = Instant::now();
    while started.elapsed() < Duration::from_millis(800) {
        if let Ok(n) = notify.recv(&mut buf) {
            received.push(String::from_utf8_lossy(&buf[..n]).into_owned());
        }
    }
    assert!(!received.iter().any(|m| m.contains("READY=1")), "READY before telemetry: {received:?}");
    // Now the drive answers.
    let model = arash_core::arash_asist();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop_mock = stop.clone();
    let mock = std::thread::spawn(move || {
        let mut motor = arash_mock::MockMotor::new(
            &model,
            &arash_core::sim::Scenario::default(),
            Default::default(),
            Default::default(),
        )
        .unwrap();
        motor.serve(master, &stop_mock).unwrap();
        drop(slave);
    });
    let started = Instant::now();
    let mut ready_at = None;
    let mut watchdogs = 0;
    while started.elapsed() < Duration::from_secs(3) {
        if let Ok(n) = notify.recv(&mut buf) {
            let m = String::from_utf8_lossy(&buf[..n]).into_owned();
            if m.contains("READY=1") {
                ready_at.get_or_insert(started.elapsed());
            }
            if m.contains("WATCHDOG=1") && ready_at.is_some() {
                watchdogs += 1;
            }
        }
    }
    assert!(ready_at.is_some(), "no READY=1 after telemetry; {}", stderr(&dir));
    assert!(watchdogs >= 5, "WATCHDOG=1 about every 100 ms while the loop runs: {watchdogs}");
    assert!(terminate(&mut d).success(), "{}", stderr(&dir));
    let mut stopping = false;
    while let Ok(n) = notify.recv(&mut buf) {
        stopping |= String::from_utf8_lossy(&buf[..n]).contains("STOPPING=1");
    }
    assert!(stopping);
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    mock.join().unwrap();
    let files = logs(&dir, "daemon-");
    assert!(!files.is_empty() && files.iter().all(|p| p.extension().unwrap() == "mcap"), "{files:?}");
    for f in files {
        assert!(!read_log(&f).unwrap().truncated, "SIGTERM finishes {}", f.display());
    }
}

#[test]
fn no_telemetry_within_the_startup_timeout_is_an_error_that_names_it() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "startup");
    let (_master, _slave, pty) = arash_mock::pseudo_terminal().unwrap();
    let out = daemon_command(&dir, &pty, "[link]\nstartup_timeout_ms = 300\n").output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("startup_timeout_ms"), "{err}");
}

#[test]
fn idle_logs_rotate_by_size() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "rotate");
    let (_mock, pty) = mock(&dir, None);
    let mut d = daemon(&dir, &pty, "[log]\nrotate_mib = 0.02\n\n[socket]\nmode = \"0600\"\n");
    let mode = std::os::unix::fs::PermissionsExt::mode(&std::fs::metadata(dir.join("s.sock")).unwrap().permissions());
    assert_eq!(mode & 0o777, 0o600, "the socket's mode is the access control");
    std::thread::sleep(Duration::from_millis(3500));
    assert!(terminate(&mut d).success());
    let files = logs(&dir, "daemon-");
    assert!(files.len() >= 2, "{files:?}");
    let total: usize = files.iter().map(|f| read_log(f).unwrap().len()).sum();
    let cycles: Vec<u64> = files.iter().flat_map(|f| read_log(f).unwrap().cycles.cycle).collect();
    assert_eq!(total, cycles.len());
    let mut sorted = cycles.clone();
    sorted.sort();
    assert!(sorted.windows(2).all(|w| w[1] == w[0] + 1), "rotation loses no cycle");
}

#[test]
fn a_logging_failure_is_reported_and_the_control_loop_goes_on() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "logfail");
    let (_mock, pty) = mock(&dir, None);
    let mut d = daemon(&dir, &pty, "[log]\nrotate_s = 1.0\n");
    wait_until(&dir, Duration::from_secs(5), "telemetry", |s| s["telemetry"] == true);
    // Pull the log directory away: the next rotation (every second) can neither finish nor
    // open a file.
    std::fs::rename(dir.join("logs"), dir.join("moved")).unwrap();
    dir.file("logs", "not a directory");
    wait_until(&dir, Duration::from_secs(10), "the logging failure", |s| s["logging"] == false);
    let before = status(&dir)["cycle"].as_u64().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert!(status(&dir)["cycle"].as_u64().unwrap() > before + 100, "the control loop stopped");
    assert!(stderr(&dir).contains("logging stopped"), "{}", stderr(&dir));
    // The daemon still stops cleanly, and says the logger failed.
    assert!(!terminate(&mut d).success());
}

/// Play 7 s of the paper's ω = 0.9 trajectory under PD with `model`'s gravity, on a daemon
/// configured with `torque_constant`; returns its status and the run's log.
fn run_with(dir: &Scratch, pty: &str, torque_constant: &[f64], model: &Path) -> (serde_json::Value, PathBuf) {
    let config = format!(
        "[control]\ncontroller = \"pd\"\nmodel = {:?}\n[drive]\ntorque_constant = {torque_constant:?}\n",
        model.to_str().unwrap()
    );
    let mut d = daemon(dir, pty, &lockstep(&config));
    wait_until(dir, Duration::from_secs(5), "telemetry", |s| s["telemetry"] == true);
    ctl(dir, &["enable"]).unwrap();
    let trajectory = concat!(env!("CARGO_MANIFEST_DIR"), "/../../trajectories/paper_validation_0.9.json");
    let log = ctl(dir, &["run", trajectory, "--duration", "7", "--wait"]).unwrap_or_else(|e| panic!("{e}"));
    let s = status(dir);
    assert!(terminate(&mut d).success(), "{}", stderr(dir));
    std::fs::remove_file(dir.join("s.sock")).ok();
    (s, PathBuf::from(log.trim()))
}

#[test]
fn the_daemon_commands_currents_through_a_models_identified_drive_gains() {
    let _serial = serial();
    let dir = Scratch::new("e2e", "gains");
    // A model file, and the same with drive gains as `arash identify --loaded --load` records
    // them: the mock drive's true torque constants, and ones 10 % and 3× off.
    let robot = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/arash_asist.urdf");
    let (log, plain) = (dir.join("run.mcap"), dir.join("plain.json"));
    let trajectory = concat!(env!("CARGO_MANIFEST_DIR"), "/../../trajectories/paper_validation_0.9.json");
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenarios/nominal.toml");
    let args = ["simulate", "--scenario", scenario, "--trajectory", trajectory, "--controller", "idc-cad"];
    let args = [&args[..], &["--duration", "7", "-o"]].concat();
    let out = Command::new(ARASH).args(args).arg(&log).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out =
        Command::new(ARASH).arg("identify").arg(&log).args(["--robot", robot, "-o"]).arg(&plain).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let truth = arash_daemon::drive_config::DriveConfig::default().torque_constant;
    let with_gains = |name: &str, scale: f64| {
        let mut m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&plain).unwrap()).unwrap();
        m["drive_gains"] = serde_json::json!({
            "gains": truth.iter().map(|k| k * scale).collect::<Vec<_>>(), "sigma": [1e-3, 1e-3, 1e-3],
            "load_body": "insertion_carriage", "load_mass": 0.3, "load_estimate": [], "condition_number": 10.0,
            "load_share": [0.1, 0.1, 0.1], "load_over_unexplained": [50.0, 50.0, 50.0], "fixed": [true, true, true],
        });
        dir.file(name, &m.to_string())
    };
    let (right, off, far) = (with_gains("right.json", 1.0), with_gains("off.json", 1.1), with_gains("far.json", 3.0));
    // A datasheet 20 % low, as the configuration's torque constants.
    let datasheet: Vec<f64> = truth.iter().map(|k| 0.8 * k).collect();
    let (_mock, pty) = mock(&dir, None);

    let (s, by_datasheet) = run_with(&dir, &pty, &datasheet, &plain);
    assert_eq!(s["torque_constant"], serde_json::json!(datasheet), "{s}");
    assert_eq!(s["torque_constant_source"][1], "drive.torque_constant", "{s}");
    let (s, by_model) = run_with(&dir, &pty, &datasheet, &right);
    assert_eq!(s["torque_constant"], serde_json::json!(truth), "{s}");
    assert!(s["torque_constant_source"][1].as_str().unwrap().contains("identified with a 0.3 kg load"), "{s}");
    // The log reads the drive's current times the constant. Through the model's true gains that
    // is the torque on the joints; through a datasheet 20 % low, 80 % of it, and every parameter
    // identified from such a log comes out 80 % of what the other's gives. The second log is
    // fitted with the cut-offs and Coulomb laws the data chose on the first: the two runs are
    // not the same samples, and choices made apart (13.6 Hz on one, 32 Hz on the other, seen in
    // CI) move a parameter such as the cable's stiffness by more than the gains' 20 %.
    let fitted = |log: &Path, name: &str, choices: &[String]| -> serde_json::Value {
        let out = dir.join(name);
        let mut command = Command::new(ARASH);
        command.arg("identify").arg(log).args(["--robot", robot]).args(choices).arg("-o").arg(&out);
        let done = command.output();
        assert!(done.as_ref().unwrap().status.success(), "{}", String::from_utf8_lossy(&done.unwrap().stderr));
        serde_json::from_str(&std::fs::read_to_string(out).unwrap()).unwrap()
    };
    let a = fitted(&by_datasheet, "a.json", &[]);
    let laws: Vec<String> = serde_json::from_value::<Vec<Option<f64>>>(a["settings"]["friction_velocities"].clone())
        .unwrap()
        .iter()
        .map(|v| v.map_or("sign".to_string(), |v| v.to_string()))
        .collect();
    let setting = |key: &str| a["settings"][key].as_f64().unwrap().to_string();
    let choices = [
        "--cutoff".to_string(),
        setting("cutoff_hz"),
        "--friction-cutoff".to_string(),
        setting("friction_cutoff_hz"),
        "--friction-velocity".to_string(),
        laws.join(","),
    ];
    let b = fitted(&by_model, "b.json", &choices);
    let values = |m: &serde_json::Value, key: &str| serde_json::from_value::<Vec<f64>>(m[key].clone()).unwrap();
    let (beta_a, beta_b) = (values(&a, "beta"), values(&b, "beta"));
    let (sigma_a, sigma_b) = (values(&a, "sigma_percent"), values(&b, "sigma_percent"));
    // The gains scale every parameter alike. The scale that maps the second fit's β onto the
    // first's, each parameter weighted by both fits' precision, is the datasheet's 0.8. All the
    // parameters take part: which of them the data determine well depends on the cut-off they
    // choose (at 4.8 Hz, on one CI run, only three were below 3 %).
    let (mut moment, mut weight) = (0.0, 0.0);
    for i in 0..beta_a.len() {
        let (ea, eb) = (sigma_a[i] / 100.0 * beta_a[i].abs(), sigma_b[i] / 100.0 * beta_b[i].abs());
        let w = 1.0 / (ea * ea + 0.64 * eb * eb);
        if w.is_finite() {
            moment += w * beta_a[i] * beta_b[i];
            weight += w * beta_b[i] * beta_b[i];
        }
    }
    let (scale, scale_sigma) = (moment / weight, weight.sqrt().recip());
    eprintln!("β by the datasheet over β by the model's gains: {scale:.4} ± {scale_sigma:.4}");
    assert!(scale_sigma < 0.01, "the two logs determine the scale only to ±{scale_sigma}: {sigma_a:?}");
    assert!((scale - 0.8).abs() < 0.04, "scale {scale} ± {scale_sigma}");
    // Each well-determined parameter on its own, within 3 standard deviations of its ratio.
    for i in (0..beta_a.len()).filter(|&i| sigma_a[i] < 3.0) {
        let ratio = beta_a[i] / beta_b[i];
        let sigma = 0.8 * (sigma_a[i].powi(2) + sigma_b[i].powi(2)).sqrt() / 100.0;
        eprintln!("β{}: {:.4e} by the datasheet, {:.4e} by the model's gains", i + 1, beta_a[i], beta_b[i]);
        assert!((ratio - 0.8).abs() < (3.0 * sigma).max(0.04), "β{}: ratio {ratio} ± {sigma}", i + 1);
    }
    let flight = read_log(&by_model).unwrap();
    assert_eq!(serde_json::from_str::<Vec<f64>>(&flight.metadata["torque_constant"]).unwrap(), truth);

    // At run time a model whose gains differ is refused; one without gains is taken.
    let mut d = daemon(&dir, &pty, &format!("[control]\ncontroller = \"pd\"\nmodel = {:?}\n", right.to_str().unwrap()));
    let err = ctl(&dir, &["controller", "pd", "--model", off.to_str().unwrap()]).unwrap_err();
    assert!(err.contains("fixed at start-up") && err.contains("restart the daemon"), "{err}");
    ctl(&dir, &["controller", "pd", "--model", plain.to_str().unwrap()]).unwrap();
    assert!(terminate(&mut d).success());
    std::fs::remove_file(dir.join("s.sock")).ok();
    // A gain 3× the configured one is a wrong scale, not a calibration: the daemon does not start.
    let config = format!("[control]\ncontroller = \"pd\"\nmodel = {:?}\n", far.to_str().unwrap());
    let out = daemon_command(&dir, &pty, &config).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("more than 2×") && err.contains("yaw"), "{err}");
}
