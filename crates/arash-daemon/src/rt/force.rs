//! The hand's force in the cycle: the momentum observer on the model in use, run on every
//! telemetry frame in every mode, its estimate mapped to a frame, and the level (free, contact,
//! collision) its thresholds give it. Built at start-up ([`ForceSetup::build`]); a step never
//! allocates.

use arash_core::choices::ForceChoice;
use arash_core::control::gains::{compensation_epsilon, model_epsilon, RobustGains};
use arash_core::force::settings::{default_bandwidth, default_frame, held_out_sigma, sigma_thresholds};
use arash_core::force::{FrameForce, Level, MomentumObserver, ObserverError, Thresholds, TorqueTiming};
use arash_core::model_file::HeldOut;
use arash_core::record::CycleRecord;
use arash_core::Model;

/// The hand's force observer (docs/force.md, "In the daemon"): it runs on every telemetry
/// frame, in every mode, on the model the daemon started with. A collision during a trajectory
/// run latches `collision`: the run stops and the joints float under the model's gravity and
/// friction compensation until the operator's reset.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ForceConfig {
    pub enabled: bool,
    /// The frame the force is mapped to; empty: the robot's instrument tip, where it names one.
    pub frame: String,
    /// Per joint (Hz); default: the model file's held-out observer run, else a quarter of the
    /// band its held-out σ was measured in, else 20 Hz (`force::settings::default_bandwidth`).
    pub bandwidth_hz: Option<Vec<f64>>,
    /// Thresholds by hand, per joint (N·m, N); default: multiples of the model file's σ.
    pub contact: Option<Vec<f64>>,
    pub collision: Option<Vec<f64>>,
    pub contact_sigmas: f64,
    pub collision_sigmas: f64,
}

impl Default for ForceConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            frame: String::new(),
            bandwidth_hz: None,
            contact: None,
            collision: None,
            contact_sigmas: arash_core::force::CONTACT_SIGMAS,
            collision_sigmas: arash_core::force::COLLISION_SIGMAS,
        }
    }
}

impl ForceConfig {
    /// Per-joint vectors of the robot's length, positive; thresholds both or neither, collision
    /// at or above contact; the frame one the robot names.
    pub fn validate(&self, model: &Model) -> Result<(), String> {
        let dof = model.dof();
        for (key, v) in [
            ("force.bandwidth_hz", &self.bandwidth_hz),
            ("force.contact", &self.contact),
            ("force.collision", &self.collision),
        ] {
            let Some(v) = v else { continue };
            if v.len() != dof {
                return Err(format!("{key} has {} entries; the robot has {dof} joints", v.len()));
            }
            if let Some(&value) = v.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
                return Err(format!("{key} must be positive and finite, not {value}"));
            }
        }
        match (&self.contact, &self.collision) {
            (Some(c), Some(k)) if c.iter().zip(k).any(|(c, k)| k < c) => {
                return Err("force.collision is below force.contact on some joint".into())
            }
            (Some(_), None) | (None, Some(_)) => return Err("force.contact and force.collision go together".into()),
            _ => {}
        }
        for (key, value) in
            [("force.contact_sigmas", self.contact_sigmas), ("force.collision_sigmas", self.collision_sigmas)]
        {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("{key} must be positive and finite, not {value}"));
            }
        }
        if self.collision_sigmas < self.contact_sigmas {
            return Err("force.collision_sigmas is below force.contact_sigmas".into());
        }
        if !self.frame.is_empty() {
            model.frame(&self.frame).map_err(|e| format!("force.frame: {e}"))?;
        }
        Ok(())
    }
}

/// The observer, its map and its thresholds.
pub struct ForceMonitor {
    observer: MomentumObserver,
    map: Option<FrameForce>,
    thresholds: Option<Thresholds>,
    sigma: Vec<f64>,
}

/// What the monitor is built from, as the daemon resolved it; also what `ctl status` shows.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ForceSetup {
    pub bandwidth_hz: Vec<f64>,
    /// Each joint's σ of the estimate (N·m, N), when the model file records one.
    pub sigma: Option<Vec<f64>>,
    pub contact: Option<Vec<f64>>,
    pub collision: Option<Vec<f64>>,
    /// The frame the force is mapped to, and the frame its moment is about.
    pub frame: Option<String>,
    /// What chose each value.
    pub reasons: Vec<ForceChoice>,
}

