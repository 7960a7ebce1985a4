//! Tests of the scene format: refusals with clear messages, grid and point
//! expansion, stage derivation and the shipped scenes.

use std::path::PathBuf;

use pidm::model::{Axis, Instance, Measure};
use pidm::scene::{Layout, MAP_MEMORY_BUDGET_BYTES, MAX_SCENE_BYTES, Scene, SceneError};

/// Parses a scene that must be valid, failing with its error message.
fn parse(text: &str) -> Scene {
    match Scene::from_toml(text, Some("test")) {
        Ok(scene) => scene,
        Err(error) => panic!("refused a valid scene: {error}\n{text}"),
    }
}

/// Checks that `text` is refused with a message containing `needle`.
fn check(text: &str, needle: &str) {
    match Scene::from_toml(text, Some("test")) {
        Ok(scene) => panic!(
            "accepted a bad scene ({} instances); expected an error containing {needle:?}:\n{text}",
            scene.instance_count()
        ),
        Err(error) => {
            let message = error.to_string();
            assert!(
                message.contains(needle),
                "the error for\n{text}\nis\n  {message}\nand lacks {needle:?}"
            );
        }
    }
}

/// Whether two numbers agree to `rel` relative.
fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs())
}

/// The path of a shipped scene.
fn shipped(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("sweeps")
        .join(name)
}

