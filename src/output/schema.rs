//! The result-file schema: the one home of the names, types and shapes
//! that the writers (`crate::output` for maps, axes and baselines,
//! `crate::trajectory` for trajectories), the readers (`pidm plot`,
//! `pidm merge`) and the memory estimate of a scene share. The layout
//! itself is described in `crate::output`'s module docs.
//!
//! Paths are relative to the file's root; messages show them with a
//! leading '/'.

/// One map dataset: shaped like the grid (1-D over the shard's instances
/// in a shard file), one entry per instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MapDataset {
    /// Its name inside its group.
    pub name: &'static str,
    /// The `units` attribute.
    pub units: &'static str,
    /// The `long_name` attribute.
    pub long_name: &'static str,
    /// The type of its entries.
    pub ty: MapType,
}

/// The element type of a map dataset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapType {
    /// Values with units (steps, velocities, standard errors).
    F64,
    /// Codes and counts (status, steps, periods).
    U32,
    /// Small codes (the kind of motion, [`crate::model::motion::Motion`]).
    U8,
}

impl MapType {
    /// Bytes one entry takes.
    pub const fn bytes(self) -> u64 {
        match self {
            MapType::F64 => 8,
            MapType::U32 => 4,
            MapType::U8 => 1,
        }
    }
}

impl MapDataset {
    /// Bytes one entry takes.
    pub const fn bytes(&self) -> u64 {
        self.ty.bytes()
    }
}

use MapType::{F64, U8, U32};

/// The datasets under [`MAPS`], in the order `Record` fields are written.
pub const MAP_DATASETS: [MapDataset; 12] = [
    map("step_x", "m", "slider step along x per x drive cycle", F64),
    map("step_y", "m", "slider step along y per y drive cycle", F64),
    map("velocity_x", "m/s", "mean slider velocity along x", F64),
    map("velocity_y", "m/s", "mean slider velocity along y", F64),
    map("status", "1", "integrator status code (0 = ok)", U32),
    map("steps", "1", "integrator steps taken", U32),
    map(
        "step_x_se",
        "m",
        "standard error of step_x (0 when periodic or a fixed window)",
        F64,
    ),
    map(
        "step_y_se",
        "m",
        "standard error of step_y (0 when periodic or a fixed window)",
        F64,
    ),
    map(
        "periods",
        "1",
        "scene periods integrated, settle included",
        U32,
    ),
    map(
        "period_lag",
        "1",
        "scene periods of the detected cycle (0 when none)",
        U32,
    ),
    map(
        MOTION_NAME,
        "1",
        "kind of motion the steady measurement found (flag_meanings)",
        U8,
    ),
    map(
        "replicas",
        "1",
        "replicas whose merged estimate the values are (1: one run; 0: not integrated)",
        U32,
    ),
];

/// The datasets under [`BASELINE`] when a scene asks for baselines.
pub const BASELINE_DATASETS: [MapDataset; 3] = [
    map(
        "step_x",
        "m",
        "1-DOF step along x with the y drive off",
        F64,
    ),
    map(
        "step_y",
        "m",
        "1-DOF step along y with the x drive off",
        F64,
    ),
    map(
        "status",
        "1",
        "integrator status code of the baselines (0 = ok)",
        U32,
    ),
];

/// The backward-travel maps of one axis (`[output] backward`).
macro_rules! backward_maps {
    ($a:literal) => {
        [
            map(
                concat!("backward_", $a),
                "m",
                concat!(
                    "slider travel against the step along ",
                    $a,
                    " per ",
                    $a,
                    " drive cycle: (total variation - |net travel|) / 2"
                ),
                F64,
            ),
            map(
                concat!("backward_", $a, "_se"),
                "m",
                concat!("standard error of backward_", $a),
                F64,
            ),
            map(
                concat!("backward_ratio_", $a),
                "1",
                concat!(
                    "backward_",
                    $a,
                    " / (|step_",
                    $a,
                    "| + backward_",
                    $a,
                    "), 0 where both are 0"
                ),
                F64,
            ),
            map(
                concat!("backward_ratio_", $a, "_se"),
                "1",
                concat!("standard error of backward_ratio_", $a),
                F64,
            ),
        ]
    };
}

/// The datasets under [`MAPS`] of a scene with `[output] backward = true`,
/// per axis (x, y), in the order of `crate::sweep::Record`'s backward
/// fields.
pub const BACKWARD_DATASETS: [[MapDataset; 4]; 2] = [backward_maps!("x"), backward_maps!("y")];

/// The path of backward map `k` (of [`BACKWARD_DATASETS`]) of `axis`.
pub fn backward_path(axis: usize, k: usize) -> String {
    format!("{MAPS}/{}", BACKWARD_DATASETS[axis][k].name)
}

