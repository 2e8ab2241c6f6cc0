//! ARASH:ASiST, built once per fuzzing process (included by the targets that need the model).

use std::sync::OnceLock;

use arash_core::Model;

pub fn model() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(arash_core::arash_asist)
}