#[test]
fn bad_scenes_are_refused_with_clear_messages() {
    let cases: &[(&str, &str)] = &[
        // Unknown keys, with the closest valid key or the right table.
        (
            "[axis.x]\nstifness = 1e6",
            "unknown key `axis.x.stifness` (did you mean `stiffness`?)",
        ),
        (
            "[axes.x]\nvoltage = 1",
            "unknown key `axes` (did you mean `axis`?)",
        ),
        ("[axis.z]\nvoltage = 1", "unknown key `axis.z`"),
        (
            "[mechanism]\nstage_mass = 1e-3",
            "unknown key `mechanism.stage_mass` (`stage_mass` belongs in [axis.x] or [axis.y])",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 1, step = 3 }",
            "unknown key `axis.x.voltage.step` (did you mean `steps`?)",
        ),
        ("[output]\nbaseline = true", "did you mean `baselines`?"),
        // Wrong types.
        (
            "[axis.y]\nvoltage = \"abc\"",
            "axis.y.voltage: expected a number, a list of numbers or a range { from, to, steps }, found a string \"abc\"",
        ),
        (
            "[axis.x]\nvoltage = [1.0, \"2\"]",
            "axis.x.voltage[1]: expected a number",
        ),
        (
            "mechanism = 5",
            "mechanism: expected a table, found an integer 5",
        ),
        (
            "[output]\nbaselines = 1",
            "output.baselines: expected a boolean",
        ),
        ("name = 3", "name: expected a string"),
        // Non-finite numbers.
        (
            "[axis.x]\nvoltage = nan",
            "axis.x.voltage = nan: expected a finite number",
        ),
        (
            "[mechanism]\nslider_mass = inf",
            "mechanism.slider_mass = inf: expected a finite number",
        ),
        (
            "[axis.x]\ngain = [1.0, -inf]",
            "axis.x.gain = -inf: expected a finite number",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = inf, steps = 3 }",
            "axis.x.voltage.to = inf",
        ),
        // Out-of-range values.
        (
            "[axis.x]\nduty = 0.0",
            "axis.x.duty = 0: expected a number in (0, 1]",
        ),
        (
            "[axis.x]\nduty = 1.5",
            "axis.x.duty = 1.5: expected a number in (0, 1]",
        ),
        (
            "[axis.y]\nduty = [0.5, 1.5]",
            "axis.y.duty = 1.5: expected a number in (0, 1] (value 2 of [0.5, 1.5])",
        ),
        (
            "[axis.x]\nstage_mass = -1e-3",
            "axis.x.stage_mass = -0.001: expected a number > 0",
        ),
        (
            "[mechanism]\nslider_mass = 0",
            "mechanism.slider_mass = 0: expected a number > 0",
        ),
        (
            "[axis.y]\nstiffness = 0",
            "axis.y.stiffness = 0: expected a number > 0",
        ),
        (
            "[axis.x]\nfrequency = 0",
            "axis.x.frequency = 0: expected a number > 0",
        ),
        (
            "[axis.x]\nfrequency = -10",
            "axis.x.frequency = -10: expected a number > 0",
        ),
        (
            "[axis.x]\ndamping = -0.1",
            "axis.x.damping = -0.1: expected a number >= 0",
        ),
        (
            "[mechanism]\ncoulomb_friction = -1",
            "mechanism.coulomb_friction = -1: expected a number >= 0",
        ),
        (
            "[mechanism]\nstatic_friction = 0",
            "mechanism.static_friction = 0: expected a number > 0",
        ),
        (
            "[mechanism]\nvelocity_band = 0",
            "mechanism.velocity_band = 0: expected a number > 0",
        ),
        (
            "[axis.x]\nquality_factor = 0",
            "axis.x.quality_factor = 0: expected a number > 0",
        ),
        (
            "[axis.x]\nresonance_hz = -1000",
            "axis.x.resonance_hz = -1000: expected a number > 0",
        ),
        (
            "[axis.x]\nvoltage = { from = -1, to = 1, steps = 3 }\nfrequency = { from = 10, to = 0, steps = 3 }",
            "axis.x.frequency = 0: expected a number > 0 (in the range { from = 10, to = 0, steps = 3 })",
        ),
        // The run length.
        (
            "[simulation]\nmeasure = \"window\"\ncycles = 10\nsettle = 10",
            "simulation.settle = 10 with simulation.cycles = 10: expected settle < cycles",
        ),
        (
            "[simulation]\nmeasure = \"window\"\ncycles = 2",
            "simulation.settle = 2 with simulation.cycles = 2",
        ),
        (
            "[simulation]\nmeasure = \"window\"\ncycles = 0",
            "simulation.cycles = 0: expected an integer",
        ),
        (
            "[simulation]\nmeasure = \"window\"\ncycles = 2.5",
            "simulation.cycles = 2.5: expected an integer",
        ),
        (
            "[simulation]\nsettle = -1",
            "simulation.settle = -1: expected an integer",
        ),
        (
            "[simulation]\nmeasure = \"window\"\ncycles = 4\nsettle = [1, 5]",
            "simulation.settle = 5 with simulation.cycles = 4",
        ),
        (
            "[simulation]\nmeasure = \"window\"\ncycles = { from = 2, to = 10, steps = 4 }",
            "do not land on integers",
        ),
        (
            "[simulation]\nmeasure = \"window\"\ncycles = { from = 3, to = 30, steps = 3, log = true }",
            "cannot take a log range",
        ),
        // The measurement: its mode, the keys of each mode and their values.
        (
            "[simulation]\nmeasure = \"forever\"",
            "simulation.measure = \"forever\": expected \"steady\" or \"window\"",
        ),
        (
            "[simulation]\nmeasure = 3",
            "simulation.measure: expected \"steady\" or \"window\", found an integer 3",
        ),
        (
            "[simulation]\nmeasure = [\"window\"]",
            "simulation.measure: expected \"steady\" or \"window\", found a list",
        ),
        (
            "[simulation]\nmeasure = \"Window\"",
            "simulation.measure = \"Window\": expected \"steady\" or \"window\"",
        ),
        (
            "[simulation]\nstep_tolerance = 0",
            "simulation.step_tolerance = 0: expected a number > 0",
        ),
        (
            "[simulation]\nstep_tolerance = -1e-9",
            "simulation.step_tolerance = -1e-9: expected a number > 0",
        ),
        (
            "[simulation]\nstep_tolerance = nan",
            "simulation.step_tolerance = nan: expected a finite number",
        ),
        (
            "[simulation]\nstep_tolerance = inf",
            "simulation.step_tolerance = inf: expected a finite number",
        ),
        (
            "[simulation]\nstep_tolerance = [1e-8, -inf]",
            "simulation.step_tolerance = -inf: expected a finite number",
        ),
        (
            "[simulation]\nstep_tolerance = 1e-2",
            "simulation.step_tolerance = 0.01: expected a number from 0 to 0.001 m",
        ),
        (
            "[simulation]\nstep_tolerance = \"1e-8\"",
            "simulation.step_tolerance: expected a number",
        ),
        (
            "[simulation]\nmax_cycles = 0",
            "simulation.max_cycles = 0: expected an integer from 1 to 4294967295",
        ),
        (
            "[simulation]\nmax_cycles = 2.5",
            "simulation.max_cycles = 2.5: expected an integer",
        ),
        (
            "[simulation]\nmax_cycles = 4294967296",
            "simulation.max_cycles = 4294967296: expected an integer from 1 to 4294967295",
        ),
        (
            "[simulation]\nmax_cycles = 2",
            "simulation.settle = 2 with simulation.max_cycles = 2: expected settle < max_cycles",
        ),
        (
            "[simulation]\nmax_cycles = 1",
            "simulation.settle = 2 with simulation.max_cycles = 1: expected settle < max_cycles",
        ),
        (
            "[simulation]\nmeasure = \"steady\"\nsettle = 50\nmax_cycles = 50",
            "simulation.settle = 50 with simulation.max_cycles = 50: expected settle < max_cycles",
        ),
        (
            "[simulation]\nmax_cycles = 40\nsettle = [1, 50]",
            "simulation.settle = 50 with simulation.max_cycles = 40",
        ),
        (
            "[simulation]\nmax_cycles = { from = 2, to = 10, steps = 3, log = true }",
            "simulation.max_cycles = { from = 2, to = 10, steps = 3, log = true }: an integer \
             key cannot take a log range",
        ),
        (
            "[simulation]\nmax_cycles = 100\n[[points]]\nlabel = \"short\"\n\
             simulation.max_cycles = 2",
            "points[0] (\"short\"): simulation.settle = 2 with simulation.max_cycles = 2",
        ),
        // A key of the other mode is refused, never ignored: `cycles` in a
        // steady scene (the default too), the steady keys in a window.
        (
            "[simulation]\ncycles = 10",
            "simulation.cycles applies to measure = \"window\"; a steady measurement takes \
             simulation.max_cycles (the most periods it may run). This scene measures \
             \"steady\" (the default, as no simulation.measure is given): set measure = \
             \"window\" for the paper's fixed window of cycles periods (line 2, column 10)",
        ),
        (
            "[simulation]\nmeasure = \"steady\"\nsettle = 2\ncycles = [10, 20]",
            "simulation.cycles applies to measure = \"window\"; a steady measurement takes \
             simulation.max_cycles (the most periods it may run). This scene sets measure = \
             \"steady\"",
        ),
        (
            "[simulation]\ncycles = 10\nmeasure = \"steady\"",
            "simulation.cycles applies to measure = \"window\"",
        ),
        (
            "[simulation]\nmeasure = \"window\"\nstep_tolerance = 1e-8",
            "simulation.step_tolerance applies to measure = \"steady\"; a window measurement \
             runs simulation.cycles periods and takes no step_tolerance or max_cycles. This \
             scene sets measure = \"window\": remove it, or set measure = \"steady\"",
        ),
        (
            "[simulation]\nmax_cycles = 100\nmeasure = \"window\"",
            "simulation.max_cycles applies to measure = \"steady\"",
        ),
        (
            "[simulation]\nmeasure = \"window\"\n[[points]]\nlabel = \"a\"\n[[points]]\n\
             label = \"b\"\nsimulation.max_cycles = 100",
            "points[1] (\"b\"): simulation.max_cycles applies to measure = \"steady\"",
        ),
        (
            "[[points]]\nsimulation.cycles = 4",
            "points[0]: simulation.cycles applies to measure = \"window\"",
        ),
        (
            "[[points]]\nsimulation.measure = \"window\"",
            "points[0]: simulation.measure cannot be set per point: it applies to the whole scene",
        ),
        (
            "[[points]]\nsimulation.step_tolerance = [1e-8, 1e-9]",
            "points[0]: simulation.step_tolerance = [1e-8, 1e-9]: expected a single value",
        ),
        (
            "[simulation]\nmax_cycles = 2000\n[output]\ntrajectories = [0]",
            "output.trajectories[0] = 0: 2000 samples per cycle x 2000 cycles = 4000000 samples \
             (a steady run may last its simulation.max_cycles periods): expected at most 2000000 \
             per trajectory; lower output.trajectory_samples_per_cycle or simulation.max_cycles",
        ),
        // Misspelt measurement keys get a hint.
        (
            "[simulation]\nmax_cycle = 100",
            "unknown key `simulation.max_cycle` (did you mean `max_cycles`?)",
        ),
        (
            "[simulation]\nstep_tolerence = 1e-8",
            "unknown key `simulation.step_tolerence` (did you mean `step_tolerance`?)",
        ),
        (
            "[simulation]\nmeasurement = \"window\"",
            "unknown key `simulation.measurement` (did you mean `measure`?)",
        ),
        (
            "[simulation]\nmesure = \"window\"",
            "unknown key `simulation.mesure` (did you mean `measure`?)",
        ),
        (
            "[axis.x]\nmax_cycles = 100",
            "unknown key `axis.x.max_cycles` (`max_cycles` belongs in [simulation])",
        ),
        (
            "[output]\nmeasure = \"window\"",
            "unknown key `output.measure` (`measure` belongs in [simulation])",
        ),
        (
            "[simulation]\ntolerance = 0",
            "simulation.tolerance = 0: expected a number > 0",
        ),
        (
            "[simulation]\ntolerance = [1e-4, 1e-5]",
            "cannot be a grid axis",
        ),
        (
            "[simulation]\nmax_steps_per_period = 0",
            "simulation.max_steps_per_period = 0",
        ),
        // Lists and ranges.
        (
            "[axis.x]\nvoltage = []",
            "axis.x.voltage = []: expected at least one value",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 1, steps = 0 }",
            "axis.x.voltage.steps = 0: expected an integer >= 1",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 1, steps = 2.5 }",
            "axis.x.voltage.steps = 2.5: expected an integer >= 1",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, steps = 3 }",
            "`to` is missing",
        ),
        (
            "[axis.x]\nvoltage = { to = 1, steps = 3 }",
            "`from` is missing",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 1 }",
            "`steps` is missing",
        ),
        (
            "[axis.x]\nfrequency = { from = 0, to = 100, steps = 3, log = true }",
            "a log range needs from > 0 and to > 0, found from = 0 and to = 100",
        ),
        (
            "[axis.x]\nvoltage = { from = 1, to = 2, steps = 3, log = 1 }",
            "axis.x.voltage.log: expected a boolean",
        ),
        // A range of one value must not pretend to span two.
        (
            "[axis.x]\nvoltage = { from = 0, to = 10, steps = 1 }",
            "axis.x.voltage = { from = 0, to = 10, steps = 1 }: steps = 1 gives the single value \
             from = 0, never reaching to = 10; expected steps >= 2 when from != to",
        ),
        // Too many steps says so, with the maximum.
        (
            "[axis.x]\nvoltage = { from = 0, to = 1, steps = 9223372036854775807 }",
            "axis.x.voltage.steps = 9223372036854775807: too large; expected at most 124491805 \
             steps",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 1, steps = 1e300 }",
            "axis.x.voltage.steps = 1e300: too large; expected at most 124491805 steps",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 1, steps = 132152840 }",
            "axis.x.voltage.steps = 132152840: too large",
        ),
        // The memory budget.
        (
            "[axis.x]\nvoltage = { from = 0, to = 1, steps = 100000 }\n[axis.y]\nvoltage = { from = 0, to = 1, steps = 100000 }",
            "do not fit the memory budget: grid 100000 x 100000 = 10000000000 instances x 69 bytes",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 1, steps = 124491805 }\n\
             gain = { from = 0, to = 1, steps = 124491805 }\n\
             frequency = { from = 1, to = 2, steps = 124491805 }\n\
             duty = { from = 0.5, to = 1, steps = 124491805 }\n\
             phase = { from = 0, to = 1, steps = 124491805 }",
            "grid 124491805 x 124491805 x 124491805 x 124491805 x 124491805 = more than \
             340282366920938463463374607431768211455 instances x 69 bytes per instance = more \
             than 340282366920938463463374607431768211455 bytes, over the budget",
        ),
        // Stage definitions.
        (
            "[axis.x]\nstage_mass = 1e-3\nstiffness = 1e6\nresonance_hz = 1000",
            "axis.x: stage_mass, stiffness and resonance_hz over-determine the stage",
        ),
        (
            "[axis.y]\ndamping = 3\nquality_factor = 50",
            "axis.y: damping and quality_factor both set the damping",
        ),
        // Derived stage quantities are checked over the whole grid, against
        // the bounds of the key they stand for.
        (
            "[axis.x]\nresonance_hz = [1000, 1e-2]",
            "(derived from axis.x.resonance_hz and the default stiffness 1000000): expected a \
             number from 1e-9 to 1000 kg (the plausible range of the model)",
        ),
        (
            "[axis.x]\nresonance_hz = 1e6\nstage_mass = 1e-3\n[axis.y]\nstage_mass = [1e-3, 1e3]",
            "(derived from axis.x.resonance_hz and axis.y.stage_mass): expected a number from \
             0.001 to 1000000000000 N/m",
        ),
        (
            "[axis.x]\nstiffness = 1e12\nstage_mass = 1e3\n\
             quality_factor = { from = 1e-3, to = 1, steps = 3 }",
            "(derived from axis.x.quality_factor, the stiffness and the stage mass): expected a \
             number from 0 to 1000000000 N s/m",
        ),
        // Points.
        (
            "[axis.y]\nvoltage = [0, 50]\n[[points]]\nlabel = \"a\"",
            "axis.y.voltage has 2 values, but a scene with [[points]] cannot have grid axes",
        ),
        (
            "[[points]]\nlabel = \"Fig. 5a\"\n[[points]]\nlabel = \"Fig. 7\"\naxis.x.duty = 2",
            "points[1] (\"Fig. 7\"): axis.x.duty = 2: expected a number in (0, 1]",
        ),
        (
            "[[points]]\naxis.x.voltage = [1, 2]",
            "points[0]: axis.x.voltage = [1, 2]: expected a single value",
        ),
        (
            "[simulation]\nmeasure = \"window\"\nsettle = 5\n[[points]]\nlabel = \"ok\"\n[[points]]\nsimulation.cycles = 3",
            "points[1]: simulation.settle = 5 with simulation.cycles = 3",
        ),
        (
            "[[points]]\nsimulation.tolerance = 1e-3",
            "points[0]: simulation.tolerance cannot be set per point",
        ),
        (
            "[[points]]\noutput.baselines = true",
            "points[0]: `output` cannot be set per point",
        ),
        (
            "[[points]]\naxis.x.stifness = 1",
            "points[0]: unknown key `axis.x.stifness` (did you mean `stiffness`?)",
        ),
        (
            "[[points]]\nlabel = 5",
            "points[0]: label: expected a string",
        ),
        (
            "[[points]]\nlabel = \"p\"\naxis.x.quality_factor = 10\naxis.x.damping = 1",
            "points[0] (\"p\"): axis.x: damping and quality_factor both set the damping",
        ),
        ("points = []", "points = []: expected at least one point"),
        // Trajectories.
        (
            "[output]\ntrajectories = \"Fig. 6\"",
            "output.trajectories: expected a list, each entry a point label",
        ),
        (
            "[output]\ntrajectories = [1.5]",
            "output.trajectories[0]: expected a point label (string), a flat instance index \
             (integer >= 0) or a table of grid coordinates",
        ),
        (
            "[output]\ntrajectories = [true]",
            "output.trajectories[0]: expected a point label (string)",
        ),
        (
            "[axis.x]\nvoltage = [50, 100]\n[output]\ntrajectories = [2]",
            "output.trajectories[0] = 2: expected an instance index from 0 to 1 (the scene has 2 \
             instances)",
        ),
        (
            "[output]\ntrajectories = [-1]",
            "output.trajectories[0] = -1: expected an instance index from 0 to 0",
        ),
        (
            "[axis.x]\nvoltage = [50, 100]\n[output]\ntrajectories = [\"a\"]",
            "output.trajectories[0] = \"a\": a grid scene has no point labels",
        ),
        (
            "[output]\ntrajectories = [\"Fig. 9\"]\n[[points]]\nlabel = \"Fig. 5a\"\n\
             [[points]]\nlabel = \"Fig. 6\"",
            "output.trajectories[0] = \"Fig. 9\": expected the label of a point: \"Fig. 5a\", \
             \"Fig. 6\"",
        ),
        (
            "[output]\ntrajectories = [\"a\"]\n[[points]]\nlabel = \"a\"\n[[points]]\nlabel = \"a\"",
            "the label names 2 points (indices [0, 1]); expected exactly one",
        ),
        (
            "[output]\ntrajectories = [\"a\"]\n[[points]]\naxis.x.voltage = 5",
            "expected the label of a point, but no point has a label",
        ),
        (
            "[output]\ntrajectories = [{ axis.x.voltage = 5 }]\n[[points]]\nlabel = \"a\"",
            "a points scene has no grid coordinates; expected a point label or index",
        ),
        (
            "[axis.x]\nvoltage = [50, 100]\n[axis.y]\nvoltage = [0, 10]\n\
             [output]\ntrajectories = [{ axis.x.voltage = 50 }]",
            "expected a value for every grid axis, but `axis.y.voltage` is missing",
        ),
        (
            "[axis.x]\nvoltage = [50, 100]\n[output]\ntrajectories = [{ axis.x.voltage = 75 }]",
            "axis.x.voltage = 75: expected one of the axis' values, [50, 100] V",
        ),
        (
            "[axis.x]\nvoltage = [50, 100]\n[output]\n\
             trajectories = [{ axis.x.voltage = 50, axis.x.duty = 0.5 }]",
            "`axis.x.duty` is not a grid axis; expected the keys axis.x.voltage",
        ),
        (
            "[axis.x]\nvoltage = [50, 100]\n[output]\ntrajectories = [{ axis.x.voltage = \"50\" }]",
            "output.trajectories[0].axis.x.voltage: expected a number",
        ),
        (
            "[axis.x]\nvoltage = [50, 100]\n[simulation]\nmax_cycles = 1000\n[output]\n\
             trajectories = [1, { \"axis.x.voltage\" = 100.0 }]",
            "output.trajectories[1] = { \"axis.x.voltage\" = 100.0 }: names the same instance as \
             output.trajectories[0]",
        ),
        (
            "[output]\ntrajectory_samples_per_cycle = 0",
            "output.trajectory_samples_per_cycle = 0: expected an integer from 1 to 1000000",
        ),
        (
            "[output]\ntrajectory_samples_per_cycle = 100.5",
            "output.trajectory_samples_per_cycle: expected an integer from 1 to 1000000, found a \
             float 100.5",
        ),
        (
            "[simulation]\nmeasure = \"window\"\ncycles = 2000\n[output]\ntrajectories = [0]",
            "output.trajectories[0] = 0: 2000 samples per cycle x 2000 cycles = 4000000 \
             samples: expected at most 2000000 per trajectory",
        ),
        (
            "[output]\ntrajectory = [0]",
            "unknown key `output.trajectory` (did you mean `trajectories`?)",
        ),
        (
            "trajectories = [0]",
            "unknown key `trajectories` (`trajectories` belongs in [output])",
        ),
        // Physical bounds: each bounded key, past one of its ends.
        (
            "[axis.x]\nfrequency = 1e300",
            "axis.x.frequency = 1e300: expected a number from 0.001 to 1000000 Hz (the plausible \
             range of the model)",
        ),
        (
            "[axis.y]\nvoltage = 1e308",
            "axis.y.voltage = 1e308: expected a number from -10000 to 10000 V",
        ),
        (
            "[axis.x]\nvoltage = 100000000000000000000000000000000000000000",
            "axis.x.voltage = 1e41: expected a number from -10000 to 10000 V",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = -2e4, steps = 3 }",
            "axis.x.voltage = -20000: expected a number from -10000 to 10000 V (the plausible \
             range of the model) (in the range { from = 0, to = -2e4, steps = 3 })",
        ),
        (
            "[mechanism]\nslider_mass = 1e-12",
            "mechanism.slider_mass = 1e-12: expected a number from 1e-9 to 1000 kg",
        ),
        (
            "[mechanism]\nstatic_friction = 1e10",
            "mechanism.static_friction = 10000000000: expected a number from 1e-12 to \
             1000000000 N",
        ),
        (
            "[mechanism]\ncoulomb_friction = 1e10",
            "mechanism.coulomb_friction = 10000000000: expected a number from 0 to 1000000000 N",
        ),
        (
            "[mechanism]\nvelocity_band = 1e-20",
            "mechanism.velocity_band = 1e-20: expected a number from 1e-15 to 1000 m/s",
        ),
        (
            "[axis.x]\nstage_mass = 1e4",
            "axis.x.stage_mass = 10000: expected a number from 1e-9 to 1000 kg",
        ),
        (
            "[axis.x]\nstiffness = 1e13",
            "axis.x.stiffness = 10000000000000: expected a number from 0.001 to 1000000000000 N/m",
        ),
        (
            "[axis.y]\ndamping = 1e10",
            "axis.y.damping = 10000000000: expected a number from 0 to 1000000000 N s/m",
        ),
        (
            "[axis.x]\nresonance_hz = 1e11",
            "axis.x.resonance_hz = 100000000000: expected a number from 0.001 to 10000000000 Hz",
        ),
        (
            "[axis.x]\nquality_factor = 1e-4",
            "axis.x.quality_factor = 0.0001: expected a number from 0.001 to 1000000000 (the",
        ),
        (
            "[axis.x]\ngain = -1e4",
            "axis.x.gain = -10000: expected a number from -1000 to 1000 N/V",
        ),
        (
            "[axis.x]\nduty = 1e-7",
            "axis.x.duty = 1e-7: expected a number from 1e-6 to 1 (the",
        ),
        (
            "[axis.y]\nphase = 2e6",
            "axis.y.phase = 2000000: expected a number from -1000000 to 1000000 cycles",
        ),
        // A phase is in cycles: 90 is almost surely degrees.
        (
            "[axis.y]\nvoltage = 100\nphase = 90",
            "axis.y.phase = 90: a phase is in cycles of the drive (1 = one period), so this is \
             90 periods, which runs like 0; if it is in degrees, write 0.25 (90 degrees / 360). \
             To mean whole cycles, set phase_units = \"cycles\" at the top of the scene (line 3",
        ),
        (
            "[axis.x]\nphase = { from = 0, to = 180, steps = 3 }",
            "axis.x.phase = 180: a phase is in cycles",
        ),
        (
            "[[points]]\naxis.x.phase = -45",
            "points[0]: axis.x.phase = -45: a phase is in cycles of the drive (1 = one period), \
             so this is -45 periods, which runs like 0; if it is in degrees, write -0.125",
        ),
        (
            "phase_units = \"degrees\"",
            "phase_units = \"degrees\": expected \"cycles\"",
        ),
        (
            "[[points]]\nphase_units = \"cycles\"",
            "`phase_units` cannot be set per point",
        ),
        (
            "[simulation]\ntolerance = 2",
            "simulation.tolerance = 2: expected a number from 1e-12 to 1 rad",
        ),
        // A name is a name, not a path: it makes results/<name>.h5.
        (
            "name = \"../../escaped\"",
            "name = \"../../escaped\": expected a name, not a path: no `/` or `\\`; the name \
             makes the default output file results/<name>.h5 (line 1, column 8)",
        ),
        (
            "name = \"/home/me/data\"",
            "name = \"/home/me/data\": expected a name, not a path",
        ),
        (
            "name = 'C:\\data\\run'",
            "name = \"C:\\\\data\\\\run\": expected a name, not a path",
        ),
        (
            "name = \"..\"",
            "name = \"..\": expected a name, not `.` or `..`",
        ),
        (
            "name = \".\"",
            "name = \".\": expected a name, not `.` or `..`",
        ),
        (
            "name = \".hidden\"",
            "name = \".hidden\": expected a name that does not start with `.`",
        ),
        (
            "name = \"-rf\"",
            "name = \"-rf\": expected a name that does not start with `-`",
        ),
        (
            "name = \"a\\u0000b\"",
            "name = \"a\\0b\": expected no control characters, found U+0000 at byte 1",
        ),
        (
            "name = \"a\\nb\"",
            "name = \"a\\nb\": expected no control characters, found U+000A at byte 1",
        ),
        ("name = \"\"", "name = \"\": expected a non-empty string"),
        (
            "name = \"  \"",
            "name = \"  \": expected a non-empty string",
        ),
        (
            "name = \"aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\"",
            "expected at most 100 bytes, found 101",
        ),
        // Locations and syntax.
        ("\n\n[axis.x]\nduty = 1.5", "(line 4, column 8)"),
        (
            "[axis.x]\nvoltage = = 3",
            "invalid TOML: TOML parse error at line 2",
        ),
        ("[axis.x]\nvoltage = 1\nvoltage = 2", "line 3"),
        // [refine]: its keys, and the grid it can refine.
        (
            "[axis.x]\nvoltage = { from = 0, to = 150, steps = 5 }\n\
             [axis.y]\nvoltage = { from = 0, to = 150, steps = 5 }\n[refine]\nlevels = 0",
            "refine.levels = 0: expected an integer from 1 to 10",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 150, steps = 5 }\n\
             [axis.y]\nvoltage = { from = 0, to = 150, steps = 5 }\n[refine]\nlevels = 2.5",
            "refine.levels = 2.5: expected an integer from 1 to 10",
        ),
        (
            "[refine]\nlevels = \"2\"",
            "refine.levels: expected an integer from 1 to 10, found a string \"2\"",
        ),
        (
            "[refine]\nlevels = 2\ntolerance = -1e-8",
            "refine.tolerance = -1e-8: expected a step tolerance in m per own drive cycle, > 0",
        ),
        (
            "[refine]\nlevels = 2\ntolerance = 1e-3",
            "refine.tolerance = 0.001",
        ),
        (
            "[refine]\nlevel = 2",
            "unknown key `refine.level` (did you mean `levels`?)",
        ),
        ("[refine]\ntolerance = 1e-8", "refine.levels: missing"),
        (
            "refine = 3",
            "refine: expected a table ([refine]), found an integer 3",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 150, steps = 5 }\n[refine]\nlevels = 2",
            "refine: the scene has 1 grid axes (axis.x.voltage); expected exactly two range axes",
        ),
        (
            "[mechanism]\nstatic_friction = [1.0, 2.0]\n\
             [axis.x]\nvoltage = { from = 0, to = 150, steps = 5 }\n\
             [axis.y]\nvoltage = { from = 0, to = 150, steps = 5 }\n[refine]\nlevels = 2",
            "refine: the scene has 3 grid axes",
        ),
        (
            "[axis.x]\nvoltage = [0.0, 50.0, 150.0]\n\
             [axis.y]\nvoltage = { from = 0, to = 150, steps = 5 }\n[refine]\nlevels = 2",
            "axis.x.voltage = [0.0, 50.0, 150.0]: [refine] needs a range { from, to, steps }",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 150, steps = 200000 }\n\
             [axis.y]\nvoltage = { from = 0, to = 150, steps = 5 }\n[refine]\nlevels = 10",
            "the finest grid would have more than",
        ),
        (
            "[refine]\nlevels = 2\n[[points]]\nlabel = \"a\"",
            "refine: a scene with [[points]] cannot be refined",
        ),
        // Ties and the frequency ratio.
        (
            "[axis.y]\nvoltage = { same_as = \"axis.x.frequency\" }",
            "axis.y.voltage.same_as = \"axis.x.frequency\": expected same_as = \"axis.x.voltage\" (the same key of the other axis)",
        ),
        (
            "[axis.y]\nvoltage = { same_as = \"axis.y.voltage\" }",
            "expected same_as = \"axis.x.voltage\"",
        ),
        (
            "[axis.y]\nstiffness = { same_as = \"axis.x.stiffness\" }",
            "axis.y.stiffness = { same_as = \"axis.x.stiffness\" }: only an axis' drive keys (gain, voltage, frequency, duty, phase, rise, hold, fall, slew_rate) can be tied",
        ),
        (
            "[simulation]\nsettle = { same_as = \"simulation.cycles\" }",
            "simulation.settle = { same_as = \"simulation.cycles\" }: only an axis' drive keys",
        ),
        (
            "[axis.y]\nvoltage = { same_as = 3 }",
            "axis.y.voltage.same_as: expected same_as = \"axis.x.voltage\" (the same key of the other axis), found an integer 3",
        ),
        (
            "[axis.y]\nvoltage = { same_as = \"axis.x.voltage\", steps = 3 }",
            "axis.y.voltage.steps: a tie takes only `same_as`",
        ),
        (
            "[axis.x]\nvoltage = { same_as = \"axis.y.voltage\" }",
            "axis.y.voltage is not given in the scene",
        ),
        (
            "[axis.x]\nvoltage = { same_as = \"axis.y.voltage\" }\n[axis.y]\nvoltage = { same_as = \"axis.x.voltage\" }",
            "axis.x.voltage and axis.y.voltage are tied to each other",
        ),
        (
            "[[points]]\naxis.y.voltage = { same_as = \"axis.x.voltage\" }",
            "points[0]: axis.y.voltage = { same_as = \"axis.x.voltage\" }: a point cannot tie keys",
        ),
        (
            "[axis.x]\nfrequency_ratio = 2",
            "axis.x.frequency_ratio: only axis.y takes a frequency ratio",
        ),
        (
            "[axis.y]\nfrequency = 5\nfrequency_ratio = 2",
            "axis.y.frequency_ratio and a frequency both set axis.y's drive frequency",
        ),
        (
            "[axis.y]\nfrequency = { same_as = \"axis.x.frequency\" }\nfrequency_ratio = 2",
            "axis.y.frequency_ratio and a tied frequency both set",
        ),
        (
            "[[points]]\naxis.y.frequency = 5\naxis.y.frequency_ratio = 2",
            "points[0]: axis.y.frequency_ratio and a frequency both set",
        ),
        (
            "[axis.y]\nfrequency_ratio = 0",
            "axis.y.frequency_ratio = 0: expected a number > 0",
        ),
        (
            "[axis.y]\nfrequency_ratio = 2000",
            "axis.y.frequency_ratio = 2000: expected a number from 0.001 to 1000",
        ),
        (
            "[axis.x]\nfrequency = [10, 5000]\n[axis.y]\nfrequency_ratio = { from = 1, to = 900, steps = 3 }",
            "axis.y.frequency = 4500000 (derived from axis.y.frequency_ratio x axis.x.frequency): expected a number from 0.001 to 1000000 Hz",
        ),
        (
            "[axis.x]\nfrequency = 0.001\n[[points]]\naxis.y.frequency_ratio = 0.5",
            "points[0]: axis.y.frequency = 0.0005 (derived from axis.y.frequency_ratio x axis.x.frequency): expected a number from 0.001",
        ),
    ];
    for (text, needle) in cases {
        check(text, needle);
        if std::env::var_os("PIDM_SHOW_ERRORS").is_some() {
            eprintln!("{}", Scene::from_toml(text, Some("test")).unwrap_err());
        }
    }
}

