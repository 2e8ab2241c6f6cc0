//! Any text as a model file: loaded and judged for a controller (shape, finiteness, physical
//! consistency recomputed from its parameters) without a panic; what is accepted is finite.
#![no_main]

use std::sync::OnceLock;

use arash_core::identify::Identification;
use arash_core::Model;
use libfuzzer_sys::fuzz_target;

fn model() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(arash_core::arash_asist)
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(id) = Identification::from_json(text) else { return };
    if let Ok(params) = id.controller_parameters(model()) {
        assert!(params.iter().all(|x| x.is_finite()));
        let _ = id.consistent_controller_parameters(model());
    }
});