/// The stall maps of one axis.
macro_rules! stall_maps {
    ($a:literal) => {
        [
            map(
                concat!("stall_load_", $a),
                "N",
                concat!(
                    "load along ",
                    $a,
                    " at which the ",
                    $a,
                    " step stops: the zero crossing nearest zero load, against the unloaded \
                     step (0 unless stall_status_",
                    $a,
                    " is 0 or 6)"
                ),
                F64,
            ),
            map(
                concat!("stall_step_near_", $a),
                "m",
                concat!(
                    "step along ",
                    $a,
                    " per ",
                    $a,
                    " drive cycle at the stall bracket's end nearer zero load (still in the \
                     unloaded direction)"
                ),
                F64,
            ),
            map(
                concat!("stall_step_far_", $a),
                "m",
                concat!(
                    "step along ",
                    $a,
                    " per ",
                    $a,
                    " drive cycle at the stall bracket's far end (stopped or reversed)"
                ),
                F64,
            ),
            map(
                concat!("stall_waves_", $a),
                "1",
                "integrations of the stall search: the unloaded run and one probe per wave",
                U32,
            ),
            map(
                concat!("stall_status_", $a),
                "1",
                "stall search status (0 found, 6 found with a probe not steady, 8 no stall \
                 load, 1-5 a probe failed)",
                U32,
            ),
        ]
    };
}

/// The datasets under [`MAPS`] of a scene with `[stall]`, per stalled
/// axis (x, y): the values of `crate::stall::StallRecord`, in its field
/// order.
pub const STALL_DATASETS: [[MapDataset; 5]; 2] = [stall_maps!("x"), stall_maps!("y")];

/// The path of stall map `k` (of [`STALL_DATASETS`]) of `axis`.
pub fn stall_path(axis: usize, k: usize) -> String {
    format!("{MAPS}/{}", STALL_DATASETS[axis][k].name)
}

const fn map(
    name: &'static str,
    units: &'static str,
    long_name: &'static str,
    ty: MapType,
) -> MapDataset {
    MapDataset {
        name,
        units,
        long_name,
        ty,
    }
}

/// Bytes the maps of one instance take in a result file (and in memory
/// while a map is assembled), with or without its baselines, stall maps
/// and backward maps.
pub const fn bytes_per_instance(baselines: bool, stall: bool, backward: bool) -> u64 {
    let mut bytes = 0;
    let mut k = 0;
    while k < MAP_DATASETS.len() {
        bytes += MAP_DATASETS[k].bytes();
        k += 1;
    }
    if baselines {
        let mut k = 0;
        while k < BASELINE_DATASETS.len() {
            bytes += BASELINE_DATASETS[k].bytes();
            k += 1;
        }
    }
    if stall {
        let mut k = 0;
        while k < STALL_DATASETS[0].len() {
            bytes += STALL_DATASETS[0][k].bytes();
            k += 1;
        }
    }
    if backward {
        let mut k = 0;
        while k < BACKWARD_DATASETS[0].len() {
            bytes += 2 * BACKWARD_DATASETS[0][k].bytes();
            k += 1;
        }
    }
    bytes
}

/// The group of a shard file's instance list.
pub const SHARD: &str = "shard";
/// The flat scene index of each instance a shard file holds.
pub const SHARD_INSTANCE: &str = "shard/instance";
/// The attribute of every map and axis that holds its description.
pub const LONG_NAME: &str = "long_name";

/// Root attributes every result file carries: the pidm version, the
/// backend that ran (its description), "f32" or "f64", the integrator
/// variant, the scene's tolerance [rad], the `--verify` rerun's tolerance
/// [rad] (only with `--verify`) and the run's wall time [s].
pub const PIDM_VERSION: &str = "pidm_version";
pub const BACKEND: &str = "backend";
pub const PRECISION: &str = "precision";
pub const VARIANT: &str = "variant";
pub const TOLERANCE: &str = "tolerance";
/// Root attributes: the friction law ("karnopp" or "lugre", docs/model.md
/// sections 3 and 8) and, under LuGre, its parameters with units as
/// instance 0 has them.
pub const FRICTION: &str = "friction";
pub const FRICTION_PARAMETERS: &str = "friction_parameters";
pub const VERIFY_TOLERANCE: &str = "verify_tolerance";
pub const WALL_TIME_S: &str = "wall_time_s";
/// Root attribute: the wall time of each part of the run [s]: the runs of
/// an interrupted and resumed run in order, or the shards of a merged one;
/// one value for a plain run. `wall_time_s` is their total.
pub const WALL_TIME_PARTS_S: &str = "wall_time_parts_s";

/// Root attributes of a shard file: which part of the scene it holds.
pub const SHARD_COUNT: &str = "shard_count";
pub const INSTANCE_COUNT: &str = "instance_count";

