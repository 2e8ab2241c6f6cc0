//! The diagnosis as text and JSON.

use super::findings::{Diagnosis, ErrorSummary, Finding, Reversion, StartedFrom};
use super::options::HARM_SIGMAS;
use crate::model::{CoulombLaws, CoulombShape};
use crate::model_file::Metrics;

impl Diagnosis {
    /// The declared model's Coulomb laws, from the settings (files before per-joint laws hold one
    /// width for every joint).
    fn friction_laws(&self) -> CoulombLaws {
        match self.settings.friction_velocities.is_empty() {
            true => {
                CoulombLaws::uniform(CoulombShape::of_epsilon(self.settings.coulomb_epsilon), self.joint_names.len())
            }
            false => CoulombLaws::of_velocities(&self.settings.friction_velocities)
                .unwrap_or_else(|_| CoulombLaws::undeclared(self.joint_names.len())),
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a diagnosis always serialises")
    }

    /// For an effect that, when added, helped some joints and harmed others on held-out data, the
    /// gain on each (the guard drops one that harms a joint beyond the comparison's noise).
    fn mixed_gains(&self, f: &Finding) -> String {
        let gains = &f.heldout_gain_per_joint;
        if !(gains.iter().any(|g| *g > 0.0) && gains.iter().any(|g| *g < 0.0)) {
            return String::new();
        }
        let each: Vec<String> = f
            .joints
            .iter()
            .filter_map(|&j| gains.get(j).map(|g| format!("{} {:+.1} %", self.joint_names[j], 100.0 * g)))
            .collect();
        format!("       held-out gain by joint when added (it helps some and harms others): {}\n", each.join(", "))
    }

    /// Joints by name, or "no joint".
    fn joint_list(&self, joints: &[usize]) -> String {
        match joints.is_empty() {
            true => "no joint".to_string(),
            false => joints.iter().map(|&j| self.joint_names[j].as_str()).collect::<Vec<_>>().join(", "),
        }
    }

    /// What the guard put back so that no joint predicts worse than the starting model.
    fn reverted_lines(&self) -> String {
        if self.reverted.is_empty() && self.still_worse.is_empty() {
            return String::new();
        }
        let mut s = "\nKept no worse than the starting model on held-out data, joint by joint:\n".to_string();
        for r in &self.reverted {
            let name = &self.joint_names[r.joint];
            let what = match &r.action {
                Reversion::HoldFriction => format!(
                    "{name}: its friction refitted here did not predict better by {HARM_SIGMAS} standard errors; \
                     held at the starting model's"
                ),
                Reversion::DropEffect { label, helped, sigmas } => {
                    let helped = self.joint_list(helped);
                    format!("{name}: {label} harmed it by {sigmas:.1} standard errors (it helped {helped}); dropped")
                }
                Reversion::Unshifted { samples, helped, sigmas } => {
                    let helped = self.joint_list(helped);
                    format!(
                        "{name}: the delay ({samples} samples) harmed it by {sigmas:.1} standard errors (it helped \
                         {helped}); its torque is not shifted"
                    )
                }
            };
            s += &format!(
                "  - {what} (held-out RMS {:.3e} → {:.3e}; the starting model's {:.3e})\n",
                r.rms_before, r.rms_after, r.start_rms
            );
        }
        for w in &self.still_worse {
            s += &format!(
                "  - {}: still worse than the starting model by {:.1} standard errors (held-out RMS {:.3e} against \
                 {:.3e}{}): no accepted effect causes it\n",
                self.joint_names[w.joint],
                w.sigmas,
                w.rms,
                w.start_rms,
                w.in_band()
            );
        }
        s
    }

    /// The report: what was found with its evidence, the errors before and after, and what was
    /// rejected (one line per effect and joint, its best variant's reason).
    pub fn report(&self) -> String {
        let mut s = format!(
            "Diagnosis of {} ({} candidates, test batches {}, α = {}, held-out: {}; Coulomb friction as {})\n\n",
            self.robot_name,
            self.settings.candidates,
            self.settings.batch_s.map_or("chosen from each test's scores".into(), |s| format!("of {s} s")),
            self.settings.alpha,
            self.settings.heldout,
            self.friction_laws()
        );
        s += "Choices made from the data, and why:\n";
        s += &self.settings.reasons.iter().map(|r| format!("  - {r}\n")).collect::<String>();
        s += &self.settings.warnings.iter().map(|w| format!("  warning: {w}\n")).collect::<String>();
        s += "\n";
        if self.accepted.is_empty() && self.too_heavy.is_some() {
            s += "No effect accepted: the model is heavier than the data (below).\n";
        } else if self.accepted.is_empty() {
            s += "No effect found beyond the declared model.\n";
        } else {
            s += "Effects found (in the order they were added):\n";
            for (i, f) in self.accepted.iter().enumerate() {
                s += &format!(
                    "  {}. {:<44} F({}, {}) = {:>9.1}  p = {:.1e} (≤ {:.1e})  held-out gain {:>5.1} %\n",
                    i + 1,
                    f.label,
                    f.term.coefficients.len(),
                    f.batches.saturating_sub(f.term.coefficients.len()),
                    f.statistic,
                    f.p_value,
                    f.threshold,
                    100.0 * f.heldout_gain
                );
                if let Some(r) = &f.refined {
                    s += &format!(
                        "       scale refined from the grid's {:.3e} within its neighbours {:.3e}–{:.3e}: {:.3} % more of \
                         the training residual explained\n",
                        r.grid,
                        r.bracket[0],
                        r.bracket[1],
                        100.0 * r.residual_drop
                    );
                }
                for ((name, c), sd) in f.term.columns.iter().zip(&f.term.coefficients).zip(&f.term.sigma) {
                    s += &format!("       {name:<24} {c:>12.4e} ± {sd:.1e}\n");
                }
                if let (Some(m), Some(b)) = (f.mass_kg, &f.body) {
                    s += &format!(
                        "       added mass on {b}: {:.1} ± {:.1} g",
                        1e3 * m,
                        1e3 * f.mass_sigma_kg.unwrap_or(0.0)
                    );
                    if let Some(g) = f.sigma_from_gains.first() {
                        s += &format!(" (± {:.1} g of it from the drive gains)", 1e3 * g);
                    }
                    if let Some(c) = f.centre_of_mass_m {
                        let mm = c.map(|x| x.map_or("–".to_string(), |x| format!("{:.1}", 1e3 * x)));
                        s += &format!(
                            ", centre of mass ({}, {}, {}) mm in its frame (–: not seen)",
                            mm[0], mm[1], mm[2]
                        );
                    }
                    s += "\n";
                }
                if !f.aliases.is_empty() {
                    s += &format!("       indistinguishable here from: {}\n", f.aliases.join(", "));
                }
                s += &self.mixed_gains(f);
            }
        }
        if let Some(h) = &self.too_heavy {
            s += &format!(
                "\nThe model is heavier than the data: on {}, {:.1} ± {:.1} g{} less mass explains the rest best \
                 (p = {:.1e}, held-out gain {:.1} %). A negative mass is no payload, and what an effect \
                 took up after it would be that weight, so the search stopped at round {}. Refit the model on \
                 this log (--refit), or take the mass out of the model.\n",
                h.body,
                1e3 * h.mass_kg,
                1e3 * h.mass_sigma_kg,
                h.mass_sigma_from_gains_kg
                    .map_or(String::new(), |g| format!(" (± {:.1} g of it from the drive gains)", 1e3 * g)),
                h.p_value,
                100.0 * h.heldout_gain,
                h.round
            );
        }
        s += &self.reverted_lines();
        s += &format!(
            "\nError per joint, before → after (before: {}; on the diagnosis's band, {:.2} Hz):\n",
            match self.settings.started_from {
                StartedFrom::Declared => "the declared model refitted",
                StartedFrom::Given => "the given model as it is",
                StartedFrom::Identified => "the model identified on this log, as it is",
            },
            self.settings.cutoff_hz
        );
        s += &self.error_table("training", &self.before, &self.after, |e| &e.training);
        s += &self.error_table("held-out", &self.before, &self.after, |e| &e.heldout);
        if !self.noise_floor.is_empty() {
            s += "  held-out floor, what no model of the motion removes (held-out gains are judged against the \
                  error above it, as far as that stands clear of it by its standard errors): the torque's noise \
                  in the band (read above a quarter of the sample rate), or what the band holds above the \
                  narrowest that predicts as well, if larger\n";
            for (k, name) in self.joint_names.iter().enumerate() {
                let noise = self.sensor_noise.get(k).copied().unwrap_or(f64::NAN);
                s += &format!("    {name:<22} RMS {:>10.3e}   (sensor noise {noise:.3e})\n", self.noise_floor[k]);
            }
        }
        s += &self.rejected_summary();
        s
    }

    fn error_table(
        &self,
        label: &str,
        before: &ErrorSummary,
        after: &ErrorSummary,
        pick: fn(&ErrorSummary) -> &Metrics,
    ) -> String {
        let (b, a) = (pick(before), pick(after));
        let mut s = format!("  {label}\n");
        for (k, name) in self.joint_names.iter().enumerate() {
            s += &format!(
                "    {name:<22} RMS {:>10.3e} → {:>10.3e}   FP% {:>6.2} → {:>6.2}   ‖e‖/‖τ‖ {:.4} → {:.4}\n",
                b.rms[k], a.rms[k], b.fp_percent[k], a.fp_percent[k], b.relative_error[k], a.relative_error[k]
            );
        }
        s
    }

    /// One line per (effect, joints): the reason of its most significant variant.
    fn rejected_summary(&self) -> String {
        let mut seen: Vec<(String, Vec<usize>)> = Vec::new();
        let mut s = String::from("\nNot added:\n");
        let mut sorted: Vec<_> = self.rejected.iter().collect();
        sorted.sort_by(|a, b| a.p_value.unwrap_or(1.0).total_cmp(&b.p_value.unwrap_or(1.0)));
        for r in sorted {
            let key = (r.name.clone(), r.joints.clone());
            if seen.contains(&key) {
                continue;
            }
            seen.push(key);
            s += &format!("  {:<44} {}\n", r.label, r.reason);
        }
        s
    }
}
