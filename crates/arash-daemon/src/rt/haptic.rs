//! The haptic mode in the cycle (docs/haptics.md): the trainee moves the instrument, and the
//! cycle commands `arash_core::haptics::HapticLaw`, the model's compensation with a share of
//! the viscous friction left to damp the rendered fixtures, plus the fixtures' torque: the same
//! law the simulated rig's tests run. Built off the real-time thread; a step never allocates.

use arash_core::effects::EffectTerm;
use arash_core::haptics::{check_passivity, Fixtures, HapticLaw, Passivity, RenderError, RenderLoop, Rendered};
use arash_core::Model;

/// `[haptic]` in the daemon's configuration.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HapticConfig {
    /// The share of each joint's identified viscous friction the mode compensates, in [0, 1).
    /// What it leaves is the physical damping that lets a wall be rendered passively: at 0 the
    /// hand feels the viscous friction (on ARASH:ASiST's CAD model 2 N·s/m along the insertion,
    /// 0.02 N at a surgeon's 10 mm/s) and the stiffest walls are allowed.
    pub viscous_compensation: f64,
    /// How long after its measurement a command acts, beyond the hold's half period (ms).
    /// Default: one period, since the drive's telemetry answers the previous command.
    pub latency_ms: Option<f64>,
    /// Over how long the command hands over between the mode and the controller, entering and
    /// leaving (ms): the difference between the two fades out linearly instead of stepping, so
    /// that a wall the hand pressed into does not vanish in one cycle.
    pub handover_ms: f64,
    /// The share of the arm's inertial torque `M(q) q̈ + C q̇` fed forward, in [0, 1): the
    /// trainee feels that much less of the instrument's mass. Off by default: on a trainee's
    /// path of a few millimetres a second it buys little (docs/haptics.md, "Inertia").
    pub inertia_compensation: f64,
    /// The low-pass (Hz) of the differenced velocity the feed-forward takes as `q̈`. Its lag
    /// takes damping away, about `s·M·ω²/ω_c` at frequency `ω`: at 10 Hz the hand's grasp rang
    /// and its force doubled; at 40 Hz it halved (docs/haptics.md, "Inertia").
    pub acceleration_cutoff_hz: f64,
}

impl Default for HapticConfig {
    fn default() -> Self {
        Self {
            viscous_compensation: 0.0,
            latency_ms: None,
            handover_ms: 100.0,
            inertia_compensation: 0.0,
            acceleration_cutoff_hz: 40.0,
        }
    }
}

impl HapticConfig {
    pub fn validate(&self) -> Result<(), String> {
        if !(0.0..1.0).contains(&self.viscous_compensation) {
            return Err(format!(
                "haptic.viscous_compensation must be in [0, 1), not {}: what is left damps the fixtures",
                self.viscous_compensation
            ));
        }
        if let Some(l) = self.latency_ms.filter(|l| !(l.is_finite() && *l >= 0.0)) {
            return Err(format!("haptic.latency_ms must be finite and at least 0, not {l}"));
        }
        if !(self.handover_ms.is_finite() && self.handover_ms >= 0.0) {
            return Err(format!("haptic.handover_ms must be finite and at least 0, not {}", self.handover_ms));
        }
        if !(0.0..1.0).contains(&self.inertia_compensation) {
            return Err(format!(
                "haptic.inertia_compensation must be in [0, 1), not {}: all of it would cancel the arm's mass",
                self.inertia_compensation
            ));
        }
        if !(self.acceleration_cutoff_hz.is_finite() && self.acceleration_cutoff_hz > 0.0) {
            return Err(format!(
                "haptic.acceleration_cutoff_hz must be positive and finite, not {}",
                self.acceleration_cutoff_hz
            ));
        }
        Ok(())
    }

    /// The loop that renders the fixtures at `period_s` on a model with parameters `params`.
    pub fn render_loop(&self, model: &Model, params: &[f64], period_s: f64) -> Result<RenderLoop, String> {
        let latency_s = self.latency_ms.map_or(period_s, |l| 1e-3 * l);
        RenderLoop::of_model(model, params, self.viscous_compensation, period_s, latency_s).map_err(|e| e.to_string())
    }
}

/// A fixture file as read: TOML, its fields checked by name.
pub fn parse_fixtures(text: &str) -> Result<Fixtures, String> {
    let fixtures: Fixtures = toml::from_str(text).map_err(|e| e.to_string())?;
    fixtures.validate().map_err(|e| e.to_string())?;
    Ok(fixtures)
}

/// The mode as the cycle runs it.
pub struct HapticMode {
    law: HapticLaw,
    /// What the passivity check found, for `ctl status`.
    pub passivity: Passivity,
}

impl HapticMode {
    /// The mode rendering `fixtures` on `model` with parameters `params` and `effects` at
    /// `period_s`: refused where the loop cannot render them passively, with the bound in the
    /// message. The Coulomb widths are the controllers' ([`super::force::cycle_epsilon`]).
    pub fn build(
        model: &Model,
        (params, effects): (&[f64], &[EffectTerm]),
        config: &HapticConfig,
        fixtures: &Fixtures,
        period_s: f64,
    ) -> Result<Self, String> {
        config.validate()?;
        let looped = config.render_loop(model, params, period_s)?;
        let passivity = check_passivity(model, fixtures, &looped).map_err(|e| e.to_string())?;
        let epsilon = super::force::cycle_epsilon(model);
        let law = HapticLaw::new(model, params, effects, &epsilon, config.viscous_compensation, fixtures)
            .and_then(|law| law.with_inertia(config.inertia_compensation, config.acceleration_cutoff_hz, period_s))
            .map_err(|e| e.to_string())?;
        Ok(Self { law, passivity })
    }

    /// The law the mode runs, for a simulated rig to run as the cycle would (`arash demo`).
    pub fn into_law(self) -> HapticLaw {
        self.law
    }

    /// This cycle's command at state `q`, `qd`.
    pub fn command(&mut self, q: &[f64], qd: &[f64], tau: &mut [f64]) -> Result<Rendered, RenderError> {
        self.law.command(q, qd, tau)
    }
}
