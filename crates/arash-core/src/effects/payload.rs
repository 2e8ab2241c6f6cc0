//! `payload`: a load on one body, as a change of its inertial parameters: its mass and first
//! moments (`m`, `m·c`), and, where the data show it, its inertia about the body's frame origin.
//! Its columns are the body's own regressor columns, and a controller folds it into the
//! parameter vector rather than adding a torque.
//!
//! Every load has an inertia (a point mass at `c` alone adds `m(|c|²I − c cᵀ)` about the
//! origin), but on a short log six more columns cost the test its power: a 50 g load on
//! ARASH:ASiST's instrument holder was no longer found with ten columns. So a payload is searched
//! with four, and once accepted its inertia is tested beside it (`diagnose/search.rs`). Left out
//! where the data show it, the inertia was taken up by other terms: on a simulated six-axis arm
//! carrying a 2.8 kg load, rotor inertia on every joint or a drive gain was accepted beside the
//! payload in half the seeds (issue 59).

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Payload;

impl Effect for Payload {
    fn id(&self) -> &'static str {
        "payload"
    }
    fn width(&self) -> usize {
        MASS_AND_MOMENTS
    }
    fn column_names(&self) -> Vec<String> {
        NAMES[..MASS_AND_MOMENTS].iter().map(|n| n.to_string()).collect()
    }
    /// A payload adds mass. A fit with less mass than the model is a model that was too
    /// heavy, or another error that correlates with gravity, and never a payload.
    fn physical_sign(&self) -> Option<f64> {
        Some(1.0)
    }
    fn plotted_against(&self) -> &'static str {
        "q"
    }
    /// A payload has no joint-wise features: its columns are the body's regressor columns.
    fn features(&self, _: &EffectTerm, _: Sample, _: &mut TermState, _: &mut [f64]) {}
    fn detail(&self, term: &EffectTerm) -> String {
        let inertia = if has_inertia(term) { ", with its inertia" } else { "" };
        format!(" on {}{inertia}", term.body.as_deref().unwrap_or("?"))
    }
    /// Searched per body, not per joint.
    fn joint_candidates(&self, _: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![])
    }
}

/// The names of a body's ten inertial parameters, in the order of its columns.
const NAMES: [&str; crate::params::PER_BODY] = ["m", "m·cx", "m·cy", "m·cz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"];

/// A payload's mass and first moments: the first four of its body's ten.
const MASS_AND_MOMENTS: usize = 4;

/// The candidate on body `name`: its mass and first moments.
pub fn on_body(name: &str) -> EffectTerm {
    let mut t = EffectTerm::new(EffectKind::Payload, None);
    t.body = Some(name.to_string());
    t.columns = Payload.column_names();
    t
}

/// `payload` with its inertia: all ten of its body's inertial parameters.
pub fn with_inertia(payload: &EffectTerm) -> EffectTerm {
    let mut t = payload.clone();
    t.columns = NAMES.map(String::from).to_vec();
    t.coefficients.clear();
    t.sigma.clear();
    t
}

/// Whether `term` (a payload) carries its inertia: its columns, as written, go past the mass
/// and first moments.
pub fn has_inertia(term: &EffectTerm) -> bool {
    term.columns.len() > MASS_AND_MOMENTS
}
