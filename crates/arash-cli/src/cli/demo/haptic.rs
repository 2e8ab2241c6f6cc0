//! The demo's chapter on the haptic mode (docs/haptics.md): a simulated trainee moves the
//! instrument on the demo's rig, undeclared effects included, under the daemon's haptic law
//! built as the daemon builds it (`HapticMode::build` with the default `[haptic]`):
//! - **transparency**: the hand's force and its moment about the remote centre, per base axis,
//!   along a slow path in free space, with the CAD model, the identified model and the
//!   identified model with the effects found; and the bare device's, the force that moves the
//!   unpowered device along the same path;
//! - **rendering**: a press into a depth wall at the stiffest the mode accepts on the model with
//!   the effects, the rendered force against the ideal wall's at the true state, the penetration
//!   and the wall's energy; and a wall just above the bound, which the mode refuses.
//!
//! The runs are in process, on the same physics the mock motor serves (`arash_core::sim`).

use std::path::Path;

use anyhow::Context;
use arash_core::haptics::Fixtures;
use arash_core::model_file::ModelFile;
use arash_core::sim::scenario::{Grasp, PathPress};
use arash_core::sim::trainee::{self, Cycle, Effort, Trial, WallPress};
use arash_core::sim::Scenario;
use arash_core::Model;
use arash_daemon::rt::haptic::{HapticConfig, HapticMode};

/// The instrument at rest in the eye when the trainee takes hold: the yaw a little aside, the
/// pitch at 17°, the tip 15 mm past the remote centre.
const START: [f64; 3] = [0.1, 0.3, 0.015];
/// The frame the trainee holds for the transparency run: the insertion carriage's origin, 8 cm
/// up the instrument from its tip, where a hand holds it above the eye.
const GRASPED_AT: &str = "insertion_carriage";
/// Seconds of each transparency run, and the first ones left out (the path's amplitude rises
/// over one period).
const TRANSPARENCY_S: f64 = 15.0;
const SETTLE_S: f64 = 3.0;
/// The wall this far deeper than the tip at the start; the trainee's set-point presses
/// `PRESS_DEPTH_M` deeper and back over `PRESS_S`, from 1 s on.
const WALL_BEYOND_M: f64 = 0.002;
const PRESS_DEPTH_M: f64 = 0.006;
const PRESS_S: f64 = 4.0;
/// The share of the passivity bound the pressed wall takes, and the one the refused wall does.
const ACCEPTED_SHARE: f64 = 0.999;
const REFUSED_SHARE: f64 = 1.01;

/// One compensation's transparency.
pub struct Row {
    pub label: String,
    pub effort: Effort,
}

/// The wall: its stiffness (N/m), the passivity bound (N/m), the press, and the message refusing
/// a wall over the bound.
pub struct Rendering {
    pub stiffness: f64,
    pub bound: f64,
    pub press: WallPress,
    pub refusal: String,
}

/// The chapter's outcome.
pub struct HapticChapter {
    /// The trainee's intended path: its peak speed per axis of the held frame (m/s).
    pub path_speed: [f64; 3],
    /// The bare device along the path the best compensation let the hand follow.
    pub bare: Effort,
    pub rows: Vec<Row>,
    pub rendering: Rendering,
}

/// Run the chapter on the rig of `rig_scenario` with `models` (label, file), the last the one the
/// wall is rendered on; write the series of each run into `dir`.
pub fn run(
    dir: &Path,
    model: &Model,
    rig_scenario: &Scenario,
    models: &[(&str, ModelFile)],
) -> anyhow::Result<HapticChapter> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let grasp = transparency_grasp();
    let (rows, bare) = transparency(dir, model, rig_scenario, models, &grasp)?;
    let (label, file) = models.last().context("the haptic chapter needs a model")?;
    let rendering = rendering(dir, model, rig_scenario, (label, file)).with_context(|| format!("{label}: the wall"))?;
    let path_speed = std::array::from_fn(|a| grasp.amplitude_m[a] * std::f64::consts::TAU / grasp.period_s[a]);
    Ok(HapticChapter { path_speed, bare, rows, rendering })
}

