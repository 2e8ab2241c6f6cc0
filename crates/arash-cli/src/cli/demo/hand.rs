//! The demo's chapter on the surgeon's hand: the force at the instrument tip estimated from the
//! calibrated model against the simulated hand's truth, with the CAD model, the identified model
//! and the identified model with the effects found (docs/force.md).
//!
//! The rig is the demo's scenario with the hand of `scenarios/hand.toml` added, run in process
//! (the same physics as the mock motor) under the robust controller on the model with effects,
//! following a trainee's slow motion with the instrument in the eye ([`surgical_motion`]). Each model's observer bandwidth and σ come from its own
//! hand-free held-out runs (`force_log::observer_held_out`), so that each is judged as a user
//! would run it. Three measurements per model:
//! - **estimation error**: the RMS of the estimated minus the applied tip force per base axis,
//!   over the RMS of the applied force, after the first second;
//! - **false alarms**: contact and collision episodes on the hand-free runs (the excitation and
//!   the validation runs);
//! - **detection**: steps of twice the collision-level force along each axis, and the delay from
//!   each step to the first sample the estimate reads a collision; and the detection floor, the
//!   contact threshold as a force per axis (`CONTACT_SIGMAS` × the estimate's σ on that axis).

use std::path::Path;

use anyhow::Context;
use arash_core::control::Trajectory;
use arash_core::force::{episodes, Level, CONTACT_SIGMAS};
use arash_core::force::{TorqueTiming, COLLISION_SIGMAS};
use arash_core::force_log::{
    default_frame, estimate_force, observer_held_out, ForceInput, ForceLog, ForceLogOptions, Source, ThresholdChoice,
};
use arash_core::identify::Log;
use arash_core::model_file::ModelFile;
use arash_core::record::{Columns, TruthColumns};
use arash_core::sim::scenario::{Hand, Step};
use arash_core::sim::{RunSpec, Scenario};
use arash_core::Model;

/// The hand the chapter's accuracy run applies (`arash simulate --scenario scenarios/hand.toml`
/// runs it on the nominal rig).
pub const HAND_SCENARIO: &str = include_str!("../../../../../scenarios/hand.toml");

/// Seconds at the start of a run left out: the observer and the controller settle.
const SETTLE_S: f64 = 1.0;
/// Seconds at the end left out: the zero-phase velocity filter's edge.
const EDGE_S: f64 = 0.3;

/// One model's figures.
pub struct HandRow {
    pub label: String,
    pub bandwidth_hz: Vec<f64>,
    /// The estimate's σ per joint (N·m or N).
    pub sigma: Vec<f64>,
    /// RMS error over RMS applied force, per instrument axis (across, across, along), against
    /// the force as applied.
    pub relative_error: [f64; 3],
    /// The same for the moment about the remote centre, per base axis.
    pub moment_error: [f64; 3],
    /// The same two for the zero-phase estimate (`arash force --zero-phase`): offline, without
    /// the causal observer's lag and in the hand's band.
    pub zero_phase_error: [f64; 3],
    pub zero_phase_moment_error: [f64; 3],
    /// The contact threshold as a force per base axis (N).
    pub floor: [f64; 3],
    /// Episodes on the hand-free runs, their length (s), and the share of their samples at
    /// contact or above (Chebyshev bounds it by 1/k₁² = 6.25 % at 4σ).
    pub false_contacts: usize,
    pub false_collisions: usize,
    pub hand_free_s: f64,
    pub contact_share: f64,
    /// Steps detected as a collision, of those applied, and the slowest detection (s).
    pub steps_detected: usize,
    pub steps: usize,
    pub slowest_detection_s: Option<f64>,
}

/// The chapter's outcome.
pub struct HandChapter {
    /// The applied force's RMS per instrument axis (N), and its moment's about the remote centre
    /// per base axis (N·m).
    pub applied_rms: [f64; 3],
    pub moment_rms: [f64; 3],
    pub rows: Vec<HandRow>,
}