impl ForceSetup {
    /// Resolve the observer's settings: the configuration's, else what the model file's held-out
    /// data gives (`held_out`), by the rules an offline estimate follows (`force_log`); without
    /// it a hand's bandwidth at `rate_hz` and no thresholds. Thresholds at multiples of σ need
    /// the file's observer run (`held_out.observer`).
    pub fn resolve(
        model: &Model,
        config: &ForceConfig,
        held_out: Option<&HeldOut>,
        rate_hz: f64,
    ) -> Result<Self, String> {
        let n = model.dof();
        let mut reasons = Vec::new();
        let bandwidth_hz = match &config.bandwidth_hz {
            Some(b) => b.clone(),
            None => {
                let (b, why) = default_bandwidth(held_out, None, rate_hz, n);
                reasons.push(why);
                b
            }
        };
        let sigma = held_out.map(|h| {
            let (sigma, why) = held_out_sigma(h);
            reasons.push(why);
            sigma
        });
        // Only the observer's own hand-free run gives a σ of the estimate and a peak to keep a
        // collision above: a residual's RMS is the model's error in its fitted band, which the
        // observer, on the cycle's velocity, exceeds (on the demo's rig a model file with only
        // the diagnosis's residual flickered in and out of contact at once and latched a false
        // collision within 0.2 s of a run).
        let observed = held_out.is_some_and(|h| h.observer.is_some());
        let (contact, collision) = match (&config.contact, &config.collision, &sigma) {
            (Some(c), Some(k), _) => {
                reasons.push(ForceChoice::ThresholdsByHand);
                (Some(c.clone()), Some(k.clone()))
            }
            (None, None, Some(s)) if observed => {
                let (t, why) = sigma_thresholds(s, config.contact_sigmas, config.collision_sigmas, held_out)
                    .map_err(|e| e.to_string())?;
                reasons.push(ForceChoice::ThresholdsFromSigma {
                    contact: config.contact_sigmas,
                    collision: config.collision_sigmas,
                });
                reasons.extend(why);
                (Some(t.contact().to_vec()), Some(t.collision().to_vec()))
            }
            (None, None, Some(_)) => {
                reasons.push(ForceChoice::NoThresholdsResidualSigma);
                (None, None)
            }
            (None, None, None) => {
                reasons.push(ForceChoice::NoThresholdsNoSigma);
                (None, None)
            }
            _ => return Err("force.contact and force.collision go together".into()),
        };
        let frame = match config.frame.as_str() {
            "" => default_frame(model).map(|c| c.frame),
            name => Some(name.to_string()),
        };
        Ok(Self { bandwidth_hz, sigma, contact, collision, frame, reasons })
    }

    /// The settings [`Self::resolve`] gives and the monitor [`Self::build`] makes with them, on
    /// `model` with parameters `params` and `effects`: what the daemon runs at start-up and after
    /// a switch to a model file. Errors are prefixed `[force]`.
    pub fn monitor(
        model: &Model,
        config: &ForceConfig,
        held_out: Option<&HeldOut>,
        rate_hz: f64,
        params: &[f64],
        effects: &[arash_core::effects::EffectTerm],
    ) -> Result<(Self, ForceMonitor), String> {
        let setup = Self::resolve(model, config, held_out, rate_hz).map_err(|e| format!("[force]: {e}"))?;
        let monitor = setup.build(model, params, effects).map_err(|e| format!("[force]: {e}"))?;
        Ok((setup, monitor))
    }

    /// The monitor on `model` with parameters `params` and `effects`.
    pub fn build(
        &self,
        model: &Model,
        params: &[f64],
        effects: &[arash_core::effects::EffectTerm],
    ) -> Result<ForceMonitor, String> {
        let epsilon = cycle_epsilon(model);
        let observer =
            MomentumObserver::new(model, params, effects, &self.bandwidth_hz, &epsilon, TorqueTiming::Preceding)
                .map_err(|e: ObserverError| e.to_string())?;
        let about = default_frame(model).and_then(|c| c.about).unwrap_or_else(|| model.frames[0].name.clone());
        let map = match &self.frame {
            Some(f) => Some(FrameForce::new(model, f, &about, 1e-3).map_err(|e| e.to_string())?),
            None => None,
        };
        let thresholds = match (&self.contact, &self.collision) {
            (Some(c), Some(k)) => Some(Thresholds::by_hand(c, k, model.dof()).map_err(|e| e.to_string())?),
            _ => None,
        };
        let sigma = self.sigma.clone().unwrap_or_else(|| vec![0.0; model.dof()]);
        Ok(ForceMonitor { observer, map, thresholds, sigma })
    }
}

