//! The MCAP flight log: a written log reads back unchanged, a truncated one reads up to its last
//! flushed chunk, and the same seed writes the same log.

use arash_core::control::{ControllerKind, RobustGains, Trajectory};
use arash_core::flightlog::{read_log, LogWriter};
use arash_core::record::{Columns, TruthColumns};
use arash_core::sim::{true_parameters, RunSpec, Scenario};

fn spec(seconds: f64) -> RunSpec {
    let model = arash_core::arash_asist();
    let scenario = Scenario { name: "nominal".into(), ..Scenario::default() };
    RunSpec {
        params: true_parameters(&model, &scenario),
        effects: vec![],
        gains: Some(RobustGains::paper(&model).unwrap()),
        scenario,
        trajectory: Trajectory::PaperValidation { omega: 0.5 },
        controller: ControllerKind::Robust,
        params_source: "truth".into(),
        duration_s: seconds,
    }
}

/// Simulate `spec` into `path`; return what was written, from memory.
fn write(spec: &RunSpec, path: &std::path::Path) -> (Columns, TruthColumns) {
    let model = arash_core::arash_asist();
    let mut rig = spec.rig(&model).unwrap();
    let mut log =
        LogWriter::create(path, &spec.log_header(&model, arash_core::ARASH_ASIST_URDF, true), 1000.0).unwrap();
    let (mut cycles, mut truth) = (Columns::default(), TruthColumns::default());
    for _ in 0..spec.cycles() {
        rig.step().unwrap();
        log.write_cycle(rig.record()).unwrap();
        log.write_truth(rig.truth()).unwrap();
        cycles.push(rig.record());
        truth.push(rig.truth());
    }
    log.finish().unwrap();
    (cycles, truth)
}

/// A directory removed when the test ends, pass or fail.
struct Scratch(std::path::PathBuf);

impl Scratch {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("arash-flightlog-{}-{test}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    fn path(&self, name: &str) -> std::path::PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn a_log_reads_back_exactly() {
    let scratch = Scratch::new("a_log_reads_back_exactly");
    let path = scratch.path("roundtrip.mcap");
    let spec = spec(2.5);
    let (cycles, truth) = write(&spec, &path);
    let log = read_log(&path).unwrap();
    assert!(!log.truncated);
    assert_eq!(log.joint_names, ["yaw", "pitch", "insertion"]);
    assert_eq!(log.cycles, cycles, "every field of every cycle, bit for bit");
    assert_eq!(log.truth.as_ref(), Some(&truth));
    assert_eq!(log.attachment_text("robot.urdf").as_deref(), Some(arash_core::ARASH_ASIST_URDF));
    let scenario = Scenario::from_toml(&log.attachment_text("scenario.toml").unwrap()).unwrap();
    assert_eq!(scenario, spec.scenario);
    assert_eq!(log.metadata["format"], "arash-log/1");
    assert_eq!(log.metadata["controller"], "robust");
    assert_eq!(log.metadata["seed"], "1");
}

#[test]
fn a_truncated_log_reads_up_to_its_last_flushed_chunk() {
    let scratch = Scratch::new("a_truncated_log_reads_up_to_its_last_flushed_chunk");
    let path = scratch.path("whole.mcap");
    let (cycles, _) = write(&spec(5.0), &path);
    let bytes = std::fs::read(&path).unwrap();
    for fraction in [0.999, 0.75, 0.5, 0.3] {
        let cut = scratch.path(&format!("cut-{fraction}.mcap"));
        let keep = (bytes.len() as f64 * fraction) as usize;
        std::fs::write(&cut, &bytes[..keep]).unwrap();
        let log = read_log(&cut).unwrap_or_else(|e| panic!("cut at {keep} bytes: {e}"));
        assert!(log.truncated, "cut at {fraction}");
        let n = log.len();
        // Chunks close every second (1000 cycles) and are about equal in size.
        let expected = (fraction * cycles.t.len() as f64 / 1000.0).floor() as usize * 1000;
        assert!(n + 1000 >= expected && n <= cycles.t.len(), "cut at {fraction}: {n} cycles");
        assert_eq!(&log.cycles.t[..], &cycles.t[..n]);
        assert_eq!(&log.cycles.tau_meas[..], &cycles.tau_meas[..3 * n]);
        let truth = log.truth.unwrap().t.len();
        assert!(truth.abs_diff(n) <= 1, "{truth} truth messages for {n} cycles");
    }
    // Cut inside the header: a clear error, not a panic.
    let cut = scratch.path("header.mcap");
    std::fs::write(&cut, &bytes[..20]).unwrap();
    let e = read_log(&cut).unwrap_err().to_string();
    assert!(e.contains("header.mcap"), "{e}");
}

#[test]
fn the_same_seed_writes_the_same_log() {
    let scratch = Scratch::new("the_same_seed_writes_the_same_log");
    let (a, b) = (scratch.path("a.mcap"), scratch.path("b.mcap"));
    write(&spec(1.2), &a);
    write(&spec(1.2), &b);
    let (a, b) = (read_log(&a).unwrap(), read_log(&b).unwrap());
    // The data sections are byte-identical; mcap orders some summary records from hash maps.
    assert_eq!(a.cycles, b.cycles);
    assert_eq!(a.truth, b.truth);
    assert_eq!(a.metadata, b.metadata);
}

#[test]
fn other_files_are_refused_with_their_name() {
    let scratch = Scratch::new("other_files_are_refused_with_their_name");
    let path = scratch.path("not-a-log.mcap");
    std::fs::write(&path, "t,q\n0,1\n").unwrap();
    let e = read_log(&path).unwrap_err().to_string();
    assert!(e.contains("not-a-log.mcap"), "{e}");
    let e = read_log(&scratch.path("missing.mcap")).unwrap_err().to_string();
    assert!(e.contains("missing.mcap"), "{e}");
}
