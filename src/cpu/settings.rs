//! The integrator's settings, shared by both precisions.

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
