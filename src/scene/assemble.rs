//! Assembling a scene: from the parsed layers to the validated [`Scene`],
//! its layout (a grid or a list of points), the checks that need the whole
//! scene (derived stage quantities, settle < cycles or max_cycles, the
//! memory budget) and the trajectories.

use std::ops::Range;

use toml::de::DeTable;

use crate::laws::settings::Replicas;

use super::error::{Location, SceneError, point_name};
use super::format::fmt_short;
use super::keys::{
    AXIS_FIELDS, FREQUENCY, FREQUENCY_RATIO, Field, Law, MAX_STEPS_SLOT, Mode, SLOTS,
    TOLERANCE_SLOT, axis_slot, slot_field, slot_path,
};
use super::layer::{Layer, PointSpec, kept_from_lower};
use super::memory::{MAP_MEMORY_BUDGET_BYTES, check_memory};
use super::name::check_name;
use super::parser::Parser;
use super::plan::{Culprits, Plan, Src, check_instance};
use super::refine::RefineSpec;
use super::trajectories::{DEFAULT_SAMPLES_PER_CYCLE, SpecAt};
use super::values::Entry;
use super::waveform::effective_shapes;
use super::{GridAxis, Layout, Scene};
use crate::laws::Settings;
use crate::model::{AXES, Instance, Shape};

/// Parses and validates a scene; see [`Scene::from_toml`].
pub(super) fn scene(text: &str, default_name: Option<&str>) -> Result<Scene, SceneError> {
    let document = DeTable::parse(text).map_err(|error| SceneError::Syntax { error })?;
    let parser = Parser { text };
    let parsed = parser.root(document.get_ref())?;

    let name = scene_name(parsed.name, default_name)?;
    let base = &parsed.base;
    let mut settings = base_settings(base, parsed.replicas.as_ref());
    settings.backward = parsed.backward;
    let keys = BaseKeys::new(base, parsed.measure, parsed.friction.as_ref());
    let grid = grid_entries(base);
    let base_shapes = base.shapes.clone().map(|s| s.map(|s| s.shape));
    parser.check_shape_keys(base, effective_shapes(&[base]), "")?;
    let plan = Plan::build(
        &keys.given,
        &keys.ties,
        (keys.mode, keys.friction),
        base_shapes,
    );

    let mut scene = Scene {
        name,
        text: text.to_owned(),
        layout: Layout::Grid { axes: Vec::new() },
        baselines: parsed.baselines,
        settings,
        trajectories: Vec::new(),
        trajectory_samples_per_cycle: parsed
            .samples_per_cycle
            .unwrap_or(DEFAULT_SAMPLES_PER_CYCLE),
        description: parsed.description,
        plan,
        raw: keys.raw,
        refine: None,
        stall: parsed.stall,
        grid_slots: Vec::new(),
        points: Vec::new(),
        point_keys: Vec::new(),
        driven: [false; AXES],
    };

    if let Some(spec) = &parsed.random {
        let beside = [
            (parsed.points.is_some(), "[[points]]"),
            (parsed.refine.is_some(), "[refine]"),
            (parsed.stall.is_some(), "[stall]"),
            (
                parsed.friction.is_some(),
                "mechanism.friction (its instances are Karnopp's)",
            ),
        ];
        random_points(
            &parser,
            spec,
            beside,
            parsed.measure,
            base,
            (&plan, &keys.raw),
            &mut scene,
        )?;
        return finish_points(&parser, &parsed.trajectories, scene);
    }

    if let Some(points) = &parsed.points {
        points_layout(
            &parser,
            &keys,
            points,
            (&grid, parsed.refine.as_ref()),
            &mut scene,
        )?;
        return finish_points(&parser, &parsed.trajectories, scene);
    }

    grid_layout(&parser, &keys, parsed.refine.as_ref(), grid, &mut scene)?;
    scene.trajectories = parser.resolve_trajectories(&parsed.trajectories, &scene)?;
    Ok(scene)
}