#[test]
fn a_scene_needs_a_name_from_text_or_file() {
    let error = Scene::from_toml("[axis.x]\nvoltage = 1", None).unwrap_err();
    assert!(error.to_string().contains("name: missing"), "{error}");
    let scene = Scene::from_toml("name = \"given\"", Some("stem")).unwrap();
    assert_eq!(scene.name, "given");
    let scene = Scene::from_toml("", Some("stem")).unwrap();
    assert_eq!(scene.name, "stem");
    let missing = shipped("no_such_scene.toml");
    match Scene::load(&missing) {
        Err(error @ SceneError::Io { .. }) => {
            assert!(error.to_string().contains("no_such_scene.toml"), "{error}")
        }
        other => panic!("expected an io error, got {other:?}"),
    }
}

/// Table 1's instance measured steady with the model's defaults: the
/// instance a scene gives when it sets nothing of `[simulation]`.
fn steady(instance: Instance) -> Instance {
    Instance {
        cycles: Measure::DEFAULT_MAX_CYCLES,
        settle: Measure::DEFAULT_SETTLE,
        measure: Measure::Steady {
            step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
        },
        ..instance
    }
}

#[test]
fn an_empty_scene_is_table_1_with_y_undriven() {
    let scene = parse("");
    assert_eq!(scene.shape(), Vec::<usize>::new());
    assert_eq!(scene.instance_count(), 1);
    assert_eq!(scene.instance(0), steady(Instance::TABLE1.baseline(0)));
    assert!(!scene.baselines);
    // A scene splits what it can; the library's default runs one chain.
    let settings = pidm::laws::Settings {
        replicas: pidm::laws::Replicas::Auto,
        ..Default::default()
    };
    assert_eq!(scene.settings, settings);
    assert!(scene.axis_ever_driven(0));
    assert!(!scene.axis_ever_driven(1));
}

