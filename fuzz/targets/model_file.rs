//! Any text as a model file: loaded and judged for a controller (shape, finiteness, physical
//! consistency recomputed from its parameters) without a panic; what is accepted is finite.

use arash_core::model_file::ModelFile;

use crate::robot::model;

pub fn check(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(id) = ModelFile::from_json(text) else { return };
    if let Ok(params) = id.controller_parameters(model()) {
        assert!(params.iter().all(|x| x.is_finite()));
        let _ = id.consistent_controller_parameters(model());
    }
}
