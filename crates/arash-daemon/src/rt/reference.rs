//! The reference the control cycle follows: hold a position, approach the start of a
//! trajectory, play it for its duration, then hold its end. Switching never allocates; the
//! trajectory arrives already built, and leaves again to be dropped off the real-time thread.

use arash_core::control::Trajectory;

use crate::link::MAX_JOINTS;

/// A trajectory to play, prepared off the real-time thread.
pub struct RunRequest {
    pub id: u32,
    pub trajectory: Trajectory,
    pub duration_s: f64,
}

/// What the reference is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Phase {
    Hold,
    /// Moving on a quintic to the trajectory's start.
    Approach,
    Run,
}

/// A change worth logging.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhaseChange {
    RunStarted(u32),
    RunEnded(u32),
}

pub struct Reference {
    dof: usize,
    phase: Phase,
    hold: [f64; MAX_JOINTS],
    from: [f64; MAX_JOINTS],
    to: [f64; MAX_JOINTS],
    /// Per-joint speed for approaches (rad/s or m/s).
    approach_speed: [f64; MAX_JOINTS],
    approach_s: f64,
    t0: f64,
    run: Option<Box<RunRequest>>,
}

/// The quintic blend `s(τ) = 10τ³ − 15τ⁴ + 6τ⁵` and its derivatives; at rest at both ends.
fn quintic(tau: f64) -> (f64, f64, f64) {
    let t = tau.clamp(0.0, 1.0);
    let (t2, t3) = (t * t, t * t * t);
    (t3 * (10.0 - 15.0 * t + 6.0 * t2), 30.0 * t2 * (1.0 - t) * (1.0 - t), 60.0 * t * (1.0 - t) * (1.0 - 2.0 * t))
}

impl Reference {
    /// Holding `q`; approaches move at most at `approach_speed` per joint.
    pub fn new(q: &[f64], approach_speed: &[f64]) -> Self {
        let dof = q.len();
        assert!(dof <= MAX_JOINTS && approach_speed.len() == dof);
        let mut r = Self {
            dof,
            phase: Phase::Hold,
            hold: [0.0; MAX_JOINTS],
            from: [0.0; MAX_JOINTS],
            to: [0.0; MAX_JOINTS],
            approach_speed: [1.0; MAX_JOINTS],
            approach_s: 0.0,
            t0: 0.0,
            run: None,
        };
        r.approach_speed[..dof].copy_from_slice(approach_speed);
        r.hold_at(q);
        r
    }

    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The id of the run being approached or played.
    pub fn run_id(&self) -> Option<u32> {
        self.run.as_ref().map(|r| r.id).filter(|_| self.phase != Phase::Hold)
    }

    /// Hold `q` from now on; a run in progress is abandoned (and returned for dropping).
    pub fn hold_at(&mut self, q: &[f64]) -> Option<Box<RunRequest>> {
        self.hold[..self.dof].copy_from_slice(q);
        self.phase = Phase::Hold;
        self.run.take()
    }

    /// Start `run` at time `t` from the reference position `q_now`: approach its first point,
    /// then play it. Returns the run it replaces, if any.
    pub fn start(&mut self, t: f64, q_now: &[f64], run: Box<RunRequest>) -> Option<Box<RunRequest>> {
        let n = self.dof;
        let (mut qd, mut qdd) = ([0.0; MAX_JOINTS], [0.0; MAX_JOINTS]);
        run.trajectory.eval(0.0, &mut self.to[..n], &mut qd[..n], &mut qdd[..n]);
        self.from[..n].copy_from_slice(q_now);
        // The quintic peaks at 1.875 × the mean speed.
        self.approach_s =
            (0..n).map(|k| 1.875 * (self.to[k] - self.from[k]).abs() / self.approach_speed[k]).fold(1.0, f64::max);
        self.t0 = t;
        self.phase = Phase::Approach;
        self.run.replace(run)
    }