#[test]
fn grid_axes_follow_file_order_and_instances_are_row_major() {
    let scene = parse(
        "[simulation]\n\
         measure = \"window\"\n\
         cycles = [10, 20]\n\
         tolerance = 1e-5\n\
         max_steps_per_period = 1000\n\
         [axis.y]\n\
         voltage = [0.0, 50.0, 100.0]\n\
         [mechanism]\n\
         slider_mass = 1e-3\n\
         [axis.x]\n\
         frequency = { from = 10, to = 40, steps = 4 }\n\
         duty = [0.5]\n",
    );
    let Layout::Grid { axes } = &scene.layout else {
        panic!("expected a grid");
    };
    let keys: Vec<&str> = axes.iter().map(|a| a.key.as_str()).collect();
    assert_eq!(
        keys,
        ["simulation.cycles", "axis.y.voltage", "axis.x.frequency"]
    );
    let units: Vec<&str> = axes.iter().map(|a| a.units).collect();
    assert_eq!(units, ["cycles", "V", "Hz"]);
    assert_eq!(scene.shape(), [2, 3, 4]);
    assert_eq!(scene.instance_count(), 24);
    assert_eq!(scene.settings.tolerance, 1e-5);
    assert_eq!(scene.settings.max_steps_per_period, 1000);
    for index in 0..24u64 {
        let (c, v, f) = (index / 12, index / 4 % 3, index % 4);
        let instance = scene.instance(index);
        assert_eq!(instance.cycles, [10, 20][c as usize]);
        assert_eq!(instance.axes[1].voltage, [0.0, 50.0, 100.0][v as usize]);
        assert_eq!(
            instance.axes[0].frequency,
            [10.0, 20.0, 30.0, 40.0][f as usize]
        );
        // A one-element list is a scalar, and y inherits x's frequency.
        assert_eq!(instance.axes[0].duty, 0.5);
        assert_eq!(instance.axes[1].frequency, instance.axes[0].frequency);
        assert_eq!(instance.mechanism.slider_mass, 1e-3);
        assert_eq!(instance.settle, 2);
    }
    assert!(scene.axis_ever_driven(1));
    let description = scene.describe();
    for needle in [
        "scene \"test\"",
        "2 x 3 x 4 = 24",
        "axis.x.frequency",
        "[10, 20] cycles",
    ] {
        assert!(
            description.contains(needle),
            "{needle:?} missing from\n{description}"
        );
    }
}

