//! Modules depend only downward (docs/architecture.md): each layer below lists the modules of a
//! crate, or the files of a folder module, lowest first, and no file may name a module listed
//! after its own. Read from the source: `crate::<module>`, and `super::<sibling>` inside a
//! folder. Comments and `#[cfg(test)]` sections are left out: a test may use anything. Between
//! crates Cargo enforces the order (arash-core ← arash-daemon ← arash-mock ← arash-cli,
//! arash-core ← arash-py), and a test here checks that the rig's binary links no plotting,
//! reports, identification or simulator.
//!
//! `cargo test -p arash-core --test layers` runs it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// arash-core, leaf first.
const CORE: &[&str] = &[
    "parallel",
    "dense",
    "spatial",
    "transmission",
    "params",
    "model",
    "choices",
    "urdf",
    "data",
    "kinematics",
    "regressor",
    "dynamics",
    "base_parameters",
    "physical",
    "effects",
    "control",
    "record",
    "model_file",
    "force",
    "haptics",
    "signal",
    "consistent",
    "identify",
    "force_log",
    "diagnose",
    "flightlog",
    "sim",
];

/// The files of arash-core's folder modules, leaf first (`mod.rs` is the folder's own face).
const FOLDERS: &[(&str, &[&str])] = &[
    ("control", &["gains", "safety", "fourier", "trajectory", "estimator", "feedforward", "laws", "logged"]),
    ("force", &["thresholds", "settings", "frame_force", "observer"]),
    ("haptics", &["fixtures", "geometry", "passivity", "render", "law"]),
    (
        "signal",
        &[
            "filter",
            "conditioning",
            "encoder",
            "resample",
            "statistics",
            "options",
            "log",
            "data_choices",
            "friction",
            "repair",
            "resting",
            "preprocess",
            "estimate",
            "friction_law",
            "cutoff",
        ],
    ),
    ("identify", &["options", "closed_loop", "drive_gains", "excitation"]),
    (
        "diagnose",
        &[
            "options",
            "findings",
            "regression",
            "band",
            "noise",
            "prepare",
            "weighted_fit",
            "band_choice",
            "candidates",
            "inputs",
            "gain_share",
            "delay",
            "outcome",
            "calibration_error",
            "guard",
            "search",
            "start",
            "refit",
            "report",
        ],
    ),
    ("flightlog", &["uniform", "schema", "reader", "writer", "recover"]),
    ("sim", &["scenario", "truth", "hand", "plant", "drive", "rig", "run", "trainee"]),
];

/// arash-daemon: the rig library, leaf first (its binary, `main.rs`, only calls `daemon`).
const DAEMON: &[&str] = &["exit", "link", "drive_config", "ctl", "rt", "live", "logger", "config", "daemon"];

/// The files of arash-daemon's folder modules, leaf first.
const DAEMON_FOLDERS: &[(&str, &[&str])] = &[
    ("link", &["frame", "serial", "can", "slcan", "canopen", "cia402", "drive_setup", "master"]),
    ("rt", &["clock", "memory", "reference", "force", "haptic", "cycle", "runner"]),
    ("live", &["window", "scene", "server"]),
    ("daemon", &["startup", "model_helper", "requests", "server"]),
];

/// arash-cli: the `arash` binary's modules (`main.rs` declares them), leaf first.
const CLI: &[&str] = &["runlog", "report", "cli", "docs_check"];

fn src(krate: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(krate).join("src")
}

/// The code of a file without comments and test sections.
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let text = text.split("#[cfg(test)]").next().unwrap_or_default();
    text.lines().filter(|l| !l.trim_start().starts_with("//")).collect::<Vec<_>>().join("\n")
}

/// Every `.rs` file of `module` under `root` (a file or a folder).
fn files_of(root: &Path, module: &str) -> Vec<PathBuf> {
    let file = root.join(format!("{module}.rs"));
    if file.exists() {
        return vec![file];
    }
    let mut out = Vec::new();
    let mut stack = vec![root.join(module)];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    out
}

/// The names that follow `prefix` in `code`, including each first segment of a `prefix{a, b::c}`
/// group.
fn named_after(code: &str, prefix: &str) -> Vec<String> {
    let ident = |s: &str| s.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect::<String>();
    let mut names = Vec::new();
    for (at, _) in code.match_indices(prefix) {
        let rest = &code[at + prefix.len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let inner = &group[..group.find('}').unwrap_or(group.len())];
            names.extend(inner.split(',').map(|item| ident(item.trim())));
        } else {
            names.push(ident(rest));
        }
    }
    names
}