    /// The reference at `t`; reports the start and end of a run.
    pub fn eval(&mut self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) -> Option<PhaseChange> {
        let n = self.dof;
        let mut change = None;
        if self.phase == Phase::Approach && t - self.t0 >= self.approach_s {
            self.phase = Phase::Run;
            self.t0 += self.approach_s;
            change = self.run.as_ref().map(|r| PhaseChange::RunStarted(r.id));
        }
        if self.phase == Phase::Run {
            let run = self.run.as_ref().expect("a run is playing");
            if t - self.t0 >= run.duration_s {
                let (mut qd_end, mut qdd_end) = ([0.0; MAX_JOINTS], [0.0; MAX_JOINTS]);
                run.trajectory.eval(run.duration_s, &mut self.hold[..n], &mut qd_end[..n], &mut qdd_end[..n]);
                self.phase = Phase::Hold;
                change = Some(PhaseChange::RunEnded(run.id));
            }
        }
        match self.phase {
            Phase::Hold => {
                q.copy_from_slice(&self.hold[..n]);
                qd.fill(0.0);
                qdd.fill(0.0);
            }
            Phase::Approach => {
                let (s, ds, dds) = quintic((t - self.t0) / self.approach_s);
                let span = self.approach_s;
                for k in 0..n {
                    let delta = self.to[k] - self.from[k];
                    q[k] = self.from[k] + delta * s;
                    qd[k] = delta * ds / span;
                    qdd[k] = delta * dds / (span * span);
                }
            }
            Phase::Run => {
                self.run.as_ref().expect("a run is playing").trajectory.eval(t - self.t0, q, qd, qdd);
            }
        }
        change
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quintic_is_at_rest_at_both_ends_and_its_derivatives_are_consistent() {
        assert_eq!(quintic(0.0), (0.0, 0.0, 0.0));
        let (s1, ds1, dds1) = quintic(1.0);
        assert!((s1 - 1.0).abs() < 1e-15 && ds1.abs() < 1e-15 && dds1.abs() < 1e-12);
        let h = 1e-6;
        for &x in &[0.1, 0.37, 0.5, 0.8] {
            let fd = (quintic(x + h).0 - quintic(x - h).0) / (2.0 * h);
            let fdd = (quintic(x + h).1 - quintic(x - h).1) / (2.0 * h);
            assert!((fd - quintic(x).1).abs() < 1e-8 && (fdd - quintic(x).2).abs() < 1e-6);
        }
        assert!((quintic(0.5).1 - 1.875).abs() < 1e-12, "peak speed factor");
    }

    #[test]
    fn a_run_approaches_its_start_plays_and_holds_its_end() {
        let mut r = Reference::new(&[0.0, 0.0, 0.0], &[0.5, 0.5, 0.01]);
        let run =
            Box::new(RunRequest { id: 7, trajectory: Trajectory::PaperValidation { omega: 0.5 }, duration_s: 2.0 });
        let (mut q, mut qd, mut qdd) = ([0.0; 3], [0.0; 3], [0.0; 3]);
        let mut start = Trajectory::PaperValidation { omega: 0.5 };
        let (mut q0, mut v0, mut a0) = ([0.0; 3], [0.0; 3], [0.0; 3]);
        start.eval(0.0, &mut q0, &mut v0, &mut a0);
        assert!(r.start(0.0, &[0.0; 3], run).is_none());
        let approach = r.approach_s;
        let mut changes = Vec::new();
        let mut t = 0.0;
        while t < approach + 3.0 {
            if let Some(c) = r.eval(t, &mut q, &mut qd, &mut qdd) {
                changes.push((c, t));
            }
            let limit = [0.5, 0.5, 0.01];
            for k in 0..3 {
                if r.phase() == Phase::Approach {
                    assert!(qd[k].abs() <= limit[k] * 1.0000001, "approach speed {} at joint {k}", qd[k]);
                }
            }
            t += 1e-3;
        }
        assert_eq!(
            changes.iter().map(|c| c.0).collect::<Vec<_>>(),
            vec![PhaseChange::RunStarted(7), PhaseChange::RunEnded(7)]
        );
        start = Trajectory::PaperValidation { omega: 0.5 };
        start.eval(2.0, &mut q0, &mut v0, &mut a0);
        assert_eq!(q, q0, "holds the end of the run");
        assert_eq!(qd, [0.0; 3]);
    }
}