#[test]
fn ranges_give_the_right_values() {
    let scene = parse(
        "[axis.x]\n\
         voltage = { from = -150, to = 150, steps = 61 }\n\
         frequency = { from = 1, to = 1000, steps = 4, log = true }\n\
         phase = { from = 0.25, to = 0.25, steps = 1 }\n",
    );
    let Layout::Grid { axes } = &scene.layout else {
        panic!("expected a grid");
    };
    assert_eq!(axes.len(), 2);
    let expected: Vec<f64> = (0..61).map(|i| -150.0 + 5.0 * i as f64).collect();
    assert_eq!(axes[0].values, expected);
    let log = [1.0, 10.0, 100.0, 1000.0];
    for (value, want) in axes[1].values.iter().zip(log) {
        assert!(close(*value, want, 1e-12), "{value} != {want}");
    }
    assert_eq!(scene.instance(0).axes[0].phase, 0.25);
    assert!(!scene.axis_ever_driven(1));
}

#[test]
fn phases_of_a_whole_cycle_or_more_need_phase_units() {
    // A sweep over one whole period ends at 1: accepted as it is.
    let scene = parse("[axis.x]\nphase = { from = 0, to = 1, steps = 5 }\n");
    assert_eq!(scene.instance(4).axes[0].phase, 1.0);
    // Beyond one cycle, phase_units = "cycles" says whole cycles are meant.
    let scene = parse(
        "phase_units = \"cycles\"\n[axis.y]\nvoltage = 100\nphase = 90\n\
         [[points]]\naxis.x.phase = 2.5\n",
    );
    assert_eq!(scene.instance(0).axes[1].phase, 90.0);
    assert_eq!(scene.instance(0).axes[0].phase, 2.5);
}

#[test]
fn a_tied_key_takes_the_other_axis_value_in_every_instance() {
    // The same voltage on both axes, over a grid axis of the x voltage.
    let scene = parse(
        "[axis.x]\n\
         voltage = [40, 80, 120]\n\
         phase = 0.25\n\
         [axis.y]\n\
         voltage = { same_as = \"axis.x.voltage\" }\n\
         phase = { same_as = \"axis.x.phase\" }\n",
    );
    let Layout::Grid { axes } = &scene.layout else {
        panic!("a grid")
    };
    let keys: Vec<&str> = axes.iter().map(|a| a.key.as_str()).collect();
    assert_eq!(keys, ["axis.x.voltage"], "a tie is not a grid axis");
    for (index, volts) in [40.0, 80.0, 120.0].into_iter().enumerate() {
        let [x, y] = scene.instance(index as u64).axes;
        assert_eq!((x.voltage, y.voltage), (volts, volts));
        assert_eq!((x.phase, y.phase), (0.25, 0.25));
        assert!(scene.axis_ever_driven(1));
    }
    // A tie to axis.x's default voltage, and x tied to a given y.
    let scene = parse("[axis.y]\nvoltage = { same_as = \"axis.x.voltage\" }\n");
    assert_eq!(scene.instance(0).axes[1].voltage, Axis::TABLE1.voltage);
    let scene =
        parse("[axis.x]\nduty = { same_as = \"axis.y.duty\" }\n[axis.y]\nduty = [0.6, 0.8]\n");
    for (index, duty) in [0.6, 0.8].into_iter().enumerate() {
        let [x, y] = scene.instance(index as u64).axes;
        assert_eq!((x.duty, y.duty), (duty, duty));
    }
    // A point that gives the tied key replaces the tie; one that gives the
    // key tied to moves both.
    let scene = parse(
        "[axis.y]\nvoltage = { same_as = \"axis.x.voltage\" }\n\
         [[points]]\naxis.y.voltage = 7\n\
         [[points]]\naxis.x.voltage = 33\n",
    );
    assert_eq!(scene.instance(0).axes[1].voltage, 7.0);
    assert_eq!(scene.instance(0).axes[0].voltage, Axis::TABLE1.voltage);
    assert_eq!(scene.instance(1).axes[1].voltage, 33.0);
    assert_eq!(scene.instance(1).axes[0].voltage, 33.0);
}

#[test]
fn a_frequency_ratio_gives_the_y_drive_a_multiple_of_the_x_frequency() {
    let scene = parse(
        "[axis.x]\n\
         frequency = [10, 20]\n\
         [axis.y]\n\
         voltage = 100\n\
         frequency_ratio = { from = 0.5, to = 2, steps = 4 }\n",
    );
    let Layout::Grid { axes } = &scene.layout else {
        panic!("a grid")
    };
    assert_eq!(axes[1].key, "axis.y.frequency_ratio");
    assert_eq!(axes[1].units, "1");
    assert_eq!(scene.instance_count(), 8);
    for index in 0..8u64 {
        let [x, y] = scene.instance(index).axes;
        let ratio = axes[1].values[(index % 4) as usize];
        assert_eq!(x.frequency, [10.0, 20.0][(index / 4) as usize]);
        assert_eq!(y.frequency, ratio * x.frequency, "instance {index}");
    }
    // Over x's default frequency; a point giving a frequency replaces the
    // base's ratio, and a point's ratio replaces the base's frequency.
    let scene = parse(
        "[axis.y]\nfrequency_ratio = 1.4\n\
         [[points]]\naxis.y.frequency = 3\n\
         [[points]]\naxis.x.frequency = 20\n",
    );
    assert_eq!(scene.instance(0).axes[1].frequency, 3.0);
    assert_eq!(scene.instance(1).axes[1].frequency, 1.4 * 20.0);
    let scene = parse("[axis.y]\nfrequency = 3\n[[points]]\naxis.y.frequency_ratio = 2\n");
    assert_eq!(
        scene.instance(0).axes[1].frequency,
        2.0 * Axis::TABLE1.frequency
    );
}

#[test]
fn axis_y_inherits_x_but_not_its_voltage() {
    let scene = parse(
        "[axis.x]\n\
         stage_mass = 3e-3\n\
         stiffness = 2e6\n\
         damping = 1.5\n\
         gain = -0.5\n\
         voltage = 80\n\
         frequency = [10, 30]\n\
         duty = 0.9\n\
         phase = 0.1\n\
         [axis.y]\n\
         duty = 0.7\n",
    );
    for index in 0..2 {
        let [x, y] = scene.instance(index).axes;
        assert_eq!(y.voltage, 0.0);
        assert_eq!(y.duty, 0.7);
        assert_eq!(
            Axis {
                voltage: x.voltage,
                duty: x.duty,
                ..y
            },
            x
        );
    }
    assert_eq!(scene.instance(1).axes[1].frequency, 30.0);
}

#[test]
fn resonance_and_quality_give_the_text_parameters() {
    let scene = parse("[axis.x]\nresonance_hz = 1000\nquality_factor = 50\nstiffness = 1e6\n");
    let [x, y] = scene.instance(0).axes;
    for axis in [x, y] {
        assert!(close(axis.stage_mass, Axis::TEXT.stage_mass, 1e-12));
        assert!(close(axis.damping, Axis::TEXT.damping, 1e-12));
        assert_eq!(axis.stiffness, Axis::TEXT.stiffness);
    }

    // y overrides only the stiffness: its mass follows from x's resonance.
    let scene = parse(
        "[axis.x]\nresonance_hz = 1000\nquality_factor = 50\nstiffness = 1e6\n\
         [axis.y]\nstiffness = 4e6\n",
    );
    let y = scene.instance(0).axes[1];
    assert_eq!(y.stiffness, 4e6);
    assert!(close(y.stage_mass, 4.0 * Axis::TEXT.stage_mass, 1e-12));
    assert!(close(y.resonance_hz(), 1000.0, 1e-12));
    assert!(close(y.quality_factor(), 50.0, 1e-12));

    // y gives its own mass: it keeps x's resonance and its stiffness follows.
    let scene = parse(
        "[axis.x]\nresonance_hz = 1000\nstiffness = 1e6\n[axis.y]\nstage_mass = 1e-2\ndamping = 2\n",
    );
    let y = scene.instance(0).axes[1];
    assert!(close(y.resonance_hz(), 1000.0, 1e-12));
    assert_eq!((y.stage_mass, y.damping), (1e-2, 2.0));

    // A resonance with a mass gives the stiffness.
    let scene = parse("[axis.x]\nresonance_hz = 1000\nstage_mass = 2.533029591058444e-2\n");
    assert!(close(scene.instance(0).axes[0].stiffness, 1e6, 1e-12));

    // A grid over the resonance recomputes the derived mass per instance.
    let scene = parse("[axis.x]\nresonance_hz = [1000, 2000]\nquality_factor = 50\n");
    for (index, f_r) in [1000.0, 2000.0].into_iter().enumerate() {
        let [x, y] = scene.instance(index as u64).axes;
        assert!(close(x.resonance_hz(), f_r, 1e-12));
        assert!(close(x.quality_factor(), 50.0, 1e-12));
        assert_eq!(x.stiffness, Axis::TABLE1.stiffness);
        assert_eq!(
            Axis {
                voltage: x.voltage,
                ..y
            },
            x
        );
    }
}