/// The scene's name: the given one, checked by the parser, or else the
/// default one (the file's stem), checked here by the same rule.
fn scene_name(given: Option<String>, default_name: Option<&str>) -> Result<String, SceneError> {
    if let Some(name) = given {
        return Ok(name);
    }
    let name = default_name.ok_or_else(|| SceneError::Invalid {
        message: "name: missing; a scene read from text needs `name = \"...\"`".to_owned(),
        location: None,
    })?;
    check_name(name).map_err(|expected| SceneError::Invalid {
        message: format!(
            "name = {expected} (this is the default name, the scene file's stem; \
             set `name = \"...\"` in the scene)"
        ),
        location: None,
    })?;
    Ok(name.to_owned())
}

/// The integrator's settings of the base layer: its tolerance and step cap
/// where given, and its replicas (`Replicas::Auto` unless it says otherwise).
fn base_settings(base: &Layer, replicas: Option<&(Replicas, Range<usize>)>) -> Settings {
    let mut settings = Settings::default();
    if let Some(entry) = &base.entries[TOLERANCE_SLOT] {
        settings.tolerance = entry.values.value(0);
    }
    if let Some(entry) = &base.entries[MAX_STEPS_SLOT] {
        settings.max_steps_per_period = entry.values.value(0) as u32;
    }
    // A scene splits what it can unless it says otherwise.
    settings.replicas = replicas.map_or(Replicas::Auto, |(replicas, _)| *replicas);
    settings
}

/// The base layer's keys, from which the scene's plan and each point's
/// own plan are built.
struct BaseKeys<'a> {
    /// The base layer itself, for locating errors.
    layer: &'a Layer,
    /// Each slot's first value (0 where not given).
    raw: [f64; SLOTS],
    /// Which slots the base gives.
    given: [bool; SLOTS],
    /// For each tied slot, the slot it is tied to.
    ties: [Option<usize>; SLOTS],
    /// The measurement mode (steady unless given).
    mode: Mode,
    /// The friction law (Karnopp's unless given).
    friction: Law,
}

impl<'a> BaseKeys<'a> {
    /// Reads the base layer's first values, given keys and ties.
    fn new(
        layer: &'a Layer,
        measure: Option<Mode>,
        friction: Option<&(Law, Range<usize>)>,
    ) -> Self {
        let mut raw = [0.0; SLOTS];
        let mut given = [false; SLOTS];
        for (slot, entry) in layer.entries.iter().enumerate() {
            if let Some(entry) = entry {
                given[slot] = true;
                raw[slot] = entry.values.value(0);
            }
        }
        BaseKeys {
            layer,
            raw,
            given,
            ties: std::array::from_fn(|slot| layer.ties[slot].as_ref().map(|tie| tie.target)),
            mode: measure.unwrap_or_default(),
            friction: friction.map_or_else(Default::default, |(law, _)| *law),
        }
    }
}

/// The base layer's keys with more than one value, the grid axes, in the
/// order of the text.
fn grid_entries(base: &Layer) -> Vec<(usize, Entry)> {
    let mut grid: Vec<(usize, Entry)> = base
        .entries
        .iter()
        .enumerate()
        .filter_map(|(slot, entry)| entry.as_ref().map(|e| (slot, e.clone())))
        .filter(|(_, entry)| entry.values.len() > 1)
        .collect();
    grid.sort_by_key(|(_, entry)| entry.span.start);
    grid
}

/// Locates an error by the first culprit found, layer by layer (the point
/// first).
fn locate_slot(parser: &Parser, culprits: Culprits, layers: &[&Layer]) -> Option<Location> {
    layers.iter().find_map(|layer| {
        culprits
            .iter()
            .flatten()
            .find_map(|&slot| layer.entries[slot].as_ref())
            .map(|entry| parser.locate(entry.span.start))
    })
}

