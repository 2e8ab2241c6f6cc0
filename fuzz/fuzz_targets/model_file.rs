//! The fuzz target `model_file`: fuzz/targets/model_file.rs, which `crates/arash-daemon/tests/fuzz_replay.rs`
//! also runs on stable on the committed corpus and on random inputs.
#![no_main]

#[path = "../targets/robot.rs"]
mod robot;
#[path = "../targets/model_file.rs"]
mod target;

libfuzzer_sys::fuzz_target!(|data: &[u8]| target::check(data));