#[test]
fn points_apply_on_top_of_the_base() {
    let scene = parse(
        "[axis.x]\nvoltage = 50\nduty = 0.9\n\
         [simulation]\nmeasure = \"window\"\n\
         [[points]]\nlabel = \"dotted\"\naxis.y.phase = 0.25\naxis.y.voltage = 20\n\
         [[points]]\n[points.axis.y]\nvoltage = 30\nfrequency = 20\n\
         [points.simulation]\ncycles = 5\nsettle = 1\n\
         [[points]]\nlabel = \"stage\"\naxis.x.quality_factor = 50\naxis.x.resonance_hz = 1000\n",
    );
    assert_eq!(scene.shape(), [3]);
    assert_eq!(scene.instance_count(), 3);
    let Layout::Points { labels } = &scene.layout else {
        panic!("expected points");
    };
    assert_eq!(labels, &["dotted", "", "stage"]);
    let first = scene.instance(0);
    assert_eq!((first.axes[0].voltage, first.axes[0].duty), (50.0, 0.9));
    assert_eq!(
        (
            first.axes[1].voltage,
            first.axes[1].phase,
            first.axes[1].duty
        ),
        (20.0, 0.25, 0.9)
    );
    assert_eq!(first.axes[0].phase, 0.0);
    let second = scene.instance(1);
    assert_eq!(
        (second.axes[1].voltage, second.axes[1].frequency),
        (30.0, 20.0)
    );
    assert_eq!(second.axes[0].frequency, 10.0);
    assert_eq!((second.cycles, second.settle), (5, 1));
    let third = scene.instance(2);
    assert!(close(
        third.axes[0].stage_mass,
        Axis::TEXT.stage_mass,
        1e-12
    ));
    assert!(close(third.axes[1].damping, Axis::TEXT.damping, 1e-12));
    assert_eq!(third.axes[1].voltage, 0.0);
    assert!(scene.axis_ever_driven(0) && scene.axis_ever_driven(1));
}

#[test]
fn memory_budget_names_shape_count_and_bytes() {
    let scene = Scene::load(&shipped("coupling.toml")).unwrap();
    assert!(scene.check_memory(MAP_MEMORY_BUDGET_BYTES).is_ok());
    let error = scene.check_memory(1000).unwrap_err();
    let message = error.to_string();
    for needle in [
        "61 x 61 = 3721 instances",
        // Six f64, five u32 and one u8 (motion) maps, two f64 and one u32
        // baselines: the bytes the result file holds per instance.
        "89 bytes",
        "331169 bytes",
        "1000 bytes",
    ] {
        assert!(
            message.contains(needle),
            "{needle:?} missing from {message}"
        );
    }
}

#[test]
fn trajectories_name_instances_by_label_index_or_grid_coordinates() {
    let grid = parse(
        "[axis.x]\nvoltage = { from = 0.0, to = 100.0, steps = 3 }\n\
         [axis.y]\nvoltage = [10.0, 20.0]\n\
         [output]\ntrajectory_samples_per_cycle = 40\n\
         trajectories = [5, { axis.y.voltage = 10.0, axis.x.voltage = 50.0 }, \
         { \"axis.x.voltage\" = 0.0, \"axis.y.voltage\" = 20.0 }]",
    );
    let got: Vec<(u64, &str)> = grid
        .trajectories
        .iter()
        .map(|t| (t.index, t.name.as_str()))
        .collect();
    assert_eq!(
        got,
        [
            (
                5,
                "instance 5 (axis.x.voltage = 100 V, axis.y.voltage = 20 V)"
            ),
            (
                2,
                "instance 2 (axis.x.voltage = 50 V, axis.y.voltage = 10 V)"
            ),
            (
                1,
                "instance 1 (axis.x.voltage = 0 V, axis.y.voltage = 20 V)"
            ),
        ]
    );
    assert_eq!(grid.trajectory_samples_per_cycle, 40);
    assert!(
        grid.describe()
            .contains("trajectories (40 samples per period)")
    );
    let points = parse(
        "[simulation]\nmax_cycles = 1000\n[output]\ntrajectories = [\"b\", 0]\n\
         [[points]]\naxis.x.voltage = 10\n[[points]]\nlabel = \"b\"",
    );
    let got: Vec<(u64, &str, &str)> = points
        .trajectories
        .iter()
        .map(|t| (t.index, t.label.as_str(), t.name.as_str()))
        .collect();
    assert_eq!(got, [(1, "b", "b"), (0, "", "point 0")]);
    assert_eq!(
        points.trajectory_samples_per_cycle,
        pidm::scene::DEFAULT_SAMPLES_PER_CYCLE
    );
    assert!(parse("").trajectories.is_empty());
    let window = parse("[simulation]\nmeasure = \"window\"\n[output]\ntrajectories = [{}]");
    assert_eq!(window.trajectories[0].index, 0);
}

#[test]
fn shipped_scenes_load() {
    let paper = Scene::load(&shipped("paper.toml")).unwrap();
    assert_eq!(paper.name, "paper");
    assert!(paper.baselines);
    assert_eq!(paper.shape(), [5]);
    let Layout::Points { labels } = &paper.layout else {
        panic!("expected points");
    };
    assert_eq!(
        labels,
        &["Fig. 5a", "Fig. 5b", "Fig. 6", "Fig. 7", "Fig. 8"]
    );
    let volts = [
        (100.0, 0.0),
        (100.0 / 2f64.sqrt(), 100.0 / 2f64.sqrt()),
        (100.0, 100.0),
        (100.0, 50.0),
        (100.0, 100.0),
    ];
    for (index, (vx, vy)) in volts.into_iter().enumerate() {
        let instance = paper.instance(index as u64);
        assert!(close(instance.axes[0].voltage, vx, 1e-15));
        assert!(close(instance.axes[1].voltage, vy, 1e-15));
        let expected = Instance::TABLE1;
        assert_eq!(instance.mechanism, expected.mechanism);
        assert_eq!((instance.cycles, instance.settle), (10, 2));
        let fy = if index == 4 { 20.0 } else { 10.0 };
        let [x, y] = instance.axes;
        assert_eq!(
            y,
            Axis {
                voltage: y.voltage,
                frequency: fy,
                ..Axis::TABLE1
            }
        );
        assert_eq!(
            x,
            Axis {
                voltage: x.voltage,
                ..Axis::TABLE1
            }
        );
    }
    assert_eq!(paper.instance(2), Instance::TABLE1);
    let recorded: Vec<(u64, &str)> = paper
        .trajectories
        .iter()
        .map(|t| (t.index, t.name.as_str()))
        .collect();
    assert_eq!(
        recorded,
        [
            (0, "Fig. 5a"),
            (1, "Fig. 5b"),
            (2, "Fig. 6"),
            (3, "Fig. 7"),
            (4, "Fig. 8")
        ]
    );

    let text = Scene::load(&shipped("paper_text.toml")).unwrap();
    assert_eq!(text.name, "paper_text");
    assert_eq!(text.shape(), [5]);
    for index in 0..5 {
        for axis in text.instance(index).axes {
            assert!(close(axis.stage_mass, Axis::TEXT.stage_mass, 1e-12));
            assert!(close(axis.damping, Axis::TEXT.damping, 1e-12));
            assert_eq!(axis.stiffness, 1e6);
        }
    }

    let coupling = Scene::load(&shipped("coupling.toml")).unwrap();
    assert_eq!(coupling.name, "coupling");
    assert!(coupling.baselines);
    assert_eq!(coupling.shape(), [61, 61]);
    assert_eq!(coupling.instance_count(), 61 * 61);
    let corner = coupling.instance(0);
    assert_eq!(
        (corner.axes[0].voltage, corner.axes[1].voltage),
        (-150.0, -150.0)
    );
    let next = coupling.instance(1);
    assert_eq!(
        (next.axes[0].voltage, next.axes[1].voltage),
        (-150.0, -145.0)
    );
    let center = coupling.instance(30 * 61 + 30);
    assert_eq!(center, steady(Instance::TABLE1.baseline(0).baseline(1)));
    assert!(coupling.axis_ever_driven(0) && coupling.axis_ever_driven(1));
    assert!(
        coupling
            .describe()
            .contains("61 values from -150 V to 150 V (linear, step 5)")
    );
}

/// A scene that sets nothing of `[simulation]` measures steady, with the
/// model's defaults: step tolerance 1e-8 m, at most 10000 periods, at least
/// 2 discarded.
#[test]
fn the_default_measurement_is_steady() {
    for text in ["", "[simulation]\nmeasure = \"steady\""] {
        let scene = parse(text);
        let instance = scene.instance(0);
        assert_eq!(
            instance.measure,
            Measure::Steady {
                step_tolerance: 1e-8
            },
            "{text}"
        );
        assert_eq!((instance.cycles, instance.settle), (10_000, 2), "{text}");
        let description = scene.describe();
        assert!(
            description.contains(
                "simulation: steady measurement, settle >= 2, step tolerance 1e-8 m, at most \
                 10000 periods"
            ),
            "{description}"
        );
    }
}

