//! Contact and collision told apart by thresholds on the external joint torque, set from the
//! model's own held-out residual (libfranka's two levels per joint, which it sets by hand).
//!
//! A joint's estimate carries the model's error as well as the hand's torque, so a threshold is
//! only as good as the σ it is a multiple of: the RMS of the model's residual on data it was not
//! fitted on (`ModelFile::held_out`). Chebyshev's inequality bounds the share of hand-free samples
//! over `k σ` by `1/k²` whatever the residual's distribution, which a model's residual (slow
//! misfit plus noise) is not Gaussian enough to be given:
//!
//! - contact at [`CONTACT_SIGMAS`] = 4σ: at most 1/16 of hand-free samples, and 6·10⁻⁵ of a
//!   Gaussian residual's;
//! - collision at [`COLLISION_SIGMAS`] = 8σ: at most 1/64 by Chebyshev, and twice the 4σ a
//!   Gaussian residual practically never passes, so a hand-free run does not stop.

/// The default contact threshold, in σ of the model's held-out residual.
pub const CONTACT_SIGMAS: f64 = 4.0;
/// The default collision threshold, in σ of the model's held-out residual.
pub const COLLISION_SIGMAS: f64 = 8.0;

/// Why thresholds could not be set.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ThresholdError {
    #[error("the {what} threshold has {got} entries; the robot has {dof} joints")]
    Length { what: &'static str, got: usize, dof: usize },
    #[error("the {what} threshold on joint {joint} is {value}; it must be positive and finite")]
    NotPositive { what: &'static str, joint: usize, value: f64 },
    #[error("the collision threshold on joint {joint} ({collision}) is below the contact threshold ({contact})")]
    Order { joint: usize, contact: f64, collision: f64 },
    #[error("σ on joint {joint} is {value}; thresholds need a positive, finite σ per joint")]
    Sigma { joint: usize, value: f64 },
    #[error("{0} must be positive and finite and the collision's at least the contact's")]
    Multiples(String),
}

/// What the estimate says at one sample, on the joint that says most.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    Free,
    Contact,
    Collision,
}

/// The contact and collision thresholds per joint (N·m or N), checked when set.
#[derive(Clone, Debug, PartialEq)]
pub struct Thresholds {
    contact: Vec<f64>,
    collision: Vec<f64>,
}

impl Thresholds {
    /// Thresholds at `contact_sigmas` and `collision_sigmas` times each joint's `sigma`.
    pub fn from_sigma(sigma: &[f64], contact_sigmas: f64, collision_sigmas: f64) -> Result<Self, ThresholdError> {
        if !(contact_sigmas.is_finite() && contact_sigmas > 0.0 && collision_sigmas.is_finite())
            || collision_sigmas < contact_sigmas
        {
            return Err(ThresholdError::Multiples(format!(
                "the multiples of σ (contact {contact_sigmas}, collision {collision_sigmas})"
            )));
        }
        if let Some((joint, &value)) = sigma.iter().enumerate().find(|(_, s)| !(s.is_finite() && **s > 0.0)) {
            return Err(ThresholdError::Sigma { joint, value });
        }
        let scaled = |k: f64| sigma.iter().map(|s| k * s).collect();
        Ok(Self { contact: scaled(contact_sigmas), collision: scaled(collision_sigmas) })
    }

    /// Raise each joint's collision threshold to at least `floor` (a held-out peak the hand-free
    /// estimate reached), and its contact threshold no further than that.
    pub fn with_collision_floor(mut self, floor: &[f64]) -> Self {
        for (c, f) in self.collision.iter_mut().zip(floor) {
            *c = c.max(*f);
        }
        self
    }

    /// Thresholds set by hand, per joint, for a robot of `dof` joints.
    pub fn by_hand(contact: &[f64], collision: &[f64], dof: usize) -> Result<Self, ThresholdError> {
        for (what, values) in [("contact", contact), ("collision", collision)] {
            if values.len() != dof {
                return Err(ThresholdError::Length { what, got: values.len(), dof });
            }
            if let Some((joint, &value)) = values.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v > 0.0)) {
                return Err(ThresholdError::NotPositive { what, joint, value });
            }
        }
        if let Some(joint) = (0..dof).find(|&k| collision[k] < contact[k]) {
            return Err(ThresholdError::Order { joint, contact: contact[joint], collision: collision[joint] });
        }
        Ok(Self { contact: contact.to_vec(), collision: collision.to_vec() })
    }

    pub fn contact(&self) -> &[f64] {
        &self.contact
    }

    pub fn collision(&self) -> &[f64] {
        &self.collision
    }

    /// The level of the external joint torque `estimate`: the highest any joint reaches.
    pub fn level(&self, estimate: &[f64]) -> Level {
        let over = |limits: &[f64]| estimate.iter().zip(limits).any(|(e, l)| e.abs() > *l);
        match (over(&self.collision), over(&self.contact)) {
            (true, _) => Level::Collision,
            (false, true) => Level::Contact,
            _ => Level::Free,
        }
    }
}

/// A run of samples at contact or above: `start..end` (sample indices, `end` exclusive) and the
/// highest level reached.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Episode {
    pub start: usize,
    pub end: usize,
    pub level: Level,
}

/// The episodes of a series of levels: each maximal run of samples that are not free.
pub fn episodes(levels: &[Level]) -> Vec<Episode> {
    let mut out: Vec<Episode> = Vec::new();
    let mut open: Option<Episode> = None;
    for (i, &level) in levels.iter().enumerate() {
        match (level, open.as_mut()) {
            (Level::Free, Some(_)) => out.extend(open.take().map(|e| Episode { end: i, ..e })),
            (Level::Free, None) => {}
            (_, Some(e)) => e.level = e.level.max(level),
            (_, None) => open = Some(Episode { start: i, end: i + 1, level }),
        }
    }
    out.extend(open.map(|e| Episode { end: levels.len(), ..e }));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_and_episodes() {
        let t = Thresholds::from_sigma(&[0.5, 2.0], CONTACT_SIGMAS, COLLISION_SIGMAS).unwrap();
        assert_eq!(t.contact(), &[2.0, 8.0]);
        assert_eq!(t.level(&[1.9, -7.9]), Level::Free);
        assert_eq!(t.level(&[0.0, -8.5]), Level::Contact);
        assert_eq!(t.level(&[-4.5, 0.0]), Level::Collision);
        use Level::*;
        let found = episodes(&[Free, Contact, Collision, Contact, Free, Free, Contact]);
        assert_eq!(
            found,
            vec![Episode { start: 1, end: 4, level: Collision }, Episode { start: 6, end: 7, level: Contact }]
        );
    }

    #[test]
    fn bad_thresholds_are_refused_by_name() {
        let e = Thresholds::by_hand(&[1.0, 1.0], &[2.0, 0.5], 2).unwrap_err();
        assert_eq!(e.to_string(), "the collision threshold on joint 1 (0.5) is below the contact threshold (1)");
        let e = Thresholds::by_hand(&[1.0, f64::NAN], &[2.0, 2.0], 2).unwrap_err();
        assert!(e.to_string().starts_with("the contact threshold on joint 1 is NaN"), "{e}");
        let e = Thresholds::from_sigma(&[0.1, 0.0], 4.0, 8.0).unwrap_err();
        assert!(e.to_string().starts_with("σ on joint 1 is 0"), "{e}");
        assert!(Thresholds::from_sigma(&[0.1], 8.0, 4.0).is_err());
    }
}
