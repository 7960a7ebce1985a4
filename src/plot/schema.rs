//! The names of everything `pidm plot` reads from a result file, in one
//! place. The writers (`crate::output` for maps, axes and baselines,
//! `crate::trajectory` for trajectories) document the layout; these names
//! must agree with theirs.
//!
//! Paths are relative to the file's root; messages show them with a
//! leading '/'.

/// The group of the maps; a file without it is no result file.
pub(super) const MAPS: &str = "maps";
/// The 2-DOF step per axis [m per own drive cycle], shaped like the grid.
pub(super) const STEP: [&str; 2] = ["maps/step_x", "maps/step_y"];
/// The integrator status per instance (0 = ok), shaped like the grid.
pub(super) const STATUS: &str = "maps/status";

/// The optional group of the 1-DOF runs beside the maps.
pub(super) const BASELINE: &str = "baseline";
/// The 1-DOF step per axis, shaped like the grid.
pub(super) const BASELINE_STEP: [&str; 2] = ["baseline/step_x", "baseline/step_y"];
/// The worse status of the two 1-DOF runs, shaped like the grid.
pub(super) const BASELINE_STATUS: &str = "baseline/status";

/// The group of the grid axes, one 1-D dataset per axis key.
pub(super) const AXES: &str = "axes";
/// The attribute of an axis dataset that holds its unit.
pub(super) const UNITS: &str = "units";
/// The point labels of a points scene, one per instance.
pub(super) const LABELS: &str = "labels";

/// Root attribute: the scene's name.
pub(super) const NAME: &str = "name";
/// Root attribute: the scene's TOML text, which gives the grid order.
pub(super) const SCENE: &str = "scene";
/// Root attribute present only in a shard file.
pub(super) const SHARD_INDEX: &str = "shard_index";

/// The optional group of the stored trajectories, `<k>/` for k = 0, 1, ...
pub(super) const TRAJECTORIES: &str = "trajectories";
/// Sample times [s] of a run group.
pub(super) const TIME: &str = "time";
/// Stage and slider displacement per axis [m] of a trajectory group.
pub(super) const STAGE: [&str; 2] = ["stage_x", "stage_y"];
pub(super) const SLIDER: [&str; 2] = ["slider_x", "slider_y"];
/// The 1-DOF run subgroups of a trajectory, x driven alone and y alone.
pub(super) const BASELINE_RUN: [&str; 2] = ["baseline_x", "baseline_y"];
/// Stage and slider displacement along the driven axis [m] of a 1-DOF run.
pub(super) const BASELINE_STAGE: &str = "stage";
pub(super) const BASELINE_SLIDER: &str = "slider";

/// Text attributes of a trajectory group.
pub(super) const POINT: &str = "point";
pub(super) const LABEL: &str = "label";
/// Integer attributes of a run group.
pub(super) const INDEX: &str = "index";
pub(super) const RUN_STATUS: &str = "status";
pub(super) const MEASURED_CYCLES: &str = "measured_cycles";
/// Number attributes of a run group [s].
pub(super) const PERIOD_S: &str = "period_s";
pub(super) const SETTLE_S: &str = "settle_s";
pub(super) const DURATION_S: &str = "duration_s";
/// Per-axis drive attributes of a run group, suffixed `_x` and `_y`.
pub(super) const VOLTAGE: &str = "voltage";
pub(super) const FREQUENCY: &str = "frequency";
pub(super) const DUTY: &str = "duty";
pub(super) const PHASE: &str = "phase";
