//! The fuzz target `config`: fuzz/targets/config.rs, which `crates/arash-daemon/tests/fuzz_replay.rs`
//! also runs on stable on the committed corpus and on random inputs.
#![no_main]

#[path = "../targets/robot.rs"]
mod robot;
#[path = "../targets/config.rs"]
mod target;

libfuzzer_sys::fuzz_target!(|data: &[u8]| target::check(data));