/// The trainee follows `grasp` in free space with each model's compensation: a row per model,
/// and the bare device along the path the last one let the hand follow.
fn transparency(
    dir: &Path,
    model: &Model,
    rig_scenario: &Scenario,
    models: &[(&str, ModelFile)],
    grasp: &Grasp,
) -> anyhow::Result<(Vec<Row>, Effort)> {
    let dt = 1.0 / rig_scenario.physics.rate_hz;
    let mut rows = Vec::new();
    let mut last = Vec::new();
    for (label, file) in models {
        let mode = mode(model, file, &Fixtures::default(), dt).with_context(|| format!("{label}: the haptic mode"))?;
        let trial =
            Trial { frame: GRASPED_AT.into(), grasp: grasp.clone(), start: START.to_vec(), seconds: TRANSPARENCY_S };
        last = trainee::run(model, rig_scenario, Box::new(mode.into_law()), &trial)
            .with_context(|| format!("{label}: the transparency run"))?;
        let effort = Effort::of(model, (GRASPED_AT, "remote_centre"), &last, SETTLE_S)?;
        write_series(&dir.join(format!("transparency_{}.csv", super::hand::slug(label))), &last)?;
        rows.push(Row { label: label.to_string(), effort });
    }
    let bare = Effort::of(model, (GRASPED_AT, "remote_centre"), &last, SETTLE_S)?;
    Ok((rows, bare))
}

/// The stiffest wall the mode accepts on `file`, pressed by the trainee, and one over its bound,
/// refused.
fn rendering(
    dir: &Path,
    model: &Model,
    rig_scenario: &Scenario,
    (label, file): (&str, &ModelFile),
) -> anyhow::Result<Rendering> {
    let dt = 1.0 / rig_scenario.physics.rate_hz;
    let looped = HapticConfig::default().render_loop(model, &params(model, file)?, dt).map_err(anyhow::Error::msg)?;
    let (wall, bound) = trainee::wall_at_bound(model, &START, WALL_BEYOND_M, &looped, ACCEPTED_SHARE)?;
    let mut over = wall.clone();
    over.wall[0].stiffness = REFUSED_SHARE * bound;
    let refusal = match mode(model, file, &over, dt) {
        Ok(_) => anyhow::bail!("{label}: a wall at {REFUSED_SHARE} × the passivity bound was accepted"),
        Err(e) => format!("{e:#}"),
    };
    let press = Grasp {
        at_s: 0.5,
        press: vec![PathPress { at_s: 1.0, duration_s: PRESS_S, depth_m: PRESS_DEPTH_M }],
        ..Grasp::default()
    };
    let trial = Trial { frame: "instrument_tip".into(), grasp: press, start: START.to_vec(), seconds: 2.0 + PRESS_S };
    let law = mode(model, file, &wall, dt)?.into_law();
    let pressed = trainee::run(model, rig_scenario, Box::new(law), &trial).context("the press")?;
    write_series(&dir.join("press.csv"), &pressed)?;
    let press = WallPress::of(model, &wall, &pressed, 1.0 + 0.5 * PRESS_S)?;
    Ok(Rendering { stiffness: wall.wall[0].stiffness, bound, press, refusal })
}

/// The trainee's path in free space: held at the carriage, 4 mm across the instrument in the
/// sagittal plane (the pitch's way) at a 7 s period and 3 mm along it at 6 s, at most 3.6 and
/// 3.1 mm/s: a slow, tremor-free motion of an instrument in an eye. Sideways the handle moves the
/// yaw through a lever of a fifth of its height at this pitch, where a relaxed grasp's force does
/// not unstick the yaw's friction at all (docs/haptics.md, "What the trainee feels").
fn transparency_grasp() -> Grasp {
    Grasp { amplitude_m: [0.0, 0.004, 0.003], period_s: [5.0, 7.0, 6.0], ..Grasp::default() }
}

/// The parameters the daemon takes from `file` for a model-based law.
fn params(model: &Model, file: &ModelFile) -> anyhow::Result<Vec<f64>> {
    Ok(file.consistent_controller_parameters(model)?)
}

/// The daemon's haptic mode on `file` rendering `fixtures`, with the default `[haptic]`.
fn mode(model: &Model, file: &ModelFile, fixtures: &Fixtures, dt: f64) -> anyhow::Result<HapticMode> {
    let params = params(model, file)?;
    HapticMode::build(model, (&params, &file.effects), &HapticConfig::default(), fixtures, dt)
        .map_err(anyhow::Error::msg)
}