/// Run the chapter: `models` are (label, model file); `hand_free` the runs no hand touched
/// (the excitation and the validation runs; those after the first are the held-out runs each
/// model's observer is calibrated on); `controller` the model the rig tracks with.
pub fn run(
    dir: &Path,
    model: &Model,
    rig_scenario: &Scenario,
    models: &[(&str, ModelFile)],
    hand_free: (&[(&str, Log<'_>)], TorqueTiming),
    controller: &ModelFile,
    omega: f64,
) -> anyhow::Result<HandChapter> {
    let (hand_free, logged) = hand_free;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let hand = Scenario::from_toml(HAND_SCENARIO)?.hand.context("scenarios/hand.toml has no [hand]")?;
    let period = std::f64::consts::TAU / omega;
    let (cycles, truth) = simulate(model, rig_scenario, &hand, controller, omega, 2.0 * period)?;
    let applied = Applied::of(model, &cycles, &truth)?;
    let applied_rms = rms_axes(&applied.local, &cycles.t);
    let moment_rms = rms_axes(&applied.moment, &cycles.t);
    let held_out = &hand_free[1.min(hand_free.len())..];
    let mut rows = Vec::new();
    for (label, file) in models {
        let observer =
            observer_held_out(model, file, held_out, logged).with_context(|| format!("{label}: the observer"))?;
        // The model file as a user's would read after `identify --validate`: the observer's
        // bandwidth, σ and peak on the held-out runs, which the defaults then take.
        let mut file = file.clone();
        let held_out = file.held_out.get_or_insert_with(|| arash_core::model_file::HeldOut {
            rms: observer.sigma.clone(),
            samples: 0,
            cutoff_hz: file.settings.cutoff_hz,
            source: "the validation runs".into(),
            observer: None,
        });
        held_out.observer = Some(observer);
        let tuned = ForceLogOptions {
            // In process, the rig records the current over the cycle that follows its sample.
            timing: TorqueTiming::Held,
            thresholds: ThresholdChoice::Sigma { contact: CONTACT_SIGMAS, collision: COLLISION_SIGMAS },
            ..Default::default()
        };
        let logged_options = ForceLogOptions { timing: logged, ..tuned.clone() };
        let accuracy = estimate(model, &file, &cycles, &tuned)?;
        let force_error = relative_error(&accuracy.local, &applied.local, &cycles.t, applied_rms);
        let moment_error = relative_error(&accuracy.moment, &applied.moment, &cycles.t, moment_rms);
        let floor = axis_floor(&accuracy);
        let smooth = estimate(model, &file, &cycles, &ForceLogOptions { zero_phase: true, ..tuned.clone() })?;
        let zero_phase_error = relative_error(&smooth.local, &applied.local, &cycles.t, applied_rms);
        let zero_phase_moment_error = relative_error(&smooth.moment, &applied.moment, &cycles.t, moment_rms);
        let (false_contacts, false_collisions, hand_free_s, contact_share) =
            false_alarms(model, &file, hand_free, &logged_options)?;
        let steps = step_hand(&floor);
        let (step_cycles, _) =
            simulate(model, rig_scenario, &steps, controller, omega, 1.0 + 0.6 * steps.step.len() as f64)?;
        let detection = estimate(model, &file, &step_cycles, &tuned)?;
        let delays = detection_delays(&detection, &steps, &step_cycles.t);
        write_series(&dir.join(format!("force_{}.csv", slug(label))), &cycles.t, &accuracy, &truth)?;
        rows.push(HandRow {
            label: label.to_string(),
            bandwidth_hz: accuracy.bandwidth_hz.clone(),
            sigma: accuracy.sigma_joint.clone(),
            relative_error: force_error,
            moment_error,
            zero_phase_error,
            zero_phase_moment_error,
            floor,
            false_contacts,
            false_collisions,
            hand_free_s,
            contact_share,
            steps_detected: delays.iter().flatten().count(),
            steps: delays.len(),
            slowest_detection_s: delays.iter().flatten().copied().reduce(f64::max),
        });
    }
    Ok(HandChapter { applied_rms, moment_rms, rows })
}

/// A trainee's motion with the instrument in the eye: one slow harmonic of period `2π/ω`, φ ± 15°,
/// ψ = 30° ± 20° and the tip 18 ± 6 mm past the remote centre; at most 7.5°/s, 10°/s and 3 mm/s
/// at ω = 0.5 rad/s, the pace of an instrument moved inside an eye. The pose matters: the yaw
/// axis is vertical through the remote centre, so a force across the instrument reaches it
/// through a lever of `d sin ψ` only (3 mm at ψ = 10°, 18 mm at 50°), and the pitch through `d`.
pub fn surgical_motion(omega: f64) -> Trajectory {
    let amplitude = [15f64.to_radians(), 20f64.to_radians(), 0.006];
    let excitation = arash_core::control::fourier::Excitation {
        harmonics: 1,
        period_s: std::f64::consts::TAU / omega,
        q0: vec![0.0, 30f64.to_radians(), 0.018],
        // q = q₀ + a/ω sin ωt − b/ω cos ωt
        a: vec![vec![amplitude[0] * omega], vec![0.0], vec![amplitude[2] * omega]],
        b: vec![vec![0.0], vec![-amplitude[1] * omega], vec![0.0]],
        condition_number: f64::NAN,
        condition_number_with_weak: f64::NAN,
    };
    Trajectory::Fourier(excitation)
}

/// A run of the demo's rig with `hand`, following [`surgical_motion`] for `duration_s`.
fn simulate(
    model: &Model,
    rig_scenario: &Scenario,
    hand: &Hand,
    controller: &ModelFile,
    omega: f64,
    duration_s: f64,
) -> anyhow::Result<(Columns, TruthColumns)> {
    let scenario = Scenario { hand: Some(hand.clone()), ..rig_scenario.clone() };
    let spec = RunSpec {
        scenario,
        trajectory: surgical_motion(omega),
        controller: arash_core::control::ControllerKind::Robust,
        params_source: "the identified model with the effects found".into(),
        params: controller.full_or_base_vector(),
        effects: controller.effects.clone(),
        // The daemon's default: the paper's gains, read in SI units.
        gains: Some(arash_core::control::RobustGains::from_paper(model, arash_core::control::gains::PaperUnits::Si)?),
        duration_s,
    };
    let mut rig = spec.rig(model)?;
    let (mut cycles, mut truth) = (Columns::default(), TruthColumns::default());
    for _ in 0..spec.cycles() {
        rig.step()?;
        cycles.push(rig.record());
        truth.push(rig.truth());
    }
    Ok((cycles, truth))
}

/// The applied force in the instrument's axes and its moment about the remote centre, from the
/// truth's force and joint positions.
struct Applied {
    local: Vec<f64>,
    moment: Vec<f64>,
}

impl Applied {
    fn of(model: &Model, cycles: &Columns, truth: &TruthColumns) -> anyhow::Result<Self> {
        let choice = default_frame(model).context("the robot names no instrument tip and remote centre")?;
        let tip = model.frame(&choice.frame)?;
        let centre = model.frame(choice.about.as_deref().unwrap_or_default())?;
        let n = model.dof();
        let mut data = arash_core::Data::new(model);
        let (mut local, mut moment) = (Vec::new(), Vec::new());
        for i in 0..cycles.t.len() {
            arash_core::kinematics::forward_kinematics(model, &mut data, &truth.q[i * n..(i + 1) * n]);
            let (rot, at) = arash_core::kinematics::frame_placement(&data, &tip);
            let (_, pivot) = arash_core::kinematics::frame_placement(&data, &centre);
            let f = arash_core::spatial::Vec3::from_column_slice(&truth.hand_force[3 * i..3 * i + 3]);
            local.extend((rot.transpose() * f).iter());
            moment.extend((at - pivot).cross(&f).iter());
        }
        Ok(Self { local, moment })
    }
}

/// The tip force from the recorded currents' torque, with the model's bandwidth, σ, thresholds
/// and timing in `tuned`.
fn estimate(model: &Model, file: &ModelFile, cycles: &Columns, tuned: &ForceLogOptions) -> anyhow::Result<ForceLog> {
    let options = ForceLogOptions { frame: default_frame(model), ..tuned.clone() };
    let input = ForceInput { t: &cycles.t, q: &cycles.q, qd: None, effort: &cycles.tau_meas };
    Ok(estimate_force(model, Source::File(file), input, &options)?)
}

/// Samples away from the run's edges: the controller and the observer settle at the start, and
/// the zero-phase velocity filter rings at both ends.
fn settled(t: &[f64]) -> impl Fn(&usize) -> bool + '_ {
    move |&i| t[i] - t[0] >= SETTLE_S && t[t.len() - 1] - t[i] >= EDGE_S
}

fn rms_axes(force: &[f64], t: &[f64]) -> [f64; 3] {
    let rows: Vec<usize> = (0..t.len()).filter(settled(t)).collect();
    std::array::from_fn(|a| (rows.iter().map(|&i| force[3 * i + a].powi(2)).sum::<f64>() / rows.len() as f64).sqrt())
}

fn relative_error(estimate: &[f64], truth: &[f64], t: &[f64], applied: [f64; 3]) -> [f64; 3] {
    let difference: Vec<f64> = estimate.iter().zip(truth).map(|(e, f)| e - f).collect();
    let error = rms_axes(&difference, t);
    std::array::from_fn(|a| error[a] / applied[a])
}

/// The contact threshold as a force per base axis: `CONTACT_SIGMAS` × the median σ of that
/// axis over the run.
fn axis_floor(estimate: &ForceLog) -> [f64; 3] {
    std::array::from_fn(|a| {
        let mut s: Vec<f64> = estimate.sigma.iter().skip(a).step_by(3).copied().collect();
        s.sort_by(f64::total_cmp);
        CONTACT_SIGMAS * s[s.len() / 2]
    })
}

/// Contact and collision episodes over the hand-free runs.
fn false_alarms(
    model: &Model,
    file: &ModelFile,
    runs: &[(&str, Log<'_>)],
    tuned: &ForceLogOptions,
) -> anyhow::Result<(usize, usize, f64, f64)> {
    let (mut contacts, mut collisions, mut seconds) = (0, 0, 0.0);
    let (mut touched, mut samples) = (0usize, 0usize);
    for (_, log) in runs {
        let input = ForceInput { t: log.t, q: log.q, qd: None, effort: log.tau };
        let out = estimate_force(model, Source::File(file), input, tuned)?;
        let start = log.t.iter().position(|t| t - log.t[0] >= SETTLE_S).unwrap_or(0);
        let end = log.t.iter().rposition(|t| log.t[log.t.len() - 1] - t >= EDGE_S).unwrap_or(log.t.len() - 1);
        for e in episodes(&out.levels[start..end.max(start)]) {
            match e.level {
                Level::Collision => collisions += 1,
                _ => contacts += 1,
            }
        }
        seconds += log.t[end.max(start)] - log.t[start];
        touched += out.levels[start..end.max(start)].iter().filter(|l| **l != Level::Free).count();
        samples += end.max(start) - start;
    }
    Ok((contacts, collisions, seconds, touched as f64 / samples.max(1) as f64))
}

/// Steps of twice the collision-level force (`COLLISION_SIGMAS / CONTACT_SIGMAS` × the floor)
/// along each base axis and against it, 0.3 s each, 0.3 s apart, from 1 s on.
fn step_hand(floor: &[f64; 3]) -> Hand {
    let mut step = Vec::new();
    for (i, (axis, sign)) in (0..3).flat_map(|a| [(a, 1.0), (a, -1.0)]).enumerate() {
        let mut force = [0.0; 3];
        force[axis] = sign * 2.0 * COLLISION_SIGMAS / CONTACT_SIGMAS * floor[axis];
        let at_s = 1.0 + 0.6 * i as f64;
        step.push(Step { at_s, end_s: Some(at_s + 0.3), force });
    }
    Hand { step, ..Hand::default() }
}

/// For each step, the delay from its start to the first sample read as a collision within it.
fn detection_delays(estimate: &ForceLog, hand: &Hand, t: &[f64]) -> Vec<Option<f64>> {
    hand.step
        .iter()
        .map(|s| {
            let end = s.end_s.unwrap_or(f64::INFINITY);
            (0..t.len())
                .filter(|&i| t[i] >= s.at_s && t[i] < end)
                .find(|&i| estimate.levels[i] == Level::Collision)
                .map(|i| t[i] - s.at_s)
        })
        .collect()
}

/// t, the applied force and the estimate (base frame), for the figure and for a reader.
fn write_series(path: &Path, t: &[f64], estimate: &ForceLog, truth: &TruthColumns) -> anyhow::Result<()> {
    let mut text = String::from("t,applied_x,applied_y,applied_z,estimate_x,estimate_y,estimate_z,level\n");
    for (i, time) in t.iter().enumerate() {
        let f = &truth.hand_force[3 * i..3 * i + 3];
        let e = &estimate.force[3 * i..3 * i + 3];
        let level = estimate.levels[i] as u8;
        text.push_str(&format!(
            "{time:.4},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{level}\n",
            f[0], f[1], f[2], e[0], e[1], e[2]
        ));
    }
    crate::report::write_atomically(path, &text)
}

pub(super) fn slug(label: &str) -> String {
    label.split(|c: char| !c.is_alphanumeric()).filter(|s| !s.is_empty()).collect::<Vec<_>>().join("_")
}

impl HandChapter {
    /// The table of the chapter, in Markdown.
    pub fn table(&self) -> String {
        let (f, m) = (self.applied_rms, self.moment_rms);
        let mut s = format!(
            "Applied force RMS across / across / along the instrument: {:.3} / {:.3} / {:.3} N; its moment about the \
             remote centre, base x / y / z: {:.4} / {:.4} / {:.4} N·m\n\n",
            f[0], f[1], f[2], m[0], m[1], m[2]
        );
        s.push_str(
            "| model | bandwidth (Hz) | σ per joint | force error across / across / along (% of applied RMS): causal; \
             zero-phase | moment error x / y / z (%): causal; zero-phase | detection floor x / y / z (N) | hand-free contacts / collisions (share of samples in contact) | steps detected \
             | slowest (ms) |\n|---|---|---|---|---|---|---|---|---|\n",
        );
        for r in &self.rows {
            let bw: Vec<String> = r.bandwidth_hz.iter().map(|b| format!("{b}")).collect();
            let sigma: Vec<String> = r.sigma.iter().map(|v| format!("{v:.4}")).collect();
            s.push_str(&format!(
                "| {} | {} | {} | {:.1} / {:.1} / {:.1}; {:.1} / {:.1} / {:.1} | {:.1} / {:.1} / {:.1}; {:.1} / {:.1} / {:.1} | {:.3} / {:.3} / {:.3} | {} / {} in {:.0} s ({:.1} %) | {} of {} | {} |\n",
                r.label,
                bw.join(", "),
                sigma.join(", "),
                100.0 * r.relative_error[0],
                100.0 * r.relative_error[1],
                100.0 * r.relative_error[2],
                100.0 * r.zero_phase_error[0],
                100.0 * r.zero_phase_error[1],
                100.0 * r.zero_phase_error[2],
                100.0 * r.moment_error[0],
                100.0 * r.moment_error[1],
                100.0 * r.moment_error[2],
                100.0 * r.zero_phase_moment_error[0],
                100.0 * r.zero_phase_moment_error[1],
                100.0 * r.zero_phase_moment_error[2],
                r.floor[0],
                r.floor[1],
                r.floor[2],
                r.false_contacts,
                r.false_collisions,
                r.hand_free_s,
                100.0 * r.contact_share,
                r.steps_detected,
                r.steps,
                r.slowest_detection_s.map_or("–".into(), |d| format!("{:.0}", 1e3 * d)),
            ));
        }
        s
    }
}
