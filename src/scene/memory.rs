//! The memory the output maps of a scene take, and the budget they must fit.

use super::format::human_bytes;
use super::{Layout, Scene, SceneError};

/// Default limit on the memory the output maps of one scene may take [bytes].
pub const MAP_MEMORY_BUDGET_BYTES: u64 = 8 << 30;

impl Scene {
    /// Output bytes per instance: the maps of the result-file schema, with
    /// the baselines', the stall maps and the backward maps when the scene
    /// asks for them.
    pub fn bytes_per_instance(&self) -> u64 {
        bytes_per_instance(self.baselines, self.stall.is_some(), self.settings.backward)
    }

    /// Refuses the scene when its output maps exceed `budget_bytes`.
    pub fn check_memory(&self, budget_bytes: u64) -> Result<(), SceneError> {
        let shape: Vec<u64> = self.shape().iter().map(|&n| n as u64).collect();
        let points = matches!(self.layout, Layout::Points { .. });
        check_memory(
            &shape,
            points,
            self.baselines,
            self.stall.is_some(),
            self.settings.backward,
            budget_bytes,
        )
    }
}

/// Output bytes per instance, as the result file's schema lays them out.
pub(super) fn bytes_per_instance(baselines: bool, stall: bool, backward: bool) -> u64 {
    crate::output::schema::bytes_per_instance(baselines, stall, backward)
}

/// Refuses a layout whose output maps exceed `budget`.
pub(super) fn check_memory(
    shape: &[u64],
    points: bool,
    baselines: bool,
    stall: bool,
    backward: bool,
    budget: u64,
) -> Result<(), SceneError> {
    let instances = shape
        .iter()
        .try_fold(1u128, |acc, &n| acc.checked_mul(n as u128))
        .unwrap_or(u128::MAX);
    let per = bytes_per_instance(baselines, stall, backward);
    if instances.saturating_mul(per as u128) > budget as u128 {
        return Err(SceneError::Memory {
            shape: shape.to_vec(),
            points,
            instances,
            bytes_per_instance: per,
            budget,
        });
    }
    Ok(())
}

/// The message of [`SceneError::Memory`].
pub(super) fn memory_message(
    shape: &[u64],
    points: bool,
    instances: u128,
    bytes_per_instance: u64,
    budget: u64,
) -> String {
    let layout = if points {
        format!("{instances} points")
    } else if shape.is_empty() {
        "a single instance".to_owned()
    } else {
        let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
        let count = if instances == u128::MAX {
            // The product overflowed: the count is only known to be huge.
            format!("more than {}", u128::MAX)
        } else {
            instances.to_string()
        };
        format!("grid {} = {count} instances", dims.join(" x "))
    };
    let bytes = instances.saturating_mul(bytes_per_instance as u128);
    let total = if bytes == u128::MAX {
        format!("more than {bytes} bytes")
    } else {
        format!("{bytes} bytes ({})", human_bytes(bytes as f64))
    };
    format!(
        "the output maps do not fit the memory budget: {layout} x {bytes_per_instance} bytes \
         per instance = {total}, over the budget of {budget} bytes ({}); use a coarser grid",
        human_bytes(budget as f64)
    )
}
