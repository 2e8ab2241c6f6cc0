//! The fuzz target `canopen_link`: fuzz/targets/canopen_link.rs, which `crates/arash-daemon/tests/fuzz_replay.rs`
//! also runs on stable on the committed corpus and on random inputs.
#![no_main]

#[path = "../targets/canopen_link.rs"]
mod target;

libfuzzer_sys::fuzz_target!(|data: &[u8]| target::check(data));