/// t, the true q and the hand's force (base frame), for the figures and a reader.
fn write_series(path: &Path, cycles: &[Cycle]) -> anyhow::Result<()> {
    let mut text = String::from("t,q1,q2,q3,hand_x,hand_y,hand_z\n");
    for c in cycles {
        let (q, f) = (&c.truth.q, &c.truth.hand_force);
        text.push_str(&format!(
            "{:.4},{:.6},{:.6},{:.7},{:.5},{:.5},{:.5}\n",
            c.truth.t, q[0], q[1], q[2], f[0], f[1], f[2]
        ));
    }
    crate::report::write_atomically(path, &text)
}

impl HapticChapter {
    /// The chapter's figures for a reader's scripts (SI units).
    pub fn json(&self) -> serde_json::Value {
        let effort = |label: &str, force: [f64; 3], moment: [f64; 3]| serde_json::json!({ "compensation": label, "force_rms": force, "moment_rms": moment });
        let mut transparency = vec![effort("none", self.bare.bare_force_rms, self.bare.bare_moment_rms)];
        transparency.extend(self.rows.iter().map(|r| effort(&r.label, r.effort.force_rms, r.effort.moment_rms)));
        let r = &self.rendering;
        let p = &r.press;
        serde_json::json!({
            "path_peak_speed": self.path_speed,
            "transparency": transparency,
            "wall": {
                "stiffness": r.stiffness,
                "passivity_bound": r.bound,
                "contact_cycles": p.contact_cycles,
                "relative_error": p.relative_error,
                "peak_force": p.peak_force,
                "penetration": p.penetration_m,
                "energy_at_deepest": p.energy_at_deepest,
                "energy_after": p.energy_after,
                "ringing": p.ringing,
                "refused_over_bound": r.refusal,
            },
        })
    }

    /// The chapter's tables, in Markdown.
    pub fn table(&self) -> String {
        let v = self.path_speed.map(|s| 1e3 * s);
        let mut s = format!(
            "Transparency: the trainee holds the instrument at the carriage and follows a slow sagittal path (at \
             most {:.1} / {:.1} / {:.1} mm/s across / across / along the instrument); the hand's force and its moment \
             per base axis, RMS after {SETTLE_S} s of {TRANSPARENCY_S} s.\n\n\
             | compensation | hand force x / y / z (N) | total (N) | moment about the remote centre x / y / z (mN·m) \
             | force against CAD |\n|---|---|---|---|---|\n",
            v[0], v[1], v[2]
        );
        let cad = self.rows.first().map_or(f64::NAN, |r| norm(r.effort.force_rms));
        let line = |label: &str, force: [f64; 3], moment: [f64; 3]| {
            format!(
                "| {label} | {:.3} / {:.3} / {:.3} | {:.3} | {:.2} / {:.2} / {:.2} | {:.2}× |\n",
                force[0],
                force[1],
                force[2],
                norm(force),
                1e3 * moment[0],
                1e3 * moment[1],
                1e3 * moment[2],
                cad / norm(force)
            )
        };
        s.push_str(&line("none (the bare device)", self.bare.bare_force_rms, self.bare.bare_moment_rms));
        for r in &self.rows {
            s.push_str(&line(&r.label, r.effort.force_rms, r.effort.moment_rms));
        }
        let r = &self.rendering;
        let p = &r.press;
        s.push_str(&format!(
            "\nRendering: a depth wall at {:.0} N/m ({ACCEPTED_SHARE} of the passivity bound {:.0} N/m), the set-point \
             pressed {:.0} mm past it and back over {PRESS_S} s: in contact for {} ms, the rendered force within {:.2} % \
             RMS of the ideal wall's at the true state, at most {:.2} N and {:.2} mm deep; the wall's energy after the \
             deepest set-point {:.3} mJ against {:.3} mJ at it, {} local maxima while the hand withdrew.\n\nA wall at \
             {REFUSED_SHARE} of the bound is refused: {}\n",
            r.stiffness,
            r.bound,
            1e3 * (PRESS_DEPTH_M - WALL_BEYOND_M),
            p.contact_cycles,
            100.0 * p.relative_error,
            p.peak_force,
            1e3 * p.penetration_m,
            1e3 * p.energy_after,
            1e3 * p.energy_at_deepest,
            p.ringing,
            r.refusal
        ));
        s
    }
}

fn norm(v: [f64; 3]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}
