//! Assembling a scene: from the parsed layers to the validated [`Scene`],
//! its layout (a grid or a list of points), the checks that need the whole
//! scene (derived stage quantities, settle < cycles or max_cycles, the
//! memory budget) and the trajectories.

use toml::de::DeTable;

use crate::laws::settings::Replicas;

use super::error::{SceneError, point_name};
use super::format::fmt_short;
use super::keys::{
    AXIS_FIELDS, FREQUENCY, FREQUENCY_RATIO, Field, MAX_STEPS_SLOT, SLOTS, TOLERANCE_SLOT,
    axis_slot, slot_field, slot_path,
};
use super::layer::{Layer, kept_from_lower};
use super::memory::{MAP_MEMORY_BUDGET_BYTES, check_memory};
use super::name::check_name;
use super::parser::Parser;
use super::plan::{Culprits, Plan, Src, check_instance};
use super::trajectories::DEFAULT_SAMPLES_PER_CYCLE;
use super::values::Entry;
use super::{GridAxis, Layout, Scene};
use crate::laws::karnopp::integrate::Settings;
use crate::model::AXES;

/// Parses and validates a scene; see [`Scene::from_toml`].
pub(super) fn scene(text: &str, default_name: Option<&str>) -> Result<Scene, SceneError> {
    let document = DeTable::parse(text).map_err(|error| SceneError::Syntax { error })?;
    let parser = Parser { text };
    let parsed = parser.root(document.get_ref())?;

    // A given name was checked by the parser; the default one is checked
    // here by the same rule.
    let name = match parsed.name {
        Some(name) => name,
        None => {
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
            name.to_owned()
        }
    };

    let base = &parsed.base;
    let mut settings = Settings::default();
    if let Some(entry) = &base.entries[TOLERANCE_SLOT] {
        settings.tolerance = entry.values.value(0);
    }
    if let Some(entry) = &base.entries[MAX_STEPS_SLOT] {
        settings.max_steps_per_period = entry.values.value(0) as u32;
    }
    // A scene splits what it can unless it says otherwise.
    settings.replicas = parsed
        .replicas
        .map_or(Replicas::Auto, |(replicas, _)| replicas);

    let mut raw = [0.0; SLOTS];
    let mut given = [false; SLOTS];
    for (slot, entry) in base.entries.iter().enumerate() {
        if let Some(entry) = entry {
            given[slot] = true;
            raw[slot] = entry.values.value(0);
        }
    }
    let mut grid: Vec<(usize, Entry)> = base
        .entries
        .iter()
        .enumerate()
        .filter_map(|(slot, entry)| entry.as_ref().map(|e| (slot, e.clone())))
        .filter(|(_, entry)| entry.values.len() > 1)
        .collect();
    grid.sort_by_key(|(_, entry)| entry.span.start);

    let mode = parsed.measure.unwrap_or_default();
    let friction = parsed
        .friction
        .as_ref()
        .map_or_else(Default::default, |(law, _)| *law);
    let ties: [Option<usize>; SLOTS] =
        std::array::from_fn(|slot| base.ties[slot].as_ref().map(|tie| tie.target));
    let plan = Plan::build(&given, &ties, mode, friction);
    // Locates an error by the first culprit found, layer by layer (the
    // point first).
    let locate_slot = |culprits: Culprits, layers: &[&Layer]| {
        layers.iter().find_map(|layer| {
            culprits
                .iter()
                .flatten()
                .find_map(|&slot| layer.entries[slot].as_ref())
                .map(|entry| parser.locate(entry.span.start))
        })
    };

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
        raw,
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
            (&plan, &raw),
            &mut scene,
        )?;
        scene.trajectories = parser.resolve_trajectories(&parsed.trajectories, &scene)?;
        scene.check_memory(MAP_MEMORY_BUDGET_BYTES)?;
        for (a, driven) in scene.driven.iter_mut().enumerate() {
            *driven = scene.points.iter().any(|p| p.axes[a].is_driven());
        }
        return Ok(scene);
    }

    if let Some(points) = parsed.points {
        if let Some(spec) = &parsed.refine {
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
            let mut point_given = given;
            let mut point_raw = raw;
            for (slot, entry) in point.layer.entries.iter().enumerate() {
                if let Some(entry) = entry {
                    point_given[slot] = true;
                    point_raw[slot] = entry.values.value(0);
                }
            }
            for axis in 0..AXES {
                let upper = point.layer.axis_given(axis);
                let lower = base.axis_given(axis);
                let kept = kept_from_lower(&upper, &lower, true);
                for j in 0..AXIS_FIELDS.len() {
                    point_given[axis_slot(axis, j)] = upper[j] || kept[j];
                }
            }
            // A point that gives a tied key (or, for axis.y's frequency, its
            // ratio) replaces the tie.
            let mut point_ties = ties;
            for (slot, tie) in point_ties.iter_mut().enumerate() {
                let replaced = point.layer.entries[slot].is_some()
                    || (slot == axis_slot(1, FREQUENCY)
                        && point.layer.entries[axis_slot(1, FREQUENCY_RATIO)].is_some());
                if replaced {
                    *tie = None;
                }
            }
            let point_plan = Plan::build(&point_given, &point_ties, mode, friction);
            let instance = point_plan.resolve(&point_raw);
            check_instance(&instance, &point_plan).map_err(|(message, slot)| {
                SceneError::Invalid {
                    message: format!("{}: {message}", point_name(index, &point.label)),
                    location: locate_slot(slot, &[&point.layer, base]),
                }
            })?;
            scene.points.push(instance);
            labels.push(point.label.clone());
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
            keys.sort();
            let keys: Vec<String> = keys.into_iter().map(|(_, key)| key).collect();
            scene.point_keys.push(if keys.is_empty() {
                "the base".to_owned()
            } else {
                keys.join(", ")
            });
        }
        scene.layout = Layout::Points { labels };
        scene.trajectories = parser.resolve_trajectories(&parsed.trajectories, &scene)?;
        scene.check_memory(MAP_MEMORY_BUDGET_BYTES)?;
        for (a, driven) in scene.driven.iter_mut().enumerate() {
            *driven = scene.points.iter().any(|p| p.axes[a].is_driven());
        }
        return Ok(scene);
    }

    // A refined scene is its finest grid from here on.
    if let Some(spec) = &parsed.refine {
        scene.refine = Some(parser.refine_grid(spec, &mut grid)?);
    }

    // Refuse oversized grids before expanding any range.
    let shape: Vec<u64> = grid.iter().map(|(_, entry)| entry.values.len()).collect();
    check_memory(
        &shape,
        false,
        scene.baselines,
        scene.stall.is_some(),
        MAP_MEMORY_BUDGET_BYTES,
    )?;

    // Per-key checks covered every value; derived quantities and
    // settle < cycles (or max_cycles) are monotone in each key, and the
    // load's magnitude |L| is convex in the loads, its limit f_c monotone,
    // so the corners of the grid over the keys involved cover every
    // instance (a refused corner is a grid point, named by its values).
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
            )
        })
        .map(|(slot, entry)| {
            let (lo, hi) = entry.values.min_max();
            (*slot, lo, hi)
        })
        .collect();
    for corner in 0..1u64 << involved.len() {
        let mut corner_raw = raw;
        for (bit, &(slot, lo, hi)) in involved.iter().enumerate() {
            corner_raw[slot] = if (corner >> bit) & 1 == 1 { hi } else { lo };
        }
        let instance = plan.resolve(&corner_raw);
        check_instance(&instance, &plan).map_err(|(message, slot)| SceneError::Invalid {
            message,
            location: locate_slot(slot, &[base]),
        })?;
    }

    let axes: Vec<GridAxis> = grid
        .iter()
        .map(|(slot, entry)| GridAxis {
            key: slot_path(*slot),
            values: entry.values.expand(),
            units: slot_field(*slot).units(),
        })
        .collect();
    scene.grid_slots = grid.iter().map(|(slot, _)| *slot).collect();
    for a in 0..AXES {
        scene.driven[a] = match plan.axes[a].voltage {
            Src::Const(v) => v != 0.0,
            // Only a frequency is a ratio.
            Src::Ratio { .. } => true,
            Src::Slot(slot) => match scene.grid_slots.iter().position(|&s| s == slot) {
                Some(g) => axes[g].values.iter().any(|&v| v != 0.0),
                None => raw[slot] != 0.0,
            },
        };
    }
    scene.layout = Layout::Grid { axes };
    scene.trajectories = parser.resolve_trajectories(&parsed.trajectories, &scene)?;
    Ok(scene)
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
