//! `arash demo` end to end in its short mode: the mock motor with the demo scenario (a wiring
//! disturbance on pitch and Stribeck friction, neither declared), the daemon, calibration,
//! diagnosis, tracking four ways and the report, with the daemon in lockstep with the simulated
//! rig (the same runs, as fast as the host goes, and the same on a busy host). Then Ctrl-C in
//! the middle of a run of the demo at its real-time pace.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use arash_core::flightlog::read_log;

mod common;

use common::Scratch;

const ARASH: &str = env!("CARGO_BIN_EXE_arash");

/// The two tests each run a 1 kHz mock and daemon; on two cores they must not overlap.
fn serial() -> std::sync::MutexGuard<'static, ()> {
    static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());
    SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn pngs(dir: &Path, found: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            pngs(&path, found);
        } else if path.extension().is_some_and(|e| e == "png") {
            found.push(path);
        }
    }
}

/// Decode a PNG and check that it has ink: at least 1 % of its pixels are not the background,
/// in more than two colours (axes alone are black on white).
fn assert_figure(path: &Path) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap_or_else(|e| panic!("{} is not a PNG: {e}", path.display()));
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let channels = info.color_type.samples();
    assert!(channels >= 3, "{}: colour type {:?}", path.display(), info.color_type);
    let pixels: Vec<&[u8]> = buffer[..info.buffer_size()].chunks(channels).collect();
    let background = pixels[0];
    let inked = pixels.iter().filter(|p| p[..3] != background[..3]).count();
    let colours: std::collections::HashSet<&[u8]> = pixels.iter().map(|p| &p[..3]).collect();
    assert!(
        inked * 100 >= pixels.len() && colours.len() > 2,
        "{} looks blank: {inked} of {} pixels inked, {} colours",
        path.display(),
        pixels.len(),
        colours.len()
    );
}

fn column(summary: &serde_json::Value, path: &[&str]) -> Vec<f64> {
    let mut v = summary;
    for key in path {
        v = &v[*key];
    }
    serde_json::from_value(v.clone()).unwrap_or_else(|e| panic!("{path:?}: {e} in {v}"))
}

