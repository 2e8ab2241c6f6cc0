//! Where a diagnosis starts. Given a model, from it. Without one, by default, from the model
//! identification makes of the same log with its own choices (periods averaged where the log is
//! periodic, its cut-off, each joint's Coulomb law): the diagnosis builds on the identification,
//! and its "before" is the model a user already has (issue 59). On a held-back surgical arm the
//! declared model refitted at the diagnosis's band, without averaging and with its own law,
//! predicted the yaw half again worse than the identified model, where nothing was added.
//!
//! The declared parameters are refitted together with the effects first: an effect the
//! identification lacks (an offset, a wiring disturbance) biases the parameters it fitted, and
//! the refit lets them move back (the KUKA's wrist joints, docs/diagnosis.md). The refit chooses
//! each Coulomb law at the diagnosis's band, as without a model ([`Laws::Own`]): fitted with the
//! identification's, chosen at its cut-off, a Stribeck term made up for a law chosen wrong on a
//! log of the declared model. The start still predicts with its own laws. The guard holds
//! every joint to the identified model's held-out error; where the refit itself loses on a joint
//! (no effect there to drop), the diagnosis runs again with the identified parameters held and
//! friction refitted, each law again chosen at the band, where its guard can put the friction back
//! with the identification's law (held with its laws, a Stribeck term made up for one on the
//! TX40's motor-side null). Where identification refuses
//! the log, the declared model is refitted, and the reason says why.

use super::findings::{Diagnosis, StartedFrom};
use super::options::{DiagnoseError, DiagnoseOptions, Start};
use super::search::{band_for, diagnose_against, diagnose_in_band, Laws};
use super::Runs;
use std::borrow::Cow;

use crate::base_parameters::{BaseParameterOptions, BaseParameters};
use crate::choices::Choice;
use crate::identify::{identify, IdentifyOptions};
use crate::model_file::{IdentifyMethod, ModelFile};
use crate::signal::log::{Declared, Log};

/// Diagnose `train`: against `given`, or without it from where `options.start` says, holding
/// out `validation` when it is given (a [`Log`] converts into one run). From the
/// identification, `declared.base` may be the base parameters identification fits
/// (`BaseParameterOptions::fitted`) or the exact ones; the diagnosis works in the exact ones.
pub fn diagnose(
    declared: Declared,
    train: Log,
    validation: Option<Runs>,
    given: Option<&ModelFile>,
    options: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    match (given, options.start) {
        (Some(_), _) | (None, Start::Declared) => {
            diagnose_against(declared, (train, validation), given, Laws::OfGiven, options)
        }
        (None, Start::Identified) => from_identified(declared, train, validation, options),
    }
}

fn from_identified(
    declared: Declared,
    train: Log,
    validation: Option<Runs>,
    options: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    options.validate(declared.model.dof())?;
    // The start is the model `arash identify` gives, in its base parameters (the weak ones
    // regrouped); the diagnosis works in every exact one, that model with the weak ones at zero,
    // which predicts exactly as it does. A refit in the regrouped ones would carry the
    // regrouping's bias (`BaseParameterOptions::diagnosed`), and a start in the exact ones is not
    // the user's model: on ARASH:ASiST its instrument holder's weak parameter moved the start's
    // prediction by 10⁻⁴ of the torque, which an 8 Hz yardstick read as a loss of 5–8 standard
    // errors on joints the diagnosis held to it.
    // `declared.base` serves as the regrouped ones where the weak-parameter test made it (a
    // front end's cached `BaseParameterOptions::fitted`; on the KUKA that test is 0.28 s of a
    // diagnosis, the exact ones 0.03 s).
    let exact = BaseParameters::compute(declared.model, &BaseParameterOptions::diagnosed())
        .map_err(|e| DiagnoseError::Identify(e.into()))?;
    let fitted = match declared.base.reach_gap {
        Some(_) => Cow::Borrowed(declared.base),
        None => Cow::Owned(declared.base.identifiable(declared.model, &BaseParameterOptions::fitted(false))),
    };
    let identified =
        identify(Declared { base: &fitted, ..declared }, train, IdentifyMethod::Ols, &IdentifyOptions::default())
            .map(|file| file.in_base(&exact).expect("the exact base parameters hold the regrouped ones' columns"));
    let declared = Declared { base: &exact, ..declared };
    let identified = match identified {
        Ok(file) => file,
        Err(e) => {
            let mut d = diagnose_against(declared, (train, validation), None, Laws::OfGiven, options)?;
            d.settings.reasons.insert(0, Choice::DiagnosisFromDeclared { why: e.to_string() });
            return Ok(d);
        }
    };
    let refit = DiagnoseOptions { refit: true, hold_friction: false, ..options.clone() };
    // Both runs choose their band and laws alike; the second shares the first's.
    let band = band_for(declared, (train, validation.as_ref()), Some(&identified), Laws::Own, &refit)?;
    let refitted = diagnose_in_band(declared, (train, validation), Some(&identified), Laws::Own, &refit, &band)?;
    if refitted.still_worse.is_empty() {
        return Ok(started_from(refitted, &identified, true, vec![]));
    }
    let held = DiagnoseOptions { refit: false, ..options.clone() };
    let d = diagnose_in_band(declared, (train, validation), Some(&identified), Laws::Own, &held, &band)?;
    Ok(started_from(d, &identified, false, refitted.still_worse))
}

/// `d` marked as started from `identified`, with the reason first.
fn started_from(
    mut d: Diagnosis,
    identified: &ModelFile,
    refitted: bool,
    worse: Vec<crate::choices::Worse>,
) -> Diagnosis {
    d.settings.started_from = StartedFrom::Identified;
    let reason = Choice::DiagnosisFromIdentified {
        periods: identified.data.periods_averaged,
        cutoff_hz: identified.settings.cutoff_hz,
        velocities: identified.coulomb_laws().velocities(),
        refitted,
        worse,
    };
    d.settings.reasons.insert(0, reason);
    d
}