/// The group of the maps; a file without it is no result file.
pub const MAPS: &str = "maps";
/// The 2-DOF step per axis [m per own drive cycle], shaped like the grid.
pub const STEP: [&str; 2] = ["maps/step_x", "maps/step_y"];
/// The integrator status per instance (0 = ok), shaped like the grid.
pub const STATUS: &str = "maps/status";
/// The standard errors of the steps per axis, shaped like the grid
/// (absent from files written before the steady measurement).
pub const STEP_SE: [&str; 2] = ["maps/step_x_se", "maps/step_y_se"];

/// The kind of motion per instance (u8, the codes of
/// [`crate::model::motion::Motion`]), shaped like the grid, with the CF attributes
/// [`FLAG_VALUES`] and [`FLAG_MEANINGS`]. Absent from files written before
/// it existed; `pidm plot` draws such a file without it.
pub const MOTION_NAME: &str = "motion";
pub const MOTION: &str = "maps/motion";
/// CF attributes of a map of codes: every code (of the map's type) and
/// their one-word names, space separated, in code order.
pub const FLAG_VALUES: &str = "flag_values";
pub const FLAG_MEANINGS: &str = "flag_meanings";

/// A refined run's map of inferred values (`crate::refine`), u8 shaped like
/// the grid: 1 where the value was interpolated (its standard errors are
/// interpolated too, not estimates), 0 where it was integrated. Only in
/// files of scenes with `[refine]`.
pub const INFERRED_NAME: &str = "inferred";
pub const INFERRED: &str = "maps/inferred";
/// Its `long_name`.
pub const INFERRED_LONG_NAME: &str =
    "1 where the value is interpolated from integrated neighbours (adaptive refinement)";

/// The group of a refined run: what was integrated and what each level did.
pub const REFINE: &str = "refine";
/// The flat row-major index of each integrated point, ascending (u64).
pub const REFINE_INDEX: &str = "refine/index";
/// The level that integrated each point of [`REFINE_INDEX`] (u8, 0 = the
/// coarse grid).
pub const REFINE_LEVEL: &str = "refine/level";
/// Per level (0 = the coarse grid), u64: the points it integrated, the
/// cells it judged and refined, the cells audited and those only the audit
/// flagged.
pub const REFINE_LEVEL_INTEGRATED: &str = "refine/level_integrated";
pub const REFINE_LEVEL_CANDIDATES: &str = "refine/level_candidates";
pub const REFINE_LEVEL_FLAGGED: &str = "refine/level_flagged";
pub const REFINE_LEVEL_AUDITED: &str = "refine/level_audited";
pub const REFINE_LEVEL_AUDIT_FINDS: &str = "refine/level_audit_finds";
/// Per level, f64 [m]: the largest difference between the interpolant and
/// an integrated probe.
pub const REFINE_LEVEL_LARGEST_MISS: &str = "refine/level_largest_miss";
/// Attributes of the refine group: `levels` (u64), `tolerance` [m] and
/// `coarse_shape` (u64 per axis).
pub const REFINE_LEVELS: &str = "levels";
pub const REFINE_TOLERANCE: &str = "tolerance";
/// Attribute of `/refine`: 1 when the 1-DOF baselines of the inferred
/// points were integrated (few distinct ones), 0 when interpolated.
pub const REFINE_EXACT_BASELINES: &str = "exact_baselines";
pub const REFINE_COARSE_SHAPE: &str = "coarse_shape";

/// The optional group of the 1-DOF runs beside the maps.
pub const BASELINE: &str = "baseline";
/// The 1-DOF step per axis, shaped like the grid.
pub const BASELINE_STEP: [&str; 2] = ["baseline/step_x", "baseline/step_y"];
/// The worse status of the two 1-DOF runs, shaped like the grid.
pub const BASELINE_STATUS: &str = "baseline/status";

/// The group of the grid axes, one 1-D dataset per axis key.
pub const AXES: &str = "axes";
/// The attribute of an axis dataset that holds its unit.
pub const UNITS: &str = "units";
/// The point labels of a points scene, one per instance.
pub const LABELS: &str = "labels";

/// Root attribute: the scene's name.
pub const NAME: &str = "name";
/// Root attribute: the scene's TOML text, which gives the grid order.
pub const SCENE: &str = "scene";
/// Root attribute present only in a shard file.
pub const SHARD_INDEX: &str = "shard_index";

/// The optional group of the stored trajectories, `<k>/` for k = 0, 1, ...
pub const TRAJECTORIES: &str = "trajectories";
/// Sample times [s] of a run group.
pub const TIME: &str = "time";
/// Stage and slider displacement per axis [m] of a trajectory group.
pub const STAGE: [&str; 2] = ["stage_x", "stage_y"];
pub const SLIDER: [&str; 2] = ["slider_x", "slider_y"];
/// The 1-DOF run subgroups of a trajectory, x driven alone and y alone.
pub const BASELINE_RUN: [&str; 2] = ["baseline_x", "baseline_y"];
/// Stage and slider displacement along the driven axis [m] of a 1-DOF run.
pub const BASELINE_STAGE: &str = "stage";
pub const BASELINE_SLIDER: &str = "slider";

