//! `payload`: a mass on one body, as a change of its mass and first moments (`m`, `m·c`). Its
//! columns are the body's own regressor columns, and a controller folds it into the parameter
//! vector rather than adding a torque.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Payload;

impl Effect for Payload {
    fn id(&self) -> &'static str {
        "payload"
    }
    fn width(&self) -> usize {
        crate::params::MASS_AND_MOMENTS
    }
    fn column_names(&self) -> Vec<String> {
        vec!["m".into(), "m·cx".into(), "m·cy".into(), "m·cz".into()]
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
        format!(" on {}", term.body.as_deref().unwrap_or("?"))
    }
    /// Searched per body, not per joint.
    fn joint_candidates(&self, _: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![])
    }
}

/// The candidate on body `name`.
pub fn on_body(name: &str) -> EffectTerm {
    let mut t = EffectTerm::new(EffectKind::Payload, None);
    t.body = Some(name.to_string());
    t.columns = Payload.column_names();
    t
}