/// The Coulomb width `ε` per joint of everything the cycle compensates by a model: online the
/// velocity is the estimator's, noisy at rest, so the controllers' width (the paper's, else the
/// default), widened to the model's own friction law where that is wider.
pub fn cycle_epsilon(model: &Model) -> Vec<f64> {
    let paper = RobustGains::paper(model).map(|g| g.epsilon);
    compensation_epsilon(model, &paper.unwrap_or_else(|_| model_epsilon(model)))
}

impl ForceMonitor {
    /// One telemetry frame `dt` after the last: the estimate into `r.tau_ext` (and the frame's
    /// force into `r.frame_force`), from `r.q`, `r.qd` and `r.tau_meas`. Returns the level, or
    /// None for a non-finite input, which leaves the estimate as it was.
    pub fn step(&mut self, dt: f64, r: &mut CycleRecord) -> Option<Level> {
        let estimate = self.observer.step(dt, &r.q, &r.qd, &r.tau_meas).ok()?;
        r.tau_ext.copy_from_slice(estimate);
        if let Some(map) = self.map.as_mut() {
            r.frame_force.copy_from_slice(&map.map(&r.q, estimate, &self.sigma).force);
        }
        Some(self.thresholds.as_ref().map_or(Level::Free, |t| t.level(estimate)))
    }

    /// Size the record's observer fields.
    pub fn prepare(&self, r: &mut CycleRecord) {
        r.tau_ext = vec![0.0; r.q.len()];
        if self.map.is_some() {
            r.frame_force = vec![0.0; 3];
        }
    }

    /// The model's compensation at the last sample (see [`MomentumObserver::compensation`]).
    pub fn compensation(&self, out: &mut [f64]) {
        self.observer.compensation(out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use arash_core::model_file::ObserverHeldOut;

    fn held_out(observer: bool) -> HeldOut {
        HeldOut {
            rms: vec![0.01, 0.02, 0.1],
            samples: 1000,
            cutoff_hz: 20.0,
            source: "validation".into(),
            observer: observer.then(|| ObserverHeldOut {
                bandwidth_hz: vec![20.0, 40.0, 80.0],
                sigma: vec![0.002, 0.003, 0.02],
                grid_hz: vec![20.0],
                grid_sigma: vec![0.002, 0.003, 0.02],
                reason: ForceChoice::Recorded { text: "test".into() },
                peak: vec![0.01, 0.05, 0.1],
            }),
        }
    }

    /// σ thresholds come only from the observer's own run, with its collision floor; a residual's
    /// RMS alone tells no contact, and says how to get one.
    #[test]
    fn thresholds_at_multiples_of_sigma_need_the_observers_held_out_run() {
        let model = arash_core::arash_asist();
        let config = ForceConfig::default();
        let residual = ForceSetup::resolve(&model, &config, Some(&held_out(false)), 1000.0).unwrap();
        assert_eq!((residual.contact.as_ref(), residual.collision.as_ref()), (None, None));
        let said = residual.reasons.iter().any(|r| matches!(r, ForceChoice::NoThresholdsResidualSigma));
        assert!(said, "{:?}", residual.reasons);
        let observed = ForceSetup::resolve(&model, &config, Some(&held_out(true)), 1000.0).unwrap();
        assert_eq!(observed.bandwidth_hz, vec![20.0, 40.0, 80.0]);
        let contact = observed.contact.unwrap();
        let collision = observed.collision.unwrap();
        for k in 0..3 {
            let sigma = [0.002, 0.003, 0.02][k];
            assert!((contact[k] - config.contact_sigmas * sigma).abs() < 1e-12, "{contact:?}");
            // Eight σ, or 1.5 times the held-out peak where that is higher (the pitch's 0.075).
            let floor = [0.01, 0.05, 0.1][k] * arash_core::force::settings::PEAK_MARGIN;
            let expected = (config.collision_sigmas * sigma).max(floor);
            assert!((collision[k] - expected).abs() < 1e-12, "{collision:?} against {expected}");
        }
    }
}