/// `measure = "window"` gives exactly the instances of the fixed window:
/// `cycles` and `settle` as given, 10 and 2 by default, so window maps stay
/// bit for bit.
#[test]
fn a_window_gives_the_fixed_window_instances() {
    let scene = parse("[simulation]\nmeasure = \"window\"");
    assert_eq!(scene.instance(0), Instance::TABLE1.baseline(0));
    assert_eq!(scene.instance(0).key(), Instance::TABLE1.baseline(0).key());
    assert!(
        scene
            .describe()
            .contains("simulation: window, cycles 10, settle 2")
    );
    let scene = parse(
        "[axis.y]\nvoltage = 100.0\n[simulation]\nmeasure = \"window\"\ncycles = 12\nsettle = 3",
    );
    let expected = Instance {
        cycles: 12,
        settle: 3,
        ..Instance::TABLE1
    };
    assert_eq!(scene.instance(0), expected);
    assert_eq!(scene.instance(0).key(), expected.key());
    // A window over the run length, and per point.
    let scene = parse("[simulation]\nmeasure = \"window\"\ncycles = [4, 8]\nsettle = 1");
    for (index, cycles) in [4, 8].into_iter().enumerate() {
        let instance = scene.instance(index as u64);
        assert_eq!(instance.measure, Measure::Window);
        assert_eq!((instance.cycles, instance.settle), (cycles, 1));
    }
    let scene =
        parse("[simulation]\nmeasure = \"window\"\n[[points]]\n[[points]]\nsimulation.cycles = 7");
    assert_eq!(scene.instance(0), Instance::TABLE1.baseline(0));
    assert_eq!(
        scene.instance(1),
        Instance {
            cycles: 7,
            ..Instance::TABLE1.baseline(0)
        }
    );
}

/// The steady keys are per instance like `cycles` and `settle`: grid axes
/// and points may set them.
#[test]
fn steady_keys_set_each_instance() {
    let scene = parse(
        "[simulation]\nmeasure = \"steady\"\nsettle = 5\n\
         step_tolerance = [1e-8, 1e-9]\nmax_cycles = { from = 100, to = 300, steps = 3 }",
    );
    let Layout::Grid { axes } = &scene.layout else {
        panic!("expected a grid");
    };
    let keys: Vec<(&str, &str)> = axes.iter().map(|a| (a.key.as_str(), a.units)).collect();
    assert_eq!(
        keys,
        [
            ("simulation.step_tolerance", "m"),
            ("simulation.max_cycles", "cycles")
        ]
    );
    assert_eq!(scene.shape(), [2, 3]);
    for index in 0..6u64 {
        let instance = scene.instance(index);
        let tolerance = [1e-8, 1e-9][(index / 3) as usize];
        assert_eq!(
            instance.measure,
            Measure::Steady {
                step_tolerance: tolerance
            }
        );
        assert_eq!(instance.cycles, [100, 200, 300][(index % 3) as usize]);
        assert_eq!(instance.settle, 5);
    }
    let description = scene.describe();
    for needle in [
        "simulation.step_tolerance  [1e-8, 1e-9] m",
        "simulation.max_cycles      [100, 200, 300] cycles",
        "simulation: steady measurement, settle >= 5, step tolerance 1e-8 m, at most 100 periods",
    ] {
        assert!(
            description.contains(needle),
            "{needle:?} missing from\n{description}"
        );
    }
    let scene = parse(
        "[simulation]\nmax_cycles = 400\n\
         [[points]]\n\
         [[points]]\nsimulation.step_tolerance = 1e-6\nsimulation.max_cycles = 20\n\
         simulation.settle = 0",
    );
    assert_eq!(
        scene.instance(0),
        Instance {
            cycles: 400,
            ..steady(Instance::TABLE1.baseline(0))
        }
    );
    assert_eq!(
        scene.instance(1),
        Instance {
            cycles: 20,
            settle: 0,
            measure: Measure::Steady {
                step_tolerance: 1e-6
            },
            ..Instance::TABLE1.baseline(0)
        }
    );
    // One period with none discarded is the shortest steady run.
    let one = parse("[simulation]\nmax_cycles = 1\nsettle = 0").instance(0);
    assert_eq!((one.cycles, one.settle), (1, 0));
}

/// `pidm random-scene` writes a scene that reads back as the very instances
/// it drew, bit for bit.
#[test]
fn random_scene_reads_back_bit_for_bit() {
    let (seed, count, cycles, settle) = (7, 5, 6, 2);
    let text = pidm::commands::random_scene(seed, count, cycles, settle).unwrap();
    assert!(text.contains("measure = \"window\""), "{text}");
    let scene = parse(&text);
    let drawn = pidm::model::random::random_instances(seed, count, cycles, settle);
    assert_eq!(scene.instance_count(), count as u64);
    for (k, inst) in drawn.iter().enumerate() {
        assert_eq!(scene.instance(k as u64).key(), inst.key(), "instance {k}");
    }
}

/// `pidm random-scene --count 0` is refused: a scene without points would
/// run one default instance.
#[test]
fn random_scene_refuses_no_instances() {
    let error = pidm::commands::random_scene(1, 0, 4, 1).unwrap_err();
    let message = error.to_string();
    assert!(
        message.contains("--count 0: expected at least 1 instance"),
        "{message}"
    );
}

/// The default name, the file stem, passes the same rule as `name`, and
/// the message says where it came from and how to give one.
#[test]
fn the_default_name_follows_the_name_rule() {
    for stem in [".hidden", "-rf", "a\u{1}b"] {
        let error = Scene::from_toml("", Some(stem)).unwrap_err().to_string();
        assert!(
            error.contains(&format!("name = {stem:?}: expected"))
                && error.contains("the default name, the scene file's stem")
                && error.contains("set `name = \"...\"` in the scene"),
            "{error}"
        );
        let given = Scene::from_toml("name = \"ok\"", Some(stem)).unwrap();
        assert_eq!(given.name, "ok");
    }
    let long = "a".repeat(pidm::scene::MAX_NAME_BYTES);
    assert_eq!(parse(&format!("name = \"{long}\"")).name, long);
    assert_eq!(parse("name = \"scan 2 (x, y)\"").name, "scan 2 (x, y)");
}

/// Scene files are read with a bound and must be text; each refusal names
/// the file.
#[test]
fn scene_files_are_bounded_text() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, bytes: &[u8]| {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    };
    // A regular file over the bound is refused by its size (sparse: no
    // disk is used).
    let big = dir.path().join("big.toml");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(MAX_SCENE_BYTES + 1)
        .unwrap();
    let cases: Vec<(PathBuf, String)> = vec![
        (
            big.clone(),
            format!("big.toml is larger than 16.0 MiB ({MAX_SCENE_BYTES} bytes)"),
        ),
        (
            write("nul.toml", b"name = \"a\"\0"),
            "nul.toml is not a text file: it holds a NUL byte at byte 10".to_owned(),
        ),
        (
            write("latin1.toml", b"# caf\xe9\n"),
            "latin1.toml is not a text file: it is not UTF-8 (invalid byte at byte 5)".to_owned(),
        ),
        (dir.path().to_owned(), "cannot read scene file".to_owned()),
    ];
    #[cfg(unix)]
    let cases = {
        let mut cases = cases;
        // A device that never ends is cut at the bound, not read forever.
        cases.push((
            PathBuf::from("/dev/zero"),
            "scene file /dev/zero is larger than 16.0 MiB".to_owned(),
        ));
        cases
    };
    for (path, needle) in &cases {
        match Scene::load(path) {
            Ok(_) => panic!("{} was accepted", path.display()),
            Err(error) => {
                let message = error.to_string();
                assert!(
                    message.contains(needle.as_str()),
                    "{message}\nlacks {needle:?}"
                );
            }
        }
    }
    let fine = write("fine.toml", "description = \"Grüße\"\n".as_bytes());
    assert_eq!(Scene::load(&fine).unwrap().name, "fine");
}

/// An error's message carries the underlying error once: no variant also
/// exposes it as its `source`, which `pidm` would print again as "caused
/// by". Checked on the library and on `pidm check` itself.
#[test]
fn errors_print_their_cause_once() {
    use std::error::Error as _;
    let syntax = Scene::from_toml("[axis.x]\nvoltage = = 3", Some("t")).unwrap_err();
    assert!(matches!(syntax, SceneError::Syntax { .. }));
    assert!(syntax.source().is_none());
    let missing = Scene::load(&shipped("no_such_scene.toml")).unwrap_err();
    assert!(missing.source().is_none());

    let dir = tempfile::tempdir().unwrap();
    let broken = dir.path().join("broken.toml");
    std::fs::write(&broken, "[axis.x]\nvoltage = = 3\n").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_pidm"))
        .arg("check")
        .arg(&broken)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        stderr.matches("TOML parse error at line 2").count(),
        1,
        "{stderr}"
    );
    assert!(!stderr.contains("caused by"), "{stderr}");
}

/// Every shipped scene stays within the bounds and loads.
#[test]
fn every_shipped_scene_validates() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("sweeps");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            if let Err(error) = Scene::load(&path) {
                panic!("{}: {error}", path.display());
            }
            count += 1;
        }
    }
    assert!(count >= 6, "only {count} scenes in {}", dir.display());
}