/// The upward references among `layers`: (file, the module it names).
fn upward(root: &Path, layers: &[&str], prefixes: &[&str]) -> Vec<(String, String)> {
    let mut found = Vec::new();
    for (level, module) in layers.iter().enumerate() {
        for file in files_of(root, module) {
            let code = code(&file);
            for prefix in prefixes {
                for name in named_after(&code, prefix) {
                    if layers[level + 1..].contains(&name.as_str()) {
                        found.push((file.display().to_string(), name));
                    }
                }
            }
        }
    }
    found
}

#[test]
fn arash_core_modules_depend_only_downward() {
    let found = upward(&src("arash-core"), CORE, &["crate::"]);
    assert!(found.is_empty(), "upward references: {found:#?}");
}

#[test]
fn files_inside_a_folder_module_depend_only_downward() {
    let folders = FOLDERS.iter().map(|f| ("arash-core", f)).chain(DAEMON_FOLDERS.iter().map(|f| ("arash-daemon", f)));
    for (krate, (folder, files)) in folders {
        let root = src(krate);
        let found = upward(&root.join(folder), files, &["super::"]);
        assert!(found.is_empty(), "upward references in {folder}/: {found:#?}");
        let listed: Vec<String> = files_of(&root, folder)
            .iter()
            .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
            .filter(|s| s != "mod")
            .collect();
        for file in &listed {
            assert!(files.contains(&file.as_str()), "{folder}/{file}.rs is not in its layer list");
        }
    }
}

#[test]
fn arash_daemon_modules_depend_only_downward() {
    let found = upward(&src("arash-daemon"), DAEMON, &["crate::"]);
    assert!(found.is_empty(), "upward references: {found:#?}");
}

#[test]
fn arash_cli_modules_depend_only_downward() {
    let found = upward(&src("arash-cli"), CLI, &["crate::"]);
    assert!(found.is_empty(), "upward references: {found:#?}");
}

/// The crates below the rig's in a crate's normal dependency tree, by name.
fn dependencies(krate: &str) -> Vec<(String, String)> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args(["tree", "--offline", "--locked", "-e", "normal", "--prefix", "none", "-p", krate])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo tree runs");
    assert!(out.status.success(), "cargo tree -p {krate}: {}", String::from_utf8_lossy(&out.stderr));
    let lines = String::from_utf8_lossy(&out.stdout).into_owned();
    lines
        .lines()
        .filter_map(|l| {
            let mut words = l.split_whitespace();
            Some((words.next()?.to_string(), words.next()?.to_string()))
        })
        .collect()
}

/// Each crate's features in a build of `packages` (cargo tree's arguments) along `edges`: name and
/// version to the features enabled.
fn features(packages: &[&str], edges: &str) -> BTreeMap<String, BTreeSet<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args(["tree", "--offline", "--locked", "-e", edges, "--prefix", "none", "-f", "{p} {f}"])
        .args(packages)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo tree runs");
    assert!(out.status.success(), "cargo tree {packages:?}: {}", String::from_utf8_lossy(&out.stderr));
    let mut found: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let mut words = line.split_whitespace();
        let (Some(name), Some(version)) = (words.next(), words.next()) else { continue };
        if !version.starts_with('v') {
            continue; // a feature's own line (`serde feature "std"`)
        }
        let listed = words.filter(|w| !w.starts_with('(')).flat_map(|w| w.split(',')).map(String::from);
        found.entry(format!("{name} {version}")).or_default().extend(listed);
    }
    found
}

/// scripts/test builds the Python package with maturin (arash-py's dependencies alone) and the
/// workspace with cargo: the second reuses what the first compiled only where every crate gets
/// the same features in both (crates/arash-py/Cargo.toml enables the workspace's; issue 62).
#[test]
fn the_python_package_builds_its_dependencies_with_the_workspaces_features() {
    // The crates built for the target and for the host (build scripts, proc-macros) get their
    // features apart: compared all together, a crate that is both (itertools) hides a difference.
    for edges in ["features,no-build,no-proc-macro", "features"] {
        same_features(features(&["-p", "arash-py"], edges), features(&["--workspace"], edges), edges);
    }
}

fn same_features(
    package: BTreeMap<String, BTreeSet<String>>,
    workspace: BTreeMap<String, BTreeSet<String>>,
    edges: &str,
) {
    let differ: Vec<(&String, Vec<&String>)> = package
        .iter()
        .filter_map(|(krate, own)| {
            let all = workspace.get(krate)?;
            (all != own).then(|| (krate, all.symmetric_difference(own).collect()))
        })
        .collect();
    assert!(package.len() > 50, "{} crates read from cargo tree -e {edges}", package.len());
    assert!(
        differ.is_empty(),
        "features that differ between the two builds ({edges}), to enable in arash-py: {differ:?}"
    );
}

