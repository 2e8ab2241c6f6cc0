//! The `arash` binary end to end: real process, real files, real exit codes.

mod common;

use common::Scratch;
use std::path::Path;
use std::process::Command;

fn arash(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_arash")).args(args).output().expect("the arash binary runs")
}

fn repo_file(path: &str) -> String {
    format!("{}/../../{path}", env!("CARGO_MANIFEST_DIR"))
}

/// `arash simulate --scenario S --trajectory T --controller C -o OUT`, then `extra` arguments.
fn simulate(
    scenario: &str,
    trajectory: &str,
    controller: &str,
    output: &std::path::Path,
    extra: &[&str],
) -> std::process::Output {
    let mut args = vec!["simulate", "--scenario", scenario, "--trajectory", trajectory, "--controller", controller];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["-o", output.to_str().unwrap()]);
    arash(&args)
}

/// The two-joint planar fixture.
fn planar_urdf() -> String {
    repo_file("tests/fixtures/planar_2link.urdf")
}

#[test]
fn model_describes_the_bundled_robot() {
    let out = arash(&["model", &repo_file("robots/arash_asist.urdf")]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("3 dof, 8 moving bodies"), "{text}");
    assert!(text.contains("standard parameters: 89"), "{text}");
    assert!(text.contains("base parameters: p = 23"), "{text}");
    assert!(text.contains("β23 = insertion.ke"), "{text}");
    assert!(text.contains("weak base parameters: 1, which no trajectory"), "{text}");
    assert!(text.contains("instrument_holder.my_R (residual"), "{text}");
    assert!(text.contains("[ -14.00,   27.00] mm"), "limits are shown in mm at the edge: {text}");
}

#[test]
fn model_reports_a_bad_file_by_name_and_fails() {
    let out = arash(&["model", "/no/such/robot.urdf"]);
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("/no/such/robot.urdf"), "{err}");
}