#[test]
fn the_demo_calibrates_diagnoses_and_controls_the_simulated_rig() {
    let _serial = serial();
    let dir = Scratch::new("demo", "full");
    let args = ["demo", "--restarts", "1", "--omegas", "0.5", "--pace", "lockstep", "-o"];
    let out = Command::new(ARASH).args(args).arg(&dir).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    for table in ["Table I (OLS)", "Table II", "Effects found", "Error per joint, before → after", "max error cut by"]
    {
        assert!(stdout.contains(table), "the demo printed no `{table}`:\n{stdout}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report/summary.json")).unwrap()).unwrap();
    let runs = summary["tracking"]["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 4, "{summary}");
    assert_eq!(runs[3]["controller"], "robust, the rig's own parameters of the declared model", "{summary}");
    let cad = column(&runs[0], &["max_error"]);
    for run in &runs[1..] {
        let identified = column(run, &["max_error"]);
        eprintln!("max tracking error (SI): CAD {cad:?}, {} {identified:?}", run["controller"]);
        assert_eq!(run["faults"], 0, "{run}");
    }
    // The paper's result, that the identified model halves the CAD baseline's error, needs a
    // declared model the rig obeys: on the rig without undeclared effects it is checked in
    // tests/python/test_demo_rig.py. Here the rig has a wiring disturbance and Stribeck friction
    // the model lacks, which leave even its own parameters of the declared model cutting yaw,
    // pitch and insertion by only about 1.8×, 1.9× and 2.1× (docs/demo.md), and a fit over the
    // excitation takes them up in its own way: the calibration must still beat CAD on every
    // joint.
    let own = column(&runs[3], &["max_error"]);
    let identified = column(&runs[1], &["max_error"]);
    for k in 0..3 {
        assert!(identified[k] < cad[k], "joint {k}: identified {} against CAD {}", identified[k], cad[k]);
    }
    // The model with the effects found is what closes the loop: on no joint is its error to be
    // more than half again the larger of the rig's own parameters' and half CAD's (the margin
    // also takes up the host's stalls, which move a maximum). (Chosen on held-out blocks of the excitation, a wiring-like term on the insertion once
    // made it track 4.6 times worse than CAD; docs/demo.md.)
    let with_effects = column(&runs[2], &["max_error"]);
    for k in 0..3 {
        assert!(
            with_effects[k] <= 1.5 * (0.5 * cad[k]).max(own[k]),
            "joint {k}: with the effects {} against CAD {} and the rig's own parameters {}",
            with_effects[k],
            cad[k],
            own[k]
        );
    }
    // Compensating the wiring term found on pitch tracks pitch better than without it.
    assert!(
        with_effects[1] < 0.75 * identified[1],
        "pitch: {} with the effects, {} without",
        with_effects[1],
        identified[1]
    );
    // And within the paper's bounds, 0.35° for the rotations and 128 µm for the insertion, which
    // on this rig only the model with its effects can promise (the wiring alone leaves the
    // rig's own parameters at 0.34° on pitch).
    assert!(with_effects[0].to_degrees() < 0.35 && with_effects[1].to_degrees() < 0.35, "{with_effects:?}");
    assert!(with_effects[2] < 128e-6, "{with_effects:?}");

    // The closed-loop estimate against the simulated rig's own base parameters. Not ≥ 90 % (that
    // is checked where the model is complete, tests/python/test_demo_rig.py): the rig's
    // undeclared wiring disturbance and Stribeck friction bias the parameters that absorb them
    // (the diagnosis's job; docs/demo.md names them). With this design's small σ those biases
    // are misses: 15 to 21 of 22 covered in the runs of 2026-11-26. Half must be.
    let truth = &summary["within_3_sigma_of_truth"];
    let of = truth["of"].as_u64().expect("the demo's rig is simulated: its truth is known");
    let covered = truth["covered"]["idim-iv"].as_u64().unwrap();
    eprintln!("IDIM-IV within 3σ of the truth: {covered} of {of} ({truth})");
    assert!(covered * 2 >= of, "IDIM-IV covers only {covered} of {of} base parameters within 3σ");

    // Table I names why each σ% above 10 % is large. "Noisy" is what the model leaves
    // unexplained: fitted with the effects found, fewer parameters are.
    let causes = &summary["table_i_causes"];
    eprintln!("Table I's causes: {causes}");
    let noisy = |fit: &str| causes[fit]["noisy"].as_u64().unwrap_or_else(|| panic!("no causes for {fit}: {causes}"));
    assert!(noisy("with_effects") < noisy("idim_iv"), "{causes}");

    // The scenario's wiring disturbance on pitch (joint 1) is named, and first.
    let accepted = summary["diagnosis"]["accepted"].as_array().unwrap();
    eprintln!("diagnosis: {accepted:?}");
    let first = accepted.first().expect("the diagnosis found nothing");
    assert_eq!(first["name"], "configuration_disturbance", "{accepted:?}");
    assert_eq!(first["joints"], serde_json::json!([1]), "{accepted:?}");
    for split in ["training", "heldout"] {
        let before = column(&summary, &["diagnosis", "error_before", split, "rms"]);
        let after = column(&summary, &["diagnosis", "error_after", split, "rms"]);
        eprintln!("{split} RMS before {before:?}, after {after:?}");
        // The wiring term cuts the pitch error, and the whole robot's error falls (what the
        // search ranks by). On the excitation itself the joint refit may move the other joints a
        // hair; on the held-out validation runs, another trajectory, a joint without an effect
        // can lose a little to the refit of the parameters it shares (docs/demo.md).
        assert!(after[1] < 0.5 * before[1], "{split}: the pitch error must fall with the wiring term");
        let ratios: Vec<f64> = after.iter().zip(&before).map(|(a, b)| a / b).collect();
        assert!(ratios.iter().sum::<f64>() < ratios.len() as f64, "{split}: {before:?} → {after:?}");
        if split == "training" {
            assert!(ratios.iter().all(|r| *r <= 1.01), "{split}: {before:?} → {after:?}");
        }
    }

    // The real robot's chapter: the TX40's wrist motor, which turns with joints 5 and 6, is
    // named with the defaults and cuts joint 5's held-out error (docs/real-data.md).
    let real = &summary["real_robot"];
    let found = real["accepted"].as_array().unwrap_or_else(|| panic!("no real robot in {summary}"));
    assert!(
        found.iter().any(|f| f["name"] == "coupled_rotor" && f["joints"] == serde_json::json!([4, 5])),
        "{found:?}"
    );
    let (before, after) =
        (column(real, &["error_before", "heldout", "rms"]), column(real, &["error_after", "heldout", "rms"]));
    eprintln!("TX40 held-out RMS before {before:?}, after {after:?}");
    assert!(after[4] < 0.5 * before[4], "{before:?} → {after:?}");
    // Each coefficient its authors also estimated (motor 6's rotor and friction, the rotor
    // inertias found) agrees with theirs within 3 combined σ.
    for compared in real["against_published"].as_array().unwrap() {
        assert!(compared["z"].as_f64().unwrap().abs() < 3.0, "{compared}");
    }

    // The haptic mode's chapter (docs/haptics.md), on this rig with its undeclared effects: the
    // trainee's hand needs at least 3 times less force and moment about the remote centre with
    // the model and its effects than with CAD, and the bare device far more than CAD; the
    // stiffest wall accepted renders within 10 % of the ideal one and its energy does not grow
    // after the deepest press; a wall over the bound is refused.
    let haptic: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report/haptic/haptic.json")).unwrap()).unwrap();
    let rows = haptic["transparency"].as_array().unwrap();
    let named = |name: &str| rows.iter().find(|r| r["compensation"] == name).unwrap_or_else(|| panic!("{haptic}"));
    let norm = |r: &serde_json::Value, what: &str| column(r, &[what]).iter().map(|v| v * v).sum::<f64>().sqrt();
    let (none, cad, effects) = (named("none"), named("CAD"), named("identified + effects"));
    eprintln!("haptic transparency: {rows:?}");
    for what in ["force_rms", "moment_rms"] {
        assert!(norm(effects, what) * 3.0 <= norm(cad, what), "{what}: {haptic}");
        assert!(norm(none, what) > 3.0 * norm(cad, what), "{what}: {haptic}");
    }
    let wall = &haptic["wall"];
    assert!(wall["contact_cycles"].as_u64().unwrap() > 1000, "{wall}");
    assert!(wall["relative_error"].as_f64().unwrap() < 0.10, "{wall}");
    assert!(wall["energy_after"].as_f64().unwrap() <= 1.01 * wall["energy_at_deepest"].as_f64().unwrap(), "{wall}");
    assert!(wall["ringing"].as_u64().unwrap() <= 3, "{wall}");
    assert!(wall["refused_over_bound"].as_str().unwrap().contains("above the passivity bound"), "{wall}");

    let mut figures = Vec::new();
    pngs(&dir.join("report"), &mut figures);
    let names: Vec<String> = figures.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    for expected in
        ["excitation.png", "torque.png", "parameters.png", "tracking_error.png", "control_effort.png", "errors.png"]
    {
        assert!(names.iter().any(|n| n == expected), "no {expected} in {names:?}");
    }
    assert!(names.iter().any(|n| n.starts_with("effect-1-configuration_disturbance")), "{names:?}");
    figures.iter().for_each(|p| assert_figure(p));
    assert!(names.iter().any(|n| n.starts_with("effect-2-coupled_rotor")), "{names:?}");
    let report = std::fs::read_to_string(dir.join("report/report.md")).unwrap();
    assert!(report.contains("## A real robot: the Stäubli TX40's measured log"), "{report}");
    for name in &names {
        assert!(report.contains(name.as_str()), "report.md does not show {name}");
    }
    // Every run's log is complete.
    let logs: Vec<PathBuf> = std::fs::read_dir(dir.join("logs")).unwrap().flatten().map(|e| e.path()).collect();
    assert!(logs.len() >= 5, "{logs:?}");
    for log in logs {
        assert!(!read_log(&log).unwrap().truncated, "{} is truncated", log.display());
    }
}

