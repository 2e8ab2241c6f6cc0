//! The fuzz targets' properties in every test run, on stable: each target of fuzz/ (its check in
//! fuzz/targets/) on its committed corpus (fuzz/corpus/<target>: the inputs that reached new
//! code when it was fuzzed) and on random inputs. Coverage-guided fuzzing itself needs the
//! nightly toolchain and minutes; it is `scripts/fuzz-smoke`, in `scripts/test --full`.

use std::path::Path;

use proptest::prelude::*;

#[path = "../../../fuzz/targets/robot.rs"]
mod robot;

#[path = "../../../fuzz/targets/can_link.rs"]
mod can_link;
#[path = "../../../fuzz/targets/canopen_link.rs"]
mod canopen_link;
#[path = "../../../fuzz/targets/config.rs"]
mod config;
#[path = "../../../fuzz/targets/model_file.rs"]
mod model_file;
#[path = "../../../fuzz/targets/serial_link.rs"]
mod serial_link;
#[path = "../../../fuzz/targets/trajectory.rs"]
mod trajectory;

/// Run `check` on every input of the target's committed corpus; how many there were.
fn replay(target: &str, check: fn(&[u8])) -> usize {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus").join(target);
    let mut inputs = 0;
    for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        check(&std::fs::read(&path).unwrap());
        inputs += 1;
    }
    inputs
}

/// The tests of one target, in module `$tests`: its corpus, and random inputs (text for a
/// target that reads text).
macro_rules! target {
    ($tests:ident, $name:ident, $text:expr) => {
        mod $tests {
            use super::*;

            #[test]
            fn its_corpus_replays() {
                assert!(replay(stringify!($name), super::$name::check) > 0, "an empty corpus");
            }

            proptest! {
                #![proptest_config(ProptestConfig { cases: 512, failure_persistence: None, ..ProptestConfig::default() })]
                #[test]
                fn random_inputs_hold(data in if $text {
                    "(?s).{0,400}".prop_map(String::into_bytes).boxed()
                } else {
                    proptest::collection::vec(any::<u8>(), 0..400).boxed()
                }) {
                    super::$name::check(&data);
                }
            }
        }
    };
}

target!(serial_link_target, serial_link, false);
target!(can_link_target, can_link, false);
target!(canopen_link_target, canopen_link, false);
target!(config_target, config, true);
target!(model_file_target, model_file, true);
target!(trajectory_target, trajectory, true);
