//! The kind of motion a steady measurement found: the one home of the codes
//! the result files hold in `/maps/motion` (u8, with CF `flag_values` and
//! `flag_meanings`).
//!
//! Each code is decided from evidence the instance's run recorded
//! (`crate::measurement::reduce` sets it from the measurement's verdict):
//!
//! * *periodic*: the state repeated after a whole number of the drives'
//!   common periods (a lag was found); the step is exact;
//! * *quasi-periodic*: the phase-resolved estimate converged: the slider's
//!   increments over successive scene periods are a smooth function of
//!   the faster drive's phase (docs/model.md section 4; the estimator is
//!   `laws::floor::phase`). A periodic motion whose period is longer
//!   than the run needed to measure it counts here too;
//! * *irregular*: only the batch means (with the cumulative-sum floor)
//!   converged: the increments are neither periodic nor a smooth function
//!   of the phase (chaotic, or not yet on their attractor);
//! * *undetermined*: no verdict: a fixed window (which measures no kind of
//!   motion), a run that stopped "not steady" at `max_cycles`, or one that
//!   failed (its `status` says how);
//! * *multistable*: the replicas of a split measurement (`crate::replicas`),
//!   each started from rest at its own phase, disagreed beyond their
//!   standard errors: they settled on different attractors. The map keeps
//!   the instance's own run (unsplit, from rest at its own phase), whose
//!   status and standard error are its own.

/// What kind of motion an instance showed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Motion {
    /// No verdict: a window, "not steady", or a failed run.
    #[default]
    Undetermined = 0,
    /// The state repeated: a lag was found.
    Periodic = 1,
    /// The increments are a smooth function of the faster drive's phase.
    QuasiPeriodic = 2,
    /// Neither: only the batch means converged.
    Irregular = 3,
    /// Replicas from other phases settled on other attractors.
    Multistable = 4,
}

impl Motion {
    /// Every kind, in code order.
    pub const ALL: [Motion; 5] = [
        Motion::Undetermined,
        Motion::Periodic,
        Motion::QuasiPeriodic,
        Motion::Irregular,
        Motion::Multistable,
    ];

    /// The code stored in result files.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The kind of a stored code, if the code exists.
    pub fn from_code(code: u8) -> Option<Motion> {
        Motion::ALL.into_iter().find(|m| m.code() == code)
    }

    /// The CF flag meaning (one word, as `flag_meanings` lists them).
    pub fn name(self) -> &'static str {
        match self {
            Motion::Undetermined => "undetermined",
            Motion::Periodic => "periodic",
            Motion::QuasiPeriodic => "quasi_periodic",
            Motion::Irregular => "irregular",
            Motion::Multistable => "multistable",
        }
    }

    /// What the kind means, for people.
    pub fn meaning(self) -> &'static str {
        match self {
            Motion::Undetermined => {
                "undetermined (a fixed window, not steady, or failed: see status)"
            }
            Motion::Periodic => {
                "periodic (the state repeated after a whole number of common periods)"
            }
            Motion::QuasiPeriodic => {
                "quasi-periodic (the increments are a smooth function of the faster drive's phase)"
            }
            Motion::Irregular => {
                "irregular (neither periodic nor smooth in the phase: only the batch means converged)"
            }
            Motion::Multistable => {
                "multistable (replicas from other phases settled on other attractors: the \
                 instance's own run is kept)"
            }
        }
    }

    /// The CF `flag_values` attribute: every code in order.
    pub fn flag_values() -> Vec<u8> {
        Motion::ALL.iter().map(|m| m.code()).collect()
    }

    /// The CF `flag_meanings` attribute: the names, space separated, in
    /// code order.
    pub fn flag_meanings() -> String {
        Motion::ALL.map(Motion::name).join(" ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_dense_and_round_trip() {
        for (k, motion) in Motion::ALL.into_iter().enumerate() {
            assert_eq!(motion.code(), k as u8);
            assert_eq!(Motion::from_code(k as u8), Some(motion));
        }
        assert_eq!(Motion::from_code(Motion::ALL.len() as u8), None);
        assert_eq!(
            Motion::flag_meanings(),
            "undetermined periodic quasi_periodic irregular multistable"
        );
        assert_eq!(Motion::flag_values(), vec![0, 1, 2, 3, 4]);
    }
}