/// The last steps of a points scene (`[[points]]` or `[random]`): its
/// trajectories resolved, its memory checked and its driven axes marked.
fn finish_points(
    parser: &Parser,
    trajectories: &[SpecAt],
    mut scene: Scene,
) -> Result<Scene, SceneError> {
    scene.trajectories = parser.resolve_trajectories(trajectories, &scene)?;
    scene.check_memory(MAP_MEMORY_BUDGET_BYTES)?;
    for (a, driven) in scene.driven.iter_mut().enumerate() {
        *driven = scene.points.iter().any(|p| p.axes[a].is_driven());
    }
    Ok(scene)
}

/// A `[[points]]` scene's instances, labels and key summaries. Refuses
/// `[refine]` and grid axes (the base's keys with several values) beside
/// `[[points]]`, then checks each point in turn.
fn points_layout(
    parser: &Parser,
    keys: &BaseKeys,
    points: &[PointSpec],
    (grid, refine): (&[(usize, Entry)], Option<&RefineSpec>),
    scene: &mut Scene,
) -> Result<(), SceneError> {
    if let Some(spec) = refine {
        return Err(parser.invalid(
            spec.span.clone(),
            "refine: a scene with [[points]] cannot be refined; expected a grid of two \
             range axes",
        ));
    }
    if let Some((slot, entry)) = grid.first() {
        return Err(parser.invalid(
            entry.span.clone(),
            format!(
                "{} has {} values, but a scene with [[points]] cannot have grid axes: \
                 give each point its own value, or drop [[points]]",
                slot_path(*slot),
                entry.values.len()
            ),
        ));
    }
    let mut labels = Vec::with_capacity(points.len());
    for (index, point) in points.iter().enumerate() {
        let instance = point_instance(parser, keys, index, point)?;
        scene.points.push(instance);
        labels.push(point.label.clone());
        scene.point_keys.push(point_keys(point));
    }
    scene.layout = Layout::Points { labels };
    Ok(())
}

/// Point `index`'s instance: its keys laid over the base's (a kept base
/// key where it does not over-determine the stage, a tie replaced by a
/// given key), resolved and checked.
fn point_instance(
    parser: &Parser,
    base: &BaseKeys,
    index: usize,
    point: &PointSpec,
) -> Result<Instance, SceneError> {
    let mut point_given = base.given;
    let mut point_raw = base.raw;
    for (slot, entry) in point.layer.entries.iter().enumerate() {
        if let Some(entry) = entry {
            point_given[slot] = true;
            point_raw[slot] = entry.values.value(0);
        }
    }
    for axis in 0..AXES {
        let upper = point.layer.axis_given(axis);
        let lower = base.layer.axis_given(axis);
        let kept = kept_from_lower(&upper, &lower, true, point.layer.shapes[axis].is_some());
        for j in 0..AXIS_FIELDS.len() {
            point_given[axis_slot(axis, j)] = upper[j] || kept[j];
        }
    }
    // A point that gives a tied key (or, for axis.y's frequency, its
    // ratio) replaces the tie.
    let mut point_ties = base.ties;
    for (slot, tie) in point_ties.iter_mut().enumerate() {
        let replaced = point.layer.entries[slot].is_some()
            || (slot == axis_slot(1, FREQUENCY)
                && point.layer.entries[axis_slot(1, FREQUENCY_RATIO)].is_some());
        if replaced {
            *tie = None;
        }
    }
    let layers = [&point.layer, base.layer];
    let prefix = format!("{}: ", point_name(index, &point.label));
    parser.check_shape_keys(&point.layer, effective_shapes(&layers), &prefix)?;
    let shapes: [Option<Shape>; AXES] = std::array::from_fn(|axis| {
        layers
            .iter()
            .find_map(|layer| layer.shapes[axis].as_ref().map(|s| s.shape))
    });
    let point_plan = Plan::build(
        &point_given,
        &point_ties,
        (base.mode, base.friction),
        shapes,
    );
    let instance = point_plan.resolve(&point_raw);
    check_instance(&instance, &point_plan).map_err(|(message, slot)| SceneError::Invalid {
        message: format!("{}: {message}", point_name(index, &point.label)),
        location: locate_slot(parser, slot, &[&point.layer, base.layer]),
    })?;
    Ok(instance)
}

