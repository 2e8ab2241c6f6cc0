//! A trainee at the simulated rig in the haptic mode (docs/haptics.md): the rig runs a law (the
//! haptic mode's, or any controller) while the scenario's grasp, a spring and damper to a
//! set-point on the trainee's intended path, moves it; what the trainee felt is read from the
//! plant's truth, never from the law:
//! - [`Effort`]: the hand's force per base axis, its moment about the remote centre, and what
//!   moving the bare device along the same path takes;
//! - [`WallPress`]: a press into the fixtures, the force the law rendered from the encoders
//!   against the ideal fixtures' at the true state, and the fixtures' energy over the press.

use super::plant::PlantError;
use super::rig::Rig;
use super::scenario::{Grasp, Hand, Scenario};
use crate::control::{Controller, Trajectory};
use crate::data::Data;
use crate::haptics::geometry::Geometry;
use crate::haptics::{check_passivity, DepthWall, FixtureError, FixtureRenderer, Fixtures, RenderError, RenderLoop};
use crate::kinematics::{forward_kinematics, frame_placement};
use crate::model::{Frame, Model, UnknownFrame};
use crate::record::{CycleRecord, TruthRecord};
use crate::spatial::Vec3;

/// What a trial failed on.
#[derive(Debug, thiserror::Error)]
pub enum TrialError {
    #[error(transparent)]
    Plant(#[from] PlantError),
    #[error(transparent)]
    Frame(#[from] UnknownFrame),
    #[error(transparent)]
    Fixture(#[from] FixtureError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("the rig latched {faults} at t = {t:.3} s with q = {q:?}")]
    Fault { faults: String, t: f64, q: Vec<f64> },
    #[error("the trial holds no sample after {from_s} s")]
    Empty { from_s: f64 },
}

/// One trial: the hand holds `grasp` at `frame` of the instrument held still at `start`, for
/// `seconds`.
#[derive(Clone, Debug)]
pub struct Trial {
    pub frame: String,
    pub grasp: Grasp,
    pub start: Vec<f64>,
    pub seconds: f64,
}

/// One control cycle: what the rig recorded and what was true.
#[derive(Clone, Debug)]
pub struct Cycle {
    pub record: CycleRecord,
    pub truth: TruthRecord,
}

/// Run `trial` on the rig of `scenario` (its own hand replaced by the trial's) under `law`. A
/// latched fault ends it with an error that names the fault and the state.
pub fn run(
    model: &Model,
    scenario: &Scenario,
    law: Box<dyn Controller>,
    trial: &Trial,
) -> Result<Vec<Cycle>, TrialError> {
    let hand = Hand { frame: trial.frame.clone(), grasp: Some(trial.grasp.clone()), ..Hand::default() };
    let scenario = Scenario { hand: Some(hand), ..scenario.clone() };
    let mut rig = Rig::new(model, &scenario, Trajectory::Hold { q: trial.start.clone() }, law)?;
    let cycles = (trial.seconds * scenario.physics.rate_hz).round() as usize;
    let mut out = Vec::with_capacity(cycles);
    for _ in 0..cycles {
        rig.step()?;
        let record = rig.record();
        if !record.faults.is_empty() {
            return Err(TrialError::Fault {
                faults: record.faults.names().join(", "),
                t: record.t,
                q: record.q.clone(),
            });
        }
        out.push(Cycle { record: record.clone(), truth: rig.truth().clone() });
    }
    Ok(out)
}

/// What the hand felt over a trial, from `from_s` on, per base axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Effort {
    /// The hand's RMS force at its frame (N).
    pub force_rms: [f64; 3],
    /// The RMS of its moment about the remote centre (N·m).
    pub moment_rms: [f64; 3],
    /// The same two for the bare device: the force at the frame whose joint torque is the
    /// motors' and the hand's together, what the hand alone must give to move the unpowered
    /// device along the path it followed.
    pub bare_force_rms: [f64; 3],
    pub bare_moment_rms: [f64; 3],
}

impl Effort {
    /// The effort at `frame` over `cycles` from `from_s` on, moments about `about`.
    pub fn of(model: &Model, (frame, about): (&str, &str), cycles: &[Cycle], from_s: f64) -> Result<Self, TrialError> {
        let kept: Vec<&Cycle> = cycles.iter().filter(|c| c.truth.t >= from_s).collect();
        if kept.is_empty() {
            return Err(TrialError::Empty { from_s });
        }
        let mut at = FrameAt::new(model, frame, about)?;
        let mut bare = crate::force::FrameForce::new(model, frame, about, 0.0)?;
        let scale = 1.0 / kept.len() as f64;
        let mut effort =
            Self { force_rms: [0.0; 3], moment_rms: [0.0; 3], bare_force_rms: [0.0; 3], bare_moment_rms: [0.0; 3] };
        let (mut total, no_sigma) = (vec![0.0; model.dof()], vec![0.0; model.dof()]);
        for c in kept {
            let truth = &c.truth;
            let lever = at.lever(&truth.q);
            let force = Vec3::from_column_slice(&truth.hand_force);
            let moment = lever.cross(&force);
            for (s, (m, h)) in total.iter_mut().zip(truth.tau_motor.iter().zip(&truth.tau_hand)) {
                *s = m + h;
            }
            let unpowered = bare.map(&truth.q, &total, &no_sigma);
            for a in 0..3 {
                effort.force_rms[a] += scale * force[a] * force[a];
                effort.moment_rms[a] += scale * moment[a] * moment[a];
                effort.bare_force_rms[a] += scale * unpowered.force[a].powi(2);
                effort.bare_moment_rms[a] += scale * unpowered.moment[a].powi(2);
            }
        }
        for rms in
            [&mut effort.force_rms, &mut effort.moment_rms, &mut effort.bare_force_rms, &mut effort.bare_moment_rms]
        {
            rms.iter_mut().for_each(|v| *v = v.sqrt());
        }
        Ok(effort)
    }
}

/// A frame's lever from a centre, base frame.
struct FrameAt {
    model: Model,
    data: Data,
    frame: Frame,
    about: Frame,
}

impl FrameAt {
    fn new(model: &Model, frame: &str, about: &str) -> Result<Self, UnknownFrame> {
        Ok(Self {
            model: model.clone(),
            data: Data::new(model),
            frame: model.frame(frame)?,
            about: model.frame(about)?,
        })
    }

    fn lever(&mut self, q: &[f64]) -> Vec3 {
        forward_kinematics(&self.model, &mut self.data, q);
        let (_, position) = frame_placement(&self.data, &self.frame);
        let (_, centre) = frame_placement(&self.data, &self.about);
        position - centre
    }
}

/// A press into fixtures, judged at the true state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallPress {
    /// Cycles in contact (a wall or cone engaged at the true state).
    pub contact_cycles: usize,
    /// The RMS, over the cycles in contact, of the rendered force minus the ideal one, over the
    /// ideal one's RMS.
    pub relative_error: f64,
    /// The largest ideal force (N) and the deepest penetration past the wall (m; from the energy
    /// `½ K x²` of a single wall).
    pub peak_force: f64,
    pub penetration_m: f64,
    /// The fixtures' energy at its highest up to `deepest_s` (the hand's deepest set-point), and
    /// its highest afterwards, while the hand withdraws (J): passive, the second never exceeds
    /// the first.
    pub energy_at_deepest: f64,
    pub energy_after: f64,
    /// Local maxima of the energy above 1 % of its peak while the hand withdraws: a wall that
    /// rings has many.
    pub ringing: usize,
}

impl WallPress {
    /// The press over `cycles` into `fixtures`, the hand's set-point deepest at `deepest_s`.
    pub fn of(model: &Model, fixtures: &Fixtures, cycles: &[Cycle], deepest_s: f64) -> Result<Self, TrialError> {
        let mut rendered = FixtureRenderer::new(model, fixtures)?;
        let mut ideal = FixtureRenderer::new(model, fixtures)?;
        let stiffness = fixtures.wall.iter().map(|w| w.stiffness).fold(0.0, f64::max);
        let mut scratch = vec![0.0; model.dof()];
        let (mut error, mut total, mut contact_cycles, mut peak_force) = (0.0, 0.0, 0, 0.0f64);
        let mut energy = Vec::with_capacity(cycles.len());
        for c in cycles {
            let from_encoders = rendered.add_torque(&c.record.q, &c.record.qd, &mut scratch)?;
            let at_truth = ideal.add_torque(&c.truth.q, &c.truth.qd, &mut scratch)?;
            energy.push((c.truth.t, at_truth.energy));
            if at_truth.contact {
                contact_cycles += 1;
                for a in 0..3 {
                    error += (from_encoders.force[a] - at_truth.force[a]).powi(2);
                    total += at_truth.force[a].powi(2);
                }
                peak_force = peak_force.max(at_truth.force.iter().map(|f| f * f).sum::<f64>().sqrt());
            }
        }
        let energy_at_deepest = energy.iter().filter(|(t, _)| *t <= deepest_s).map(|(_, e)| *e).fold(0.0, f64::max);
        let after: Vec<f64> = energy.iter().filter(|(t, _)| *t > deepest_s).map(|(_, e)| *e).collect();
        let energy_after = after.iter().copied().fold(0.0, f64::max);
        let peak = energy_at_deepest.max(energy_after);
        let ringing = after.windows(3).filter(|w| w[1] > w[0] && w[1] > w[2] && w[1] > 0.01 * peak).count();
        let penetration_m = if stiffness > 0.0 { (2.0 * peak / stiffness).sqrt() } else { 0.0 };
        let relative_error = if total > 0.0 { (error / total).sqrt() } else { f64::NAN };
        Ok(Self { contact_cycles, relative_error, peak_force, penetration_m, energy_at_deepest, energy_after, ringing })
    }
}

/// A depth wall `beyond_m` deeper than the tip is at `q`, its stiffness `share` of the stiffest
/// `looped` renders passively there (no damping of its own), and that bound (N/m).
pub fn wall_at_bound(
    model: &Model,
    q: &[f64],
    beyond_m: f64,
    looped: &RenderLoop,
    share: f64,
) -> Result<(Fixtures, f64), TrialError> {
    let mut geometry = Geometry::new(model, &Fixtures::default())?;
    geometry.at(q);
    let depth_m = geometry.depth(&mut vec![0.0; model.dof()]) + beyond_m;
    let wall =
        |stiffness: f64| Fixtures { wall: vec![DepthWall { depth_m, stiffness, damping: 0.0 }], ..Default::default() };
    let bound = check_passivity(model, &wall(1.0), looped)?.fixtures[0]
        .stiffness_bound
        .ok_or_else(|| FixtureError::Loop("a depth wall's passivity check gave no stiffness bound".into()))?;
    let fixtures = wall(share * bound);
    check_passivity(model, &fixtures, looped)?;
    Ok((fixtures, bound))
}