/// Read the demo's output until it names its live stream, then, on another thread, connect as a
/// Foxglove client (subprotocol `foxglove.sdk.v1`), subscribe to `/arash/cycle` and return the
/// log times of the first 100 messages. The rest of the output is drained so the demo never
/// blocks on it.
fn watch_live(stdout: std::process::ChildStdout) -> std::thread::JoinHandle<Vec<u64>> {
    use std::io::BufRead;
    use tokio_tungstenite::tungstenite::{client::IntoClientRequest, Message};
    let mut lines = std::io::BufReader::new(stdout).lines();
    let address = loop {
        let line = lines.next().expect("the demo ended before naming its live stream").unwrap();
        if let Some(rest) = line.split("live stream on ws://").nth(1) {
            break rest.split(':').take(2).collect::<Vec<_>>().join(":");
        }
    };
    std::thread::spawn(move || lines.for_each(drop));
    std::thread::spawn(move || {
        let mut request = format!("ws://{address}").into_client_request().unwrap();
        request.headers_mut().insert("sec-websocket-protocol", "foxglove.sdk.v1".parse().unwrap());
        let tcp = std::net::TcpStream::connect(&address).unwrap();
        let (mut ws, _) = tokio_tungstenite::tungstenite::client(request, tcp).unwrap();
        let mut cycle_channel = None;
        while cycle_channel.is_none() {
            let Message::Text(text) = ws.read().unwrap() else { continue };
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            if v["op"] == "advertise" {
                let channels = v["channels"].as_array().unwrap();
                cycle_channel = channels.iter().find(|c| c["topic"] == "/arash/cycle").map(|c| c["id"].clone());
            }
        }
        let subscribe =
            serde_json::json!({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": cycle_channel}]});
        ws.send(Message::Text(subscribe.to_string().into())).unwrap();
        let mut times = Vec::new();
        while times.len() < 100 {
            if let Message::Binary(frame) = ws.read().unwrap() {
                // opcode 1 (message data), subscription id, log time, payload
                assert_eq!((frame[0], u32::from_le_bytes(frame[1..5].try_into().unwrap())), (1, 7));
                times.push(u64::from_le_bytes(frame[5..13].try_into().unwrap()));
            }
        }
        times
    })
}

#[test]
fn ctrl_c_disables_the_motors_and_keeps_the_logs() {
    let _serial = serial();
    let dir = Scratch::new("demo", "interrupt");
    let mut demo = Command::new(ARASH)
        .args(["demo", "--restarts", "1", "--omegas", "0.5", "--live", "127.0.0.1:0", "-o"])
        .arg(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stream = watch_live(demo.stdout.take().unwrap());
    // Interrupt once the excitation run has been moving the rig for a few seconds.
    let started = Instant::now();
    let logs = |dir: &Path| -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> =
            std::fs::read_dir(dir.join("logs")).map(|r| r.flatten().map(|e| e.path()).collect()).unwrap_or_default();
        v.sort_by_key(|p| std::fs::metadata(p).and_then(|m| m.modified()).ok());
        v
    };
    while !logs(&dir).iter().any(|p| p.to_string_lossy().contains("excitation")) {
        assert!(started.elapsed() < Duration::from_secs(120), "the excitation run never started");
        std::thread::sleep(Duration::from_millis(100));
    }
    std::thread::sleep(Duration::from_secs(4));
    // `--live`: the demo's daemon streamed the excitation run as it moved the rig. A message's log
    // time is its cycle's telemetry time, which cycles without fresh telemetry repeat (a loaded
    // host stalls the pty: seven equal times in a row beside two CPU hogs).
    let cycles = stream.join().unwrap();
    let in_order = cycles.windows(2).all(|w| w[1] >= w[0]) && cycles.last() > cycles.first();
    assert!(cycles.len() >= 50 && in_order, "{cycles:?}");
    // SAFETY: signalling our own child, as a terminal's Ctrl-C would.
    unsafe { libc::kill(demo.id() as i32, libc::SIGINT) };
    let stopped = Instant::now();
    let status = loop {
        if let Some(status) = demo.try_wait().unwrap() {
            break status;
        }
        assert!(stopped.elapsed() < Duration::from_secs(20), "the demo did not stop after Ctrl-C");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(!status.success(), "an interrupted demo must not report success");
    // The daemon closed its logs (no `.part` left): the interrupted run's log is readable to
    // its end, and the daemon's last log ends with the motors disabled.
    let files = logs(&dir);
    assert!(files.iter().all(|p| p.extension().is_some_and(|e| e == "mcap")), "unfinished logs: {files:?}");
    let run_log = files.iter().find(|p| p.to_string_lossy().contains("excitation")).unwrap();
    let run = read_log(run_log).unwrap();
    assert!(!run.truncated && run.len() > 1000, "{}: {} cycles", run_log.display(), run.len());
    // The last cycle logged, in whichever file holds it, has the motors off.
    let (last_cycle, last_mode) = files
        .iter()
        .map(|p| read_log(p).unwrap())
        .filter(|l| !l.is_empty())
        .map(|l| (*l.cycles.cycle.last().unwrap(), *l.cycles.mode.last().unwrap()))
        .max()
        .expect("cycles were logged");
    assert_eq!(
        <arash_core::record::Mode as arash_core::record::Code>::from_code(last_mode),
        Some(arash_core::record::Mode::Disabled),
        "cycle {last_cycle}: the motors were not disabled at the end"
    );
}