/// The keys a point sets, in the order of the text ("axis.x.voltage =
/// 100, ..."), or "the base" when it sets none.
fn point_keys(point: &PointSpec) -> String {
    let mut keys: Vec<(usize, String)> = point
        .layer
        .entries
        .iter()
        .enumerate()
        .filter_map(|(slot, entry)| {
            entry.as_ref().map(|entry| {
                let value = fmt_short(entry.values.value(0));
                (entry.span.start, format!("{} = {value}", slot_path(slot)))
            })
        })
        .collect();
    for (axis, given) in point.layer.shapes.iter().enumerate() {
        if let Some(given) = given {
            let name = crate::model::AXIS_NAMES[axis];
            keys.push((
                given.span.start,
                format!("axis.{name}.waveform = {:?}", given.shape.name()),
            ));
        }
    }
    keys.sort();
    let keys: Vec<String> = keys.into_iter().map(|(_, key)| key).collect();
    if keys.is_empty() {
        "the base".to_owned()
    } else {
        keys.join(", ")
    }
}

/// A grid scene's layout: refined to its finest grid where `[refine]`
/// says so, its size checked before any range is expanded, the grid's
/// corners checked, then the axes expanded and the driven axes marked.
fn grid_layout(
    parser: &Parser,
    keys: &BaseKeys,
    refine: Option<&RefineSpec>,
    mut grid: Vec<(usize, Entry)>,
    scene: &mut Scene,
) -> Result<(), SceneError> {
    // A refined scene is its finest grid from here on.
    if let Some(spec) = refine {
        scene.refine = Some(parser.refine_grid(spec, &mut grid)?);
    }

    // Refuse oversized grids before expanding any range.
    let shape: Vec<u64> = grid.iter().map(|(_, entry)| entry.values.len()).collect();
    check_memory(
        &shape,
        false,
        scene.baselines,
        scene.stall.is_some(),
        scene.settings.backward,
        MAP_MEMORY_BUDGET_BYTES,
    )?;

    check_grid_corners(parser, keys, &scene.plan, &grid)?;

    let axes: Vec<GridAxis> = grid
        .iter()
        .map(|(slot, entry)| GridAxis {
            key: slot_path(*slot),
            values: entry.values.expand(),
            units: slot_field(*slot).units(),
        })
        .collect();
    scene.grid_slots = grid.iter().map(|(slot, _)| *slot).collect();
    scene.driven = grid_driven(&scene.plan, &scene.grid_slots, &axes, &keys.raw);
    scene.layout = Layout::Grid { axes };
    Ok(())
}