/// systemd runs `arash-daemon`: the tools' plotting, fonts, progress bars and CSV are not in it,
/// nor the identification's SDP, optimiser, statistics, FFT and filter design, the thread pool
/// they use, or the simulated rig (arash-core's `identification` and `simulation` features, and
/// the mock motor's crate). The same check on `arash` finds them all, so it can fail.
#[test]
fn the_rig_links_no_plotting_or_reports() {
    let tools = [
        "arash-cli",
        "plotters",
        "dejavu",
        "indicatif",
        "csv",
        "clarabel",
        "argmin",
        "statrs",
        "realfft",
        "sci-rs",
        "rayon",
        "rand_distr",
        "arash-mock",
        "arash-blas-lapack",
    ];
    let rig = dependencies("arash-daemon");
    let found: Vec<&&str> = tools.iter().filter(|t| rig.iter().any(|(d, _)| d == **t)).collect();
    assert!(found.is_empty(), "arash-daemon depends on {found:?}");
    let cli = dependencies("arash-cli");
    assert!(tools.iter().all(|t| cli.iter().any(|(d, _)| d == t)), "cargo tree -p arash-cli lacks one of {tools:?}");
}

/// One nalgebra in the rig: sci-rs brought a second (0.33 beside 0.35), which builds and links
/// the linear algebra twice. The CLI's tree, with sci-rs, has two, so the check can fail.
#[test]
fn the_rig_links_one_nalgebra() {
    let versions = |krate: &str| -> BTreeSet<String> {
        dependencies(krate).into_iter().filter(|(name, _)| name == "nalgebra").map(|(_, v)| v).collect()
    };
    assert_eq!(versions("arash-daemon").len(), 1, "nalgebra in arash-daemon: {:?}", versions("arash-daemon"));
    assert!(versions("arash-cli").len() > 1, "the CLI's tree has one nalgebra now: {:?}", versions("arash-cli"));
}

/// arash-core leaves the BLAS to the binary: its SDP calls the Fortran names, and only the
/// binaries that run it (the CLI, the Python extension) link arash's own, so that a program with
/// a BLAS of its own can link arash-core (`tests/own-blas` links the rig beside its own `dgemm_`).
#[test]
fn only_the_binaries_that_run_the_sdp_link_arash_blas() {
    let links = |krate: &str| dependencies(krate).iter().any(|(name, _)| name == "arash-blas-lapack");
    assert!(!links("arash-core"), "arash-core (default features) depends on arash-blas-lapack");
    assert!(links("arash-cli") && links("arash-py"), "the CLI or the Python extension lacks arash-blas-lapack");
}

/// The check can fail: an upward reference planted in a copy is found.
#[test]
fn an_upward_reference_is_found() {
    let dir = std::env::temp_dir().join(format!("arash-layers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("low.rs"), "use crate::high::Thing;\n// crate::ignored\n").unwrap();
    std::fs::write(dir.join("high.rs"), "use crate::low::{a, b::C};\n").unwrap();
    let found = upward(&dir, &["low", "high"], &["crate::"]);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].1, "high");
}

/// What the diagnosis may take from identification: the identified model it starts from (the
/// call, its options, its error). Every other thing both use (filters, derivatives, the period,
/// the cut-off and friction-law choices, the least squares that judges them, the consistent
/// fit) lives below both, in `signal` or `consistent` (issue 59).
const DIAGNOSIS_FROM_IDENTIFY: &[&str] = &["identify", "IdentifyOptions", "IdentifyError"];

/// The names a folder's files take from `crate::identify` that are not in `allowed`.
fn reaching_into_identify(folder: &Path, allowed: &[&str]) -> Vec<(String, String)> {
    let mut found = Vec::new();
    for file in files_of(folder.parent().unwrap(), &folder.file_name().unwrap().to_string_lossy()) {
        for name in named_after(&code(&file), "crate::identify::") {
            if !allowed.contains(&name.as_str()) {
                found.push((file.display().to_string(), name));
            }
        }
    }
    found
}

#[test]
fn the_diagnosis_takes_only_the_identified_model_from_identify() {
    let found = reaching_into_identify(&src("arash-core").join("diagnose"), DIAGNOSIS_FROM_IDENTIFY);
    assert!(found.is_empty(), "diagnose reaches into identify for: {found:#?}");
}

/// The check can fail: a preprocessing internal taken from identify in a copy is found.
#[test]
fn a_reach_into_identify_is_found() {
    let dir = std::env::temp_dir().join(format!("arash-reach-{}", std::process::id())).join("diagnose");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("start.rs"), "use crate::identify::{identify, IdentifyOptions};\n").unwrap();
    std::fs::write(dir.join("band.rs"), "use crate::identify::closed_loop::Estimator;\n").unwrap();
    let found = reaching_into_identify(&dir, DIAGNOSIS_FROM_IDENTIFY);
    std::fs::remove_dir_all(dir.parent().unwrap()).unwrap();
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].1, "closed_loop");
}