/// Text attributes of a trajectory group.
pub const POINT: &str = "point";
pub const LABEL: &str = "label";
/// Integer attributes of a run group.
pub const INDEX: &str = "index";
pub const RUN_STATUS: &str = "status";
pub const MEASURED_CYCLES: &str = "measured_cycles";
/// Number attributes of a run group [s].
pub const PERIOD_S: &str = "period_s";
pub const SETTLE_S: &str = "settle_s";
pub const DURATION_S: &str = "duration_s";
/// Per-axis drive attributes of a run group, suffixed `_x` and `_y`.
pub const VOLTAGE: &str = "voltage";
pub const FREQUENCY: &str = "frequency";
pub const DUTY: &str = "duty";
pub const PHASE: &str = "phase";
/// The axis' waveform and slew limit in words (`scene::drive_words`:
/// "duty 0.98", "trapezoid rise 0.3, hold 0, fall 0.1, slew rate 1e5 V/s").
pub const DRIVE: &str = "drive";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paths_readers_use_are_the_datasets_writers_write() {
        let path = |group: &str, d: &MapDataset| format!("{group}/{}", d.name);
        assert_eq!(
            STEP.map(String::from),
            [0, 1].map(|k| path(MAPS, &MAP_DATASETS[k]))
        );
        assert_eq!(STATUS, path(MAPS, &MAP_DATASETS[4]));
        assert_eq!(MOTION, path(MAPS, &MAP_DATASETS[10]));
        assert_eq!(MAP_DATASETS[10].ty, MapType::U8);
        assert_eq!(
            BASELINE_STEP.map(String::from),
            [0, 1].map(|k| path(BASELINE, &BASELINE_DATASETS[k]))
        );
        assert_eq!(BASELINE_STATUS, path(BASELINE, &BASELINE_DATASETS[2]));
        assert_eq!(SHARD_INSTANCE, format!("{SHARD}/instance"));
        // Six f64 maps (steps, velocities, standard errors), five u32 maps
        // (status, steps, periods, period_lag, replicas) and the u8 motion
        // map: 6 x 8 + 5 x 4 + 1; two f64 and one u32 baselines add 20.
        assert_eq!(MAP_DATASETS[11].name, "replicas");
        assert_eq!(bytes_per_instance(false, false, false), 69);
        assert_eq!(bytes_per_instance(true, false, false), 89);
        // The backward maps: four f64 per axis.
        assert_eq!(bytes_per_instance(false, false, true), 69 + 64);
        assert_eq!(BACKWARD_DATASETS[1][2].name, "backward_ratio_y");
        assert_eq!(backward_path(0, 1), "maps/backward_x_se");
        // The stall maps: three f64 (load, the steps at the bracket's
        // ends) and two u32 (waves, status), named by their axis.
        assert_eq!(bytes_per_instance(false, true, false), 69 + 32);
        assert_eq!(STALL_DATASETS[0][0].name, "stall_load_x");
        assert_eq!(STALL_DATASETS[1][4].name, "stall_status_y");
        assert_eq!(stall_path(0, 0), "maps/stall_load_x");
        assert_eq!(STALL_DATASETS[1][0].units, "N");
    }

    /// docs/output.md's table of the kinds of motion, the codes `/maps/motion`
    /// holds, lists every kind of `crate::model::motion::Motion` with its name
    /// and meaning, in code order (here beside the map's schema, as
    /// `status.rs` holds the status table).
    #[test]
    fn the_output_docs_table_lists_every_kind_of_motion_with_its_meaning() {
        use crate::model::motion::Motion;
        let readme = include_str!("../../docs/output.md");
        let section = readme
            .split("\n## Kinds of motion\n")
            .nth(1)
            .expect("docs/output.md has a Kinds of motion section");
        let section = section.split("\n## ").next().unwrap();
        assert!(section.contains("`/maps/motion`"), "{section}");
        let rows: Vec<[String; 3]> = section
            .lines()
            .filter_map(|line| {
                let cols: Vec<&str> = line.trim().trim_matches('|').split('|').collect();
                let code = cols.first()?.trim();
                code.parse::<u8>().ok()?;
                Some([code, cols.get(1)?, cols.get(2)?].map(|c| c.trim().to_string()))
            })
            .collect();
        let want: Vec<[String; 3]> = Motion::ALL
            .iter()
            .map(|m| {
                [
                    m.code().to_string(),
                    m.name().to_string(),
                    m.meaning().to_string(),
                ]
            })
            .collect();
        assert_eq!(rows, want);
    }
}