/// Checks the corners of the grid over the keys whose checks are monotone.
///
/// Per-key checks covered every value; derived quantities and settle <
/// cycles (or max_cycles) are monotone in each key, and the load's
/// magnitude |L| is convex in the loads, its limit f_c monotone, so the
/// corners of the grid over the keys involved cover every instance (a
/// refused corner is a grid point, named by its values).
fn check_grid_corners(
    parser: &Parser,
    keys: &BaseKeys,
    plan: &Plan,
    grid: &[(usize, Entry)],
) -> Result<(), SceneError> {
    let involved: Vec<(usize, f64, f64)> = grid
        .iter()
        .filter(|(slot, _)| {
            let field = slot_field(*slot);
            matches!(
                field,
                Field::StageMass
                    | Field::Stiffness
                    | Field::ResonanceHz
                    | Field::QualityFactor
                    | Field::Frequency
                    | Field::FrequencyRatio
                    | Field::Cycles
                    | Field::Settle
                    | Field::MaxCycles
                    | Field::LoadX
                    | Field::LoadY
                    | Field::CoulombFriction
                    | Field::Rise
                    | Field::Hold
                    | Field::Fall
            )
        })
        .map(|(slot, entry)| {
            let (lo, hi) = entry.values.min_max();
            (*slot, lo, hi)
        })
        .collect();
    for corner in 0..1u64 << involved.len() {
        let mut corner_raw = keys.raw;
        for (bit, &(slot, lo, hi)) in involved.iter().enumerate() {
            corner_raw[slot] = if (corner >> bit) & 1 == 1 { hi } else { lo };
        }
        let instance = plan.resolve(&corner_raw);
        check_instance(&instance, plan).map_err(|(message, slot)| SceneError::Invalid {
            message,
            location: locate_slot(parser, slot, &[keys.layer]),
        })?;
    }
    Ok(())
}

/// Whether each axis of a grid scene is ever driven: a constant voltage
/// other than 0, a ratio (only a frequency is one), or a voltage key with
/// some value other than 0 on its grid axis or in the base.
fn grid_driven(
    plan: &Plan,
    grid_slots: &[usize],
    axes: &[GridAxis],
    raw: &[f64; SLOTS],
) -> [bool; AXES] {
    std::array::from_fn(|a| match plan.axes[a].voltage {
        Src::Const(v) => v != 0.0,
        // Only a frequency is a ratio.
        Src::Ratio { .. } => true,
        Src::Slot(slot) => match grid_slots.iter().position(|&s| s == slot) {
            Some(g) => axes[g].values.iter().any(|&v| v != 0.0),
            None => raw[slot] != 0.0,
        },
    })
}

/// A `[random]` scene's instances as points: `count` random instances from
/// `seed` (`crate::model::random`, as `pidm random-scene` writes them), measured
/// over the window of the scene's `[simulation]`; labelled "random K" as
/// that command labels them. Refuses what does not apply beside
/// `[random]`: points, refinement, stall searches, a steady measurement
/// and any mechanism or axis key.
fn random_points(
    parser: &Parser,
    spec: &super::parser::RandomSpec,
    beside: [(bool, &str); 4],
    measure: Option<super::keys::Mode>,
    base: &Layer,
    (plan, raw): (&Plan, &[f64; SLOTS]),
    scene: &mut Scene,
) -> Result<(), SceneError> {
    let refuse = |what: &str| {
        Err(parser.invalid(
            spec.span.clone(),
            format!(
                "random: a scene with [random] lists its own instances, so it cannot have \
                 {what}; expected [random] with [simulation] (measure = \"window\", cycles, \
                 settle), [output] and a name only"
            ),
        ))
    };
    if let Some((_, what)) = beside.iter().find(|(given, _)| *given) {
        return refuse(what);
    }
    if measure != Some(super::keys::Mode::Window) {
        return Err(parser.invalid(
            spec.span.clone(),
            "random: random instances are measured over a fixed window, as `pidm \
             random-scene` writes them; expected [simulation] measure = \"window\" (with \
             cycles and settle)",
        ));
    }
    parser.check_random_keys(base)?;
    // The window: the base instance's cycles and settle.
    let base = plan.resolve(raw);
    check_instance(&base, plan).map_err(|(message, _)| SceneError::Invalid {
        message,
        location: None,
    })?;
    let count = spec.count as usize;
    scene.points =
        crate::model::random::random_instances(spec.seed, count, base.cycles, base.settle);
    scene.point_keys = (0..count)
        .map(|k| format!("random instance {k} of seed {}", spec.seed))
        .collect();
    scene.layout = Layout::Points {
        labels: (0..count).map(|k| format!("random {k}")).collect(),
    };
    Ok(())
}
