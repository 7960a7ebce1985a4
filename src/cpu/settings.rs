//! The integrator's settings, shared by both precisions, and which
//! replica of a split run an integration is.

/// The one accuracy knob and the per-instance work limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Largest deviation, in radians, allowed between the friction direction
    /// and its quadratic model within one slip step. Only a turning friction
    /// direction (genuine 2-DOF slip) is affected; stick, 1-DOF slip and
    /// slip along a fixed direction are integrated exactly. Measured error in
    /// the step maps is about tolerance / 4 micrometres (`pidm accuracy`);
    /// the default 1e-4 keeps every MODEL.md reference case within 3e-5 um.
    pub tolerance: f64,
    /// Steps (accepted, rejected and events) allowed per scene period before
    /// the instance stops with
    /// [`STATUS_STEP_BUDGET`](crate::cpu::integrate::STATUS_STEP_BUDGET).
    pub max_steps_per_period: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            tolerance: 1e-4,
            max_steps_per_period: 2_000_000,
        }
    }
}

/// One replica of a run split into `count` replicas (`pidm::replicas`):
/// replica `index` is the instance with its faster drive's phase advanced
/// by `index rho / count` cycles, so that period k of replica r starts at
/// the phase of period `count k + r` of a virtual run whose faster drive
/// advances by `rho / count` a period. Each replica adds its slider
/// positions to the virtual run's windows with that run's trapezoid
/// weights (`phase::window_coefficient`), so the replicas' sums add up to the
/// virtual run's: `count` times the periods for the same chain length.
/// `{ index: 0, count: 1 }` ([`Replica::NONE`]) is a run of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Replica {
    pub index: u32,
    pub count: u32,
}

impl Replica {
    /// A run of its own: the phase ladder judges its own windows.
    pub const NONE: Replica = Replica { index: 0, count: 1 };
}
