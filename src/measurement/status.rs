//! Instance status codes and what they mean: the one home of the codes the
//! result files hold in `/maps/status` and `/baseline/status`.
//!
//! The integrators set codes 0 to 4 (their values live in
//! `laws::karnopp::integrate::constants`, from which the shader's prelude is also
//! generated); the sweep sets 5 after `--verify`; the measurement's
//! reduction (`crate::measurement`) sets 6. Every non-zero status but 6
//! leaves 0 in the instance's map entries, never NaN; 6 ("not steady")
//! keeps the best estimate and its standard error. Code 7 (an f32 band
//! graze, `laws::status::STATUS_GRAZE`) never reaches a file:
//! every f32 path integrates such an instance again in f64
//! (`laws::karnopp::f32_needs_f64`), so it is no status here. Code 8 is the stall
//! search's own (`crate::stall`, `/maps/stall_status`): the step does not
//! change sign on the loaded side.

use crate::laws::status::{
    STATUS_EVENT_STORM, STATUS_NON_FINITE, STATUS_OK, STATUS_STEP_BUDGET, STATUS_STEP_UNDERFLOW,
};
use crate::laws::status::{STATUS_NOT_STEADY, STATUS_UNCONVERGED};

/// What became of one instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Status {
    /// The instance finished normally.
    Ok = STATUS_OK,
    /// The step budget (`simulation.max_steps_per_period`) ran out.
    StepBudget = STATUS_STEP_BUDGET,
    /// A non-finite number appeared in the state.
    NonFinite = STATUS_NON_FINITE,
    /// The slip step size fell below the time resolution of a period.
    StepUnderflow = STATUS_STEP_UNDERFLOW,
    /// Mode changes kept following each other without time advancing.
    EventStorm = STATUS_EVENT_STORM,
    /// `--verify` found a step that a 100 times tighter tolerance moved.
    Unconverged = STATUS_UNCONVERGED,
    /// A steady measurement ran to `simulation.max_cycles` without its
    /// motion repeating or its standard error falling within
    /// `simulation.step_tolerance`; the map keeps the best estimate.
    NotSteady = STATUS_NOT_STEADY,
    /// The stall search (`[stall]`, docs/model.md section 7) found no load
    /// below the kinetic friction that stops the axis: its step keeps the
    /// unloaded direction up to the largest load probed, so the actuator
    /// pushes any load the interface can hold. The stall-load map holds 0
    /// there, never a made-up number.
    NoStall = STATUS_NO_STALL,
}

/// The stall search's status of an instance whose step does not change
/// sign for |L| < f_c on the side against its unloaded step. 7 is the f32
/// band graze, which never reaches a file.
pub const STATUS_NO_STALL: u32 = 8;

impl Status {
    /// Every status, in code order.
    pub const ALL: [Status; 8] = [
        Status::Ok,
        Status::StepBudget,
        Status::NonFinite,
        Status::StepUnderflow,
        Status::EventStorm,
        Status::Unconverged,
        Status::NotSteady,
        Status::NoStall,
    ];

    /// The code stored in result files.
    pub fn code(self) -> u32 {
        self as u32
    }

    /// The status of a stored code, if the code exists.
    pub fn from_code(code: u32) -> Option<Status> {
        Status::ALL.into_iter().find(|s| s.code() == code)
    }

    /// What the status means, for people.
    pub fn meaning(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::StepBudget => "step budget exceeded (simulation.max_steps_per_period)",
            Status::NonFinite => "non-finite state",
            Status::StepUnderflow => {
                "step size underflow (a turn of the friction direction could not be resolved)"
            }
            Status::EventStorm => "event storm (mode changes without time advancing)",
            Status::Unconverged => {
                "unconverged (--verify: a 100 times tighter tolerance moved a step by more than \
                 0.001 um)"
            }
            Status::NotSteady => {
                "not steady (ran to simulation.max_cycles; the map keeps the best estimate and \
                 its standard error in step_*_se)"
            }
            Status::NoStall => {
                "no stall load ([stall] only: the step keeps its direction under every load \
                 against it below the kinetic friction that was probed; the actuator pushes any \
                 load it can hold)"
            }
        }
    }

    /// The meaning of a stored code, or a note that it does not exist.
    pub fn describe(code: u32) -> &'static str {
        Status::from_code(code).map_or("no such status", Status::meaning)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_dense_but_for_the_graze_and_round_trip() {
        use crate::laws::status::STATUS_GRAZE;
        let codes: Vec<u32> = Status::ALL.iter().map(|s| s.code()).collect();
        let dense: Vec<u32> = (0..=Status::ALL.len() as u32)
            .filter(|&c| c != STATUS_GRAZE)
            .collect();
        assert_eq!(codes, dense);
        for status in Status::ALL {
            assert_eq!(Status::from_code(status.code()), Some(status));
        }
        // The f32 graze never reaches a file: a stored 7 is refused.
        assert_eq!(Status::from_code(STATUS_GRAZE), None);
        assert_eq!(Status::from_code(STATUS_NO_STALL + 1), None);
        assert_eq!(Status::describe(99), "no such status");
    }

    #[test]
    fn the_output_docs_table_lists_every_status_with_its_meaning() {
        let readme = include_str!("../../docs/output.md");
        let section = readme
            .split("\n## Status codes\n")
            .nth(1)
            .expect("docs/output.md has a Status codes section");
        let section = section.split("\n## ").next().unwrap();
        let rows: Vec<(String, String)> = section
            .lines()
            .filter_map(|line| {
                let cols: Vec<&str> = line.trim().trim_matches('|').split('|').collect();
                let code = cols.first()?.trim();
                code.parse::<u32>().ok()?;
                Some((code.to_string(), cols.get(1)?.trim().to_string()))
            })
            .collect();
        let want: Vec<(String, String)> = Status::ALL
            .iter()
            .map(|s| (s.code().to_string(), s.meaning().to_string()))
            .collect();
        assert_eq!(rows, want);
    }
}
