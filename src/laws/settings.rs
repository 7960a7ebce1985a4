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
    /// the default 1e-4 keeps every docs/model.md reference case within 3e-5 um.
    pub tolerance: f64,
    /// Steps (accepted, rejected and events) allowed per scene period before
    /// the instance stops with
    /// [`STATUS_STEP_BUDGET`](crate::laws::status::STATUS_STEP_BUDGET).
    pub max_steps_per_period: u32,
    /// How many replicas a steady measurement that can be split runs as
    /// (`simulation.replicas`, whose default is `Auto`; `pidm::replicas`).
    /// `Settings::default()` runs every instance alone (`Count(1)`): the
    /// library's callers ask for replicas, a scene gets them unless it
    /// says otherwise.
    pub replicas: Replicas,
    /// Whether a run also measures the slider's backward travel
    /// (`output.backward`; `crate::laws::floor::variation`): the CPU in
    /// f64 keeps the slider's total variation beside the step. Off by
    /// default: a run that does not ask pays nothing.
    pub backward: bool,
}

/// Why a scene with `output.backward` runs in f64 only: what `--precision
/// f32` is refused with.
pub const BACKWARD_F64_ONLY: &str =
    "output.backward = true: the backward travel is measured in f64 only";

impl Default for Settings {
    fn default() -> Self {
        Settings {
            tolerance: 1e-4,
            max_steps_per_period: 2_000_000,
            replicas: Replicas::default(),
            backward: false,
        }
    }
}

/// `simulation.replicas`: how many replicas (`pidm::replicas`) each
/// steady measurement that can be split runs as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Replicas {
    /// As many as the backend's idle threads or lanes allow, up to
    /// `pidm::replicas::MAX_AUTO` (a scene's default).
    Auto,
    /// Exactly this many (1: none), whatever is idle.
    Count(u32),
}

impl Default for Replicas {
    /// One run per instance: the library's callers ask for replicas.
    fn default() -> Replicas {
        Replicas::Count(1)
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
///
/// A replica with a `cycle` q > 0 is instead one piece of a periodic
/// motion's common period (`pidm::replicas`, "cycle splits"): replica r
/// starts from rest at the drives' phases of period `start` of the
/// instance's own run ([`Replica::cycle_segment`]), settles as that run
/// does, and integrates the next `length` periods with no stop rule of its
/// own; its group joins the pieces end to start.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Replica {
    pub index: u32,
    pub count: u32,
    /// Which of the `count` virtual runs the replicas make (`turns` m =
    /// 0..count): the virtual run's faster drive advances by (rho + m) /
    /// count a period, whose `count` multiple is rho in the cycle as for
    /// every m, and replica r starts r (rho + m) / count cycles later. The
    /// host picks the m whose virtual run spaces its phases most evenly
    /// (`pidm::replicas::split`).
    pub turns: u32,
    /// The common period [scene periods] a cycle split cuts into `count`
    /// pieces, 0 for a phase split or a run of its own.
    pub cycle: u32,
}

impl Replica {
    /// A run of its own: the phase ladder judges its own windows.
    pub const NONE: Replica = Replica {
        index: 0,
        count: 1,
        turns: 0,
        cycle: 0,
    };

    /// The virtual run's advance of the faster drive per period [cycles]
    /// for a run whose own is `rho`: rho itself for a run of its own.
    pub fn virtual_step(&self, rho: f64) -> f64 {
        if self.count <= 1 {
            rho
        } else {
            (rho + self.turns as f64) / self.count as f64
        }
    }

    /// A cycle split's piece for this replica: the period of the
    /// instance's own measurement it starts at and the periods it measures
    /// [scene periods], `floor(index q / count)` up to the next replica's
    /// start, so that the pieces tile the common period q.
    pub fn cycle_segment(&self) -> (u32, u32) {
        let at = |index: u32| (index as u64 * self.cycle as u64 / self.count.max(1) as u64) as u32;
        let start = at(self.index);
        (start, at(self.index + 1) - start)
    }
}