#[test]
fn model_reports_a_malformed_urdf_with_the_offending_element() {
    let dir = Scratch::new("cli", "malformed-urdf");
    let path = dir.file(
        "bad.urdf",
        r#"<robot name="bad"><link name="a"/><link name="b"><inertial><mass value="-2"/><inertia ixx="1" iyy="1" izz="1"/></inertial></link>
           <joint name="j" type="revolute"><parent link="a"/><child link="b"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>"#,
    );
    let out = arash(&["model", path.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("link `b`") && err.contains("mass -2 kg is not positive"), "{err}");
}

#[test]
fn model_loads_a_point_mass_link_and_warns_with_its_name() {
    let dir = Scratch::new("cli", "point-mass-urdf");
    let path = dir.file(
        "point.urdf",
        r#"<robot name="p"><link name="a"/><link name="b"><inertial><mass value="0.2"/><inertia ixx="0" iyy="0" izz="0"/></inertial></link>
           <joint name="j" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.1 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>"#,
    );
    let out = arash(&["model", path.to_str().unwrap()]);
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(out.status.success(), "{err}");
    assert!(err.contains("warning:") && err.contains("link `b`") && err.contains("semidefinite"), "{err}");
}

#[test]
fn identify_names_a_missing_column_and_a_bad_cell() {
    let robot = repo_file("robots/arash_asist.urdf");
    let dir = Scratch::new("cli", "identify-bad-cells");
    let never = dir.join("never.json");
    let missing = dir.file("missing.csv", "t,q.yaw,q.pitch,tau.yaw,tau.pitch,tau.insertion\n0,0,0,0,0,0\n");
    let out = arash(&["identify", missing.to_str().unwrap(), "--robot", &robot, "-o", never.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("has no column `q.insertion`"), "{err}");

    let bad = dir.file(
        "bad.csv",
        "t,q.yaw,q.pitch,q.insertion,tau.yaw,tau.pitch,tau.insertion\n0,0,0,0,0,0,0\n0.001,0,abc,0,0,0,0\n",
    );
    let out = arash(&["identify", bad.to_str().unwrap(), "--robot", &robot, "-o", never.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("row 3 column `q.pitch` is `abc`"), "{err}");
}

#[test]
fn identify_refuses_a_log_that_does_not_move() {
    let robot = repo_file("robots/arash_asist.urdf");
    let mut text = String::from("t,q.yaw,q.pitch,q.insertion,tau.yaw,tau.pitch,tau.insertion\n");
    for i in 0..2000 {
        text += &format!("{},0.1,0.2,0.003,0.01,0.02,0.3\n", i as f64 * 1e-3);
    }
    let dir = Scratch::new("cli", "identify-still");
    let never = dir.join("never.json");
    let still = dir.file("still.csv", &text);
    let out = arash(&["identify", still.to_str().unwrap(), "--robot", &robot, "-o", never.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("joint 1 never moves"), "{err}");
}

#[test]
fn excite_refuses_bad_options_by_name() {
    let dir = Scratch::new("cli", "excite-bad-options");
    let never = dir.join("never.json");
    let out = arash(&[
        "excite",
        "--robot",
        &repo_file("robots/arash_asist.urdf"),
        "--harmonics",
        "1",
        "-o",
        never.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("harmonics = 1") && err.contains("2 or more"), "{err}");
    let out = arash(&[
        "excite",
        "--robot",
        &repo_file("robots/arash_asist.urdf"),
        "--acceleration-limits",
        "1,2",
        "-o",
        never.to_str().unwrap(),
    ]);
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(!out.status.success() && err.contains("acceleration_limits has 2 entries"), "{err}");
    assert!(!never.exists(), "a refused design writes no file");
}

/// Settings go through their own `validate` (identify/options.rs) before any log is read: the log
/// named here does not exist, and the error is about the setting.
#[test]
fn identify_refuses_bad_settings_by_name_before_reading_logs() {
    let dir = Scratch::new("cli", "identify-bad-settings");
    let missing = dir.join("missing.csv");
    let model = dir.join("never.json");
    for (flag, name) in [("--pull=-1", "pull = -1"), ("--order=13", "order = 13"), ("--cutoff=0", "cutoff_hz = 0")] {
        let out = arash(&["identify", missing.to_str().unwrap(), "-o", model.to_str().unwrap(), flag]);
        let err = String::from_utf8(out.stderr).unwrap();
        assert!(!out.status.success() && err.contains(name) && !err.contains("missing.csv"), "{flag}: {err}");
    }
    assert!(!model.exists());
}

#[test]
fn simulate_writes_a_flight_log_that_identify_reads() {
    let robot = repo_file("robots/arash_asist.urdf");
    let dir = Scratch::new("cli", "simulate");
    let log = dir.join("run.mcap");
    let out = arash(&[
        "simulate",
        "--scenario",
        &repo_file("scenarios/nominal.toml"),
        "--trajectory",
        &repo_file("trajectories/paper_validation_0.9.json"),
        "--controller",
        "idc-cad",
        "--robot",
        &robot,
        "--duration",
        "7",
        "-o",
        log.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("simulated 7.0 s of rig time") && err.contains("real time"), "{err}");
    let flight = arash_core::flightlog::read_log(&log).unwrap();
    assert_eq!(flight.len(), 7000);
    assert_eq!(flight.metadata["controller"], "idc");
    assert_eq!(flight.metadata["params"], "cad");
    assert!(flight.truth.is_none(), "the truth is logged only with --truth");
    let model = dir.join("model.json");
    let out = arash(&["identify", log.to_str().unwrap(), "--robot", &robot, "-o", model.to_str().unwrap()]);
    let (text, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{err}");
    assert!(err.contains("from 7000 samples") && text.contains("Identified base parameters"), "{err}{text}");
    assert!(model.exists());
    // By default the weak base parameter is regrouped, and the table says so; --keep-weak fits it.
    assert!(
        text.contains("instrument_holder.my_R regrouped") && text.contains("β22") && !text.contains("β23"),
        "{text}"
    );
    let kept = dir.join("model-kept.json");
    let out =
        arash(&["identify", log.to_str().unwrap(), "--robot", &robot, "--keep-weak", "-o", kept.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("β23") && !text.contains("regrouped"), "{text}");
}

/// A closed-loop run through `identify --method didim`: the flight log names its reference and
/// controller; the same run as CSV needs the reference columns and `--controller`, and each
/// missing piece is named with the methods that still work.
#[test]
fn identify_fits_a_closed_loop_log_and_names_what_a_log_lacks_for_it() {
    let dir = Scratch::new("cli", "closed-loop");
    let log = dir.join("run.mcap");
    let excitation = repo_file("trajectories/excitation_L5_T15.json");
    let out = simulate(&repo_file("scenarios/nominal.toml"), &excitation, "pd", &log, &["--duration", "30"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let model = dir.join("didim.json");
    let (log_path, model_path) = (log.to_str().unwrap(), model.to_str().unwrap());
    let out = arash(&["identify", log_path, "--method", "didim", "--coulomb-epsilon", "0.001", "-o", model_path]);
    let (text, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{err}");
    assert!(text.contains("DIDIM: the closed loop simulated with the estimate"), "{text}");

    // The same cycles as CSV, with and without the reference columns.
    let flight = arash_core::flightlog::read_log(&log).unwrap();
    let joints = ["yaw", "pitch", "insertion"];
    let header = |reference: bool| {
        let mut names = vec!["t".to_string()];
        let channels: &[&str] = if reference { &["q", "tau", "q_des", "qd_des", "qdd_des"] } else { &["q", "tau"] };
        for channel in channels {
            names.extend(joints.iter().map(|j| format!("{channel}.{j}")));
        }
        names.join(",") + "\n"
    };
    let c = &flight.cycles;
    let rows = |reference: bool| -> String {
        (0..c.t.len())
            .map(|i| {
                let mut row = vec![c.t[i]];
                let channels: Vec<&Vec<f64>> = match reference {
                    true => vec![&c.q, &c.tau_meas, &c.q_des, &c.qd_des, &c.qdd_des],
                    false => vec![&c.q, &c.tau_meas],
                };
                for x in channels {
                    row.extend_from_slice(&x[3 * i..3 * i + 3]);
                }
                row.iter().map(|v| format!("{v:e}")).collect::<Vec<_>>().join(",") + "\n"
            })
            .collect()
    };
    let plain = dir.file("plain.csv", &(header(false) + &rows(false)));
    let with_reference = dir.file("reference.csv", &(header(true) + &rows(true)));
    let never = dir.join("from-csv.json");
    let identify = |csv: &std::path::Path, extra: &[&str]| {
        let mut args = vec!["identify", csv.to_str().unwrap(), "--method", "didim", "--coulomb-epsilon", "0.001"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", never.to_str().unwrap()]);
        arash(&args)
    };
    let out = identify(&plain, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("no q_des, qd_des and qdd_des")
            && err.contains("ols, wls and consistent"),
        "{err}"
    );
    let out = identify(&with_reference, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("names no controller; give it with --controller"), "{err}");
    let controller = dir.file("controller.json", &flight.logged_controller().unwrap().unwrap().to_json());
    let out = identify(&with_reference, &["--controller", controller.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let written: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&never).unwrap()).unwrap();
    assert_eq!(written["settings"]["method"], "didim");
}

#[test]
fn simulate_refuses_bad_inputs_by_name() {
    let traj = repo_file("trajectories/paper_validation_0.5.json");
    let dir = Scratch::new("cli", "simulate-bad-inputs");
    let never = dir.join("never.mcap");
    let scenario = dir.file("bad.toml", "[effects.cogging]\namplitude = [0.1, 0.1]\n");
    let out = simulate(scenario.to_str().unwrap(), &traj, "pd", &never, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("effects.cogging.amplitude") && err.contains("2 entries"), "{err}");
    let scenario = repo_file("scenarios/nominal.toml");
    let out = simulate(&scenario, &traj, "idc", &never, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--params"), "{err}");
    let bad = dir.file("traj.json", r#"{"kind": "paper-validation", "omega": 0}"#);
    let out = simulate(&scenario, bad.to_str().unwrap(), "pd", &never, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("omega") && err.contains("traj.json"), "{err}");
}

/// `arash diagnose` on a simulated log with a wiring disturbance: it names the effect, writes the
/// report, the JSON, the updated model and the figures, every figure a PNG with content; and a
/// bad option is refused by name.
#[test]
fn diagnose_names_the_effect_and_writes_report_model_and_figures() {
    let dir = Scratch::new("cli", "diagnose");
    let log = dir.join("run.mcap");
    let out = arash(&[
        "simulate",
        "--scenario",
        &repo_file("scenarios/configuration_disturbance.toml"),
        "--trajectory",
        &repo_file("trajectories/excitation_L5_T15.json"),
        "--controller",
        "idc-cad",
        "--duration",
        "45",
        "-o",
        log.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report_dir = dir.join("diagnosis");
    let never = dir.join("never");
    // The simulated rig's friction law, declared as a lab declares its robot's.
    let out =
        arash(&["diagnose", log.to_str().unwrap(), "--coulomb-epsilon", "0.001", "-o", report_dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("1. configuration_disturbance"), "{text}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report_dir.join("diagnosis.json")).unwrap()).unwrap();
    assert_eq!(json["accepted"][0]["name"], "configuration_disturbance");
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report_dir.join("model.json")).unwrap()).unwrap();
    assert_eq!(model["format"], "arash-model/1");
    assert_eq!(model["effects"][0]["kind"], "configuration_disturbance");
    let report = std::fs::read_to_string(report_dir.join("report.txt")).unwrap();
    assert!(text.starts_with(report.trim()), "report.txt is what was printed");
    assert_eq!(model["held_out"]["rms"].as_array().map(Vec::len), Some(3), "{}", model["held_out"]);
    force_reads_the_run_with_the_diagnosed_model(&log, &report_dir.join("model.json"), &dir.join("force"));
    let pngs: Vec<_> = std::fs::read_dir(&report_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    assert!(pngs.len() >= 2, "{pngs:?}");
    for png in &pngs {
        let bytes = std::fs::read(png).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", png.display());
        assert!(bytes.len() > 10_000, "{} looks blank", png.display());
    }
    // From the identification: the same effect named against `arash identify`'s model of the log,
    // and the consistent refit made in that model's base parameters.
    let from_identified = dir.join("from_identified");
    let out = arash(&[
        "diagnose",
        log.to_str().unwrap(),
        "--coulomb-epsilon",
        "0.001",
        "--from-identified",
        "--consistent",
        "-o",
        from_identified.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("1. configuration_disturbance"), "{text}");
    assert!(text.contains("before: the model identified on this log, as it is"), "{text}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(from_identified.join("diagnosis.json")).unwrap()).unwrap();
    assert_eq!(json["settings"]["started_from"], "identified");
    assert!(from_identified.join("model_consistent.json").exists());
    let out = arash(&["diagnose", log.to_str().unwrap(), "--effects", "gremlins", "-o", never.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("gremlins"), "{err}");
    let out = arash(&["diagnose", log.to_str().unwrap(), "--hold-friction", "-o", never.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--model"), "{err}");
}

/// `arash force` over the hand-free run the model was diagnosed on: thresholds from the model's
/// held-out σ, the force at the instrument tip by default, no collision, and its files written.
fn force_reads_the_run_with_the_diagnosed_model(log: &Path, model: &Path, out_dir: &Path) {
    let (log, model, out_dir) = (log.to_str().unwrap(), model.to_str().unwrap(), out_dir.to_str().unwrap());
    let out = arash(&["force", log, "--model", model, "-o", out_dir]);
    let (text, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{err}");
    assert!(text.contains("the force at `instrument_tip`, its moment about `remote_centre`"), "{text}");
    assert!(
        text.contains("σ is the model's held-out residual RMS") && text.contains(", 0 reaching collision"),
        "{text}"
    );
    let csv = std::fs::read_to_string(Path::new(out_dir).join("force.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.starts_with("t,tau_ext.") && header.contains(",force.z,") && header.ends_with(",singular"),
        "{header}"
    );
    assert_eq!(csv.lines().count(), 45_001);
    let png = std::fs::read(Path::new(out_dir).join("force.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 10_000);
    let out = arash(&["force", log, "--model", model, "--frame", "tool", "-o", out_dir]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no frame `tool`"), "{err}");
}

/// A scenario for the two-joint planar fixture.
const PLANAR_SCENARIO: &str = "name = \"planar\"\n[truth]\nviscous = [0.01, 0.01]\ncoulomb = [0.01, 0.01]\n\
    stiffness = [0.0, 0.0]\n[sensors]\ncounts_per_rev = [8192.0, 8192.0]\ntransmission = [0.01, 0.01]\n\
    torque_noise = [0.01, 0.01]\n";

#[test]
fn simulate_on_a_robot_of_another_dof_refuses_the_papers_gains_and_runs_pd() {
    let dir = Scratch::new("cli", "simulate-planar");
    let scenario = dir.file("planar.toml", PLANAR_SCENARIO);
    let hold = dir.file("hold.json", r#"{"kind": "hold", "q": [0.2, -0.3]}"#);
    let log = dir.join("planar.mcap");
    let urdf = planar_urdf();
    let extra = ["--robot", &urdf, "--params", "cad", "--duration", "1"];
    let run = |controller: &str| simulate(scenario.to_str().unwrap(), hold.to_str().unwrap(), controller, &log, &extra);
    for controller in ["robust", "idc"] {
        let out = run(controller);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{controller}: {err}");
        assert!(err.contains("planar_2link") && err.contains("2 joints") && err.contains("PD"), "{err}");
        assert!(!err.contains("panicked") && !log.exists(), "{err}");
    }
    let out = run("pd");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(log.exists());
}

#[test]
fn simulate_refuses_a_trajectory_beyond_the_limits_naming_sample_joint_and_limit() {
    let dir = Scratch::new("cli", "simulate-limits");
    let never = dir.join("never.mcap");
    let yaw = dir.file("yaw.json", r#"{"kind": "hold", "q": [1.5, 0.2, 0.005]}"#);
    let out = simulate(&repo_file("scenarios/nominal.toml"), yaw.to_str().unwrap(), "pd", &never, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("sample 0") && err.contains("joint 0 `yaw`"), "{err}");
    assert!(!never.exists(), "a refused run writes no log");
}

#[test]
fn bad_logs_are_refused_by_name_with_no_backtrace_and_no_file_left() {
    let dir = Scratch::new("cli", "bad-logs");
    let never = dir.join("never.json");
    let refused = |args: &[&str], expect: &[&str]| {
        let out = arash(args);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        for e in expect {
            assert!(err.contains(e), "{args:?}: expected `{e}` in {err}");
        }
        assert!(!err.contains("panicked") && !err.contains("stack backtrace"), "{err}");
        assert!(!never.exists(), "a refused command left {}", never.display());
    };
    // NaN in a cell names the row and the column.
    let nan = dir.file(
        "nan.csv",
        "t,q.yaw,q.pitch,q.insertion,tau.yaw,tau.pitch,tau.insertion\n0,0,0,0,0,0,0\n0.001,0,0,0,NaN,0,0\n",
    );
    refused(&["identify", nan.to_str().unwrap(), "-o", never.to_str().unwrap()], &["row 3", "tau.yaw", "NaN"]);
    // A log of another robot (two joints) for ARASH:ASiST names both sets of joints.
    let planar = dir.join("planar.mcap");
    let scenario = dir.file("planar.toml", PLANAR_SCENARIO);
    let hold = dir.file("hold.json", r#"{"kind": "hold", "q": [0.2, -0.3]}"#);
    let urdf = planar_urdf();
    let extra = ["--robot", &urdf, "--duration", "1"];
    let out = simulate(scenario.to_str().unwrap(), hold.to_str().unwrap(), "pd", &planar, &extra);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    refused(&["identify", planar.to_str().unwrap(), "-o", never.to_str().unwrap()], &["shoulder", "yaw"]);
    // Bytes that are not a log at all, and an empty file.
    let junk = dir.file("junk.mcap", "this is not an MCAP file");
    refused(
        &["identify", junk.to_str().unwrap(), "-o", never.to_str().unwrap()],
        &["junk.mcap", "not an arash flight log"],
    );
    let empty = dir.file("empty.csv", "");
    refused(&["identify", empty.to_str().unwrap(), "-o", never.to_str().unwrap()], &["empty.csv"]);
    // A log cut off by a crash is read up to the cut, and says so.
    let whole = dir.join("whole.mcap");
    let (nominal, fast) = (repo_file("scenarios/nominal.toml"), repo_file("trajectories/paper_validation_0.9.json"));
    let out = simulate(&nominal, &fast, "idc-cad", &whole, &["--duration", "7"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bytes = std::fs::read(&whole).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let model = dir.join("model.json");
    let out = arash(&["identify", cut.to_str().unwrap(), "-o", model.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("was cut off"), "{err}");
}

/// The binary links no system BLAS or LAPACK (issue 20): `ldd` names only the C runtime, so it
/// runs on a machine without Debian's libblas/liblapack.
#[test]
#[cfg(target_os = "linux")]
fn the_binary_needs_only_the_c_runtime() {
    let out = Command::new("ldd").arg(env!("CARGO_BIN_EXE_arash")).output().expect("ldd runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let runtime =
        ["linux-vdso", "libc.so", "libm.so", "libgcc_s.so", "ld-linux", "libpthread.so", "libdl.so", "librt.so"];
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        assert!(runtime.iter().any(|r| line.contains(r)), "the arash binary needs {line}:\n{text}");
    }
}

/// `arash ctl --wait` waits for a run, so with any other request it is refused before the
/// daemon is asked anything (the socket here does not exist: a refusal that named it would have
/// tried to connect).
#[test]
fn ctl_wait_without_a_run_is_refused_before_the_daemon_is_asked() {
    let out = arash(&["ctl", "--socket", "/nonexistent/arash.sock", "enable", "--wait"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("--wait") && err.contains("arash ctl run"), "{err}");
    assert!(!err.contains("connecting"), "{err}");
}