#[test]
fn a_refined_scene_is_its_finest_grid_with_the_coarse_one_inside() {
    let refined = parse(
        "[axis.x]\nvoltage = { from = -150, to = 150, steps = 5 }\n\
         [axis.y]\nfrequency = { from = 5, to = 40, steps = 3, log = true }\n\
         [refine]\nlevels = 2",
    );
    let uniform = parse(
        "[axis.x]\nvoltage = { from = -150, to = 150, steps = 17 }\n\
         [axis.y]\nfrequency = { from = 5, to = 40, steps = 9, log = true }",
    );
    let refine = refined.refine.expect("[refine] is read");
    assert_eq!(refine.levels, 2);
    assert_eq!(refine.tolerance, pidm::scene::DEFAULT_REFINE_TOLERANCE_M);
    assert_eq!(refine.coarse, [5, 3]);
    assert_eq!(refined.shape(), vec![17, 9]);
    assert_eq!(refined.layout, uniform.layout);
    // Every instance is the uniform finest grid's, bit for bit.
    for k in 0..refined.instance_count() {
        assert_eq!(refined.instance(k).key(), uniform.instance(k).key(), "{k}");
    }
    let tol = parse(
        "[axis.x]\nvoltage = { from = -150, to = 150, steps = 5 }\n\
         [axis.y]\nvoltage = { from = -150, to = 150, steps = 5 }\n\
         [refine]\nlevels = 1\ntolerance = 5e-8",
    );
    assert_eq!(tol.refine.unwrap().tolerance, 5e-8);
    assert!(uniform.refine.is_none());
}

/// docs/model.md section 7: a load whose magnitude |L| is the kinetic friction
/// or more is refused, naming the keys, their values and the reason; on a
/// grid the grid value that reaches it, before any work.
#[test]
fn loads_of_the_kinetic_friction_or_more_are_refused() {
    let reason = "a slider slipping along a load of the kinetic friction or more is not \
                  stopped by it and may run away (docs/model.md section 7)";
    let cases: &[(&str, &str)] = &[
        (
            "[mechanism]\nload_x = 1.0",
            "mechanism.load_x = 1: expected a load of magnitude |L| < the kinetic friction f_c \
             = 1 N (the default coulomb_friction)",
        ),
        (
            "[mechanism]\nload_x = 0.8\nload_y = -0.7",
            "mechanism.load_x = 0.8 and mechanism.load_y = -0.7 (|L| = 1.06301 N): expected",
        ),
        // A grid: the value of the grid that reaches f_c, and the corner
        // of two grids whose magnitude does.
        (
            "[mechanism]\nload_x = { from = -1.2, to = 0.5, steps = 5 }",
            "mechanism.load_x = -1.2: expected a load of magnitude |L| <",
        ),
        (
            "[mechanism]\nload_x = [-0.8, 0.0, 0.8]\nload_y = [0.0, 0.7]",
            "mechanism.load_x = -0.8 and mechanism.load_y = 0.7 (|L| = 1.06301 N)",
        ),
        // The kinetic friction a grid or a point gives.
        (
            "[mechanism]\ncoulomb_friction = [0.2, 1.0]\nload_y = 0.5",
            "mechanism.load_y = 0.5: expected a load of magnitude |L| < \
             mechanism.coulomb_friction = 0.2 N",
        ),
        (
            "[[points]]\nlabel = \"heavy\"\nmechanism = { load_y = -1.5 }",
            "points[0] (\"heavy\"): mechanism.load_y = -1.5: expected",
        ),
        (
            "[mechanism]\ncoulomb_friction = 0\nload_x = 0.01",
            "mechanism.load_x = 0.01: expected a load of magnitude |L| < \
             mechanism.coulomb_friction = 0 N",
        ),
        // The plausible range of the key itself.
        (
            "[mechanism]\nload_x = 2e9",
            "mechanism.load_x = 2000000000: expected a number from -1000000000 to 1000000000 N",
        ),
        (
            "[mechanism]\nload_y = nan",
            "mechanism.load_y = nan: expected a finite number",
        ),
    ];
    for (text, needle) in cases {
        check(text, needle);
        if needle.contains("|L| <") {
            check(text, reason);
        }
    }
    // Below f_c it is a load like any other: scalars, grids whose every
    // corner is inside the circle, points; and no load with no friction.
    for text in [
        "[mechanism]\nload_x = -0.99",
        "[mechanism]\nload_x = [-0.9, 0.9]\nload_y = [-0.4, 0.4]",
        "[[points]]\nmechanism = { load_x = 0.5, load_y = 0.5 }",
        "[mechanism]\ncoulomb_friction = 0",
    ] {
        parse(text);
    }
    let scene = parse("[mechanism]\nload_x = [-0.5, 0.25]\nload_y = 0.125");
    assert_eq!(scene.instance(1).mechanism.load, [0.25, 0.125]);
    assert_eq!(scene.instance(0).baseline(1).mechanism.load, [0.0, 0.125]);
}

/// `[stall]`: its keys and what a stall scene may not hold, each refusal
/// naming the key, the value and why.
#[test]
fn stall_scenes_are_checked() {
    let cases: &[(&str, &str)] = &[
        (
            "[stall]\ntolerance = 1e-3",
            "stall.axis: missing; expected \"x\" or \"y\"",
        ),
        (
            "[stall]\naxis = \"z\"",
            "stall.axis = \"z\": expected \"x\" or \"y\"",
        ),
        ("[stall]\naxis = 1", "stall.axis: expected a string"),
        (
            "[stall]\naxis = \"x\"\ntolerance = 0",
            "stall.tolerance = 0: expected a load in N, > 0",
        ),
        (
            "[stall]\naxis = \"x\"\ntol = 1",
            "unknown key `stall.tol` (did you mean `tolerance`?)",
        ),
        (
            "[mechanism]\nload_x = -0.1\n[stall]\naxis = \"x\"",
            "mechanism.load_x = -0.1: [stall] axis = \"x\" searches this load itself",
        ),
        (
            "[mechanism]\nload_y = [0.0, 0.1]\n[stall]\naxis = \"y\"",
            "mechanism.load_y = [0.0, 0.1]: [stall] axis = \"y\" searches this load itself",
        ),
        (
            "[stall]\naxis = \"x\"\n[[points]]\nlabel = \"p\"\nmechanism = { load_x = 0.1 }",
            "points[0] (\"p\"): mechanism.load_x = 0.1: [stall] axis = \"x\"",
        ),
        (
            "[axis.x]\nvoltage = { from = 0, to = 100, steps = 3 }\n\
             frequency = { from = 10, to = 20, steps = 3 }\n\
             [refine]\nlevels = 1\n[stall]\naxis = \"x\"",
            "refine: a scene with [stall] cannot be refined",
        ),
    ];
    for (text, needle) in cases {
        check(text, needle);
    }
    // The other axis' load may be anything below f_c, a grid axis too.
    let scene = parse("[mechanism]\nload_y = [-0.5, 0.5]\n[stall]\naxis = \"x\"\ntolerance = 1e-3");
    let stall = scene.stall.expect("a stall scene");
    assert_eq!((stall.axis, stall.tolerance), (0, 1e-3));
    assert_eq!(
        parse("[stall]\naxis = \"y\"").stall.unwrap().tolerance,
        1e-4
    );
    assert!(parse("name = \"plain\"").stall.is_none());
}

/// `[random]` lists the instances `pidm random-scene` writes as points, bit
/// for bit, labels included.
#[test]
fn a_random_table_lists_the_instances_random_scene_writes_as_points() {
    use pidm::commands::{random_scene, random_scene_compact};
    for (seed, count, cycles, settle) in [(7, 300, 4, 1), (3, 40, 10, 3), (0, 1, 2, 1)] {
        let points = parse(&random_scene(seed, count, cycles, settle).unwrap());
        let table = random_scene_compact(seed, count, cycles, settle).unwrap();
        assert!(table.len() < 400, "{table}");
        let compact = parse(&table);
        assert_eq!(compact.instance_count(), count as u64);
        assert_eq!(compact.layout, points.layout, "labels of seed {seed}");
        for i in 0..count as u64 {
            assert_eq!(
                format!("{:?}", compact.instance(i)),
                format!("{:?}", points.instance(i)),
                "seed {seed}, instance {i}"
            );
        }
    }
}

/// What does not apply beside `[random]` is refused, naming the key.
#[test]
fn a_random_table_refuses_what_does_not_apply() {
    let window = "name = \"r\"\n[simulation]\nmeasure = \"window\"\ncycles = 4\nsettle = 1\n";
    let with = |extra: &str| format!("{window}{extra}");
    check(
        &with("[random]\nseed = 1\n"),
        "random.count: missing; expected an integer",
    );
    check(
        &with("[random]\nseed = -1\ncount = 3\n"),
        "random.seed = -1: expected an integer from 0",
    );
    check(
        &with("[random]\nseed = 1\ncount = 0\n"),
        "random.count = 0: expected an integer from 1",
    );
    check(
        &with("[random]\nseed = 1\ncount = 2.5\n"),
        "random.count = 2.5",
    );
    check(
        &with("[random]\nseed = 1\ncount = 3\nsize = 3\n"),
        "unknown key `random.size`",
    );
    check(
        &with("[axis.x]\nvoltage = 100.0\n[random]\nseed = 1\ncount = 3\n"),
        "axis.x.voltage: a scene with [random] draws every mechanism and axis parameter",
    );
    check(
        &with("[mechanism]\nslider_mass = 0.01\n[random]\nseed = 1\ncount = 3\n"),
        "mechanism.slider_mass: a scene with [random] draws",
    );
    check(
        &with("[random]\nseed = 1\ncount = 3\n[[points]]\nlabel = \"a\"\n"),
        "cannot have [[points]]",
    );
    check(
        "name = \"r\"\n[random]\nseed = 1\ncount = 3\n",
        "expected [simulation] measure = \"window\"",
    );
    check(
        "name = \"r\"\n[simulation]\nmeasure = \"window\"\ncycles = 2\nsettle = 2\n\
         [random]\nseed = 1\ncount = 3\n",
        "settle",
    );
}
