//! The human summary of a scene (`pidm check`): [`Scene::describe`].

use std::fmt::Write as _;

use super::format::{fmt_short, human_bytes};
use super::{Layout, Scene};
use crate::laws::Law;
use crate::model::{AXIS_NAMES, Instance, Measure};

impl Scene {
    /// A multi-line human summary: name, grid axes or points, instance
    /// count, baselines, settings and the first instance's parameters.
    pub fn describe(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "scene {:?}", self.name);
        if let Some(description) = &self.description {
            let _ = writeln!(out, "  {}", description.trim());
        }
        self.write_layout(&mut out);
        self.write_searches(&mut out);
        self.write_settings(&mut out);
        if self.instance_count() > 0 {
            write_first_instance(&mut out, &self.instance(0));
        }
        out
    }

    /// The summary's layout: "single instance", the grid's axes and their
    /// values, or the points with their labels and keys.
    fn write_layout(&self, out: &mut String) {
        let count = self.instance_count();
        match &self.layout {
            Layout::Grid { axes } if axes.is_empty() => {
                let _ = writeln!(out, "single instance");
            }
            Layout::Grid { axes } => {
                let dims: Vec<String> = axes.iter().map(|a| a.values.len().to_string()).collect();
                let _ = writeln!(
                    out,
                    "grid {} = {count} instances (row-major, last axis fastest):",
                    dims.join(" x ")
                );
                let width = axes.iter().map(|a| a.key.len()).max().unwrap_or(0);
                for axis in axes {
                    let _ = writeln!(
                        out,
                        "  {:width$}  {}",
                        axis.key,
                        describe_values(&axis.values, axis.units)
                    );
                }
            }
            Layout::Points { labels } => {
                let _ = writeln!(out, "{count} points:");
                for (i, (label, keys)) in labels.iter().zip(&self.point_keys).enumerate() {
                    let label = if label.is_empty() {
                        String::new()
                    } else {
                        format!("{label}: ")
                    };
                    let _ = writeln!(out, "  [{i}] {label}{keys}");
                }
            }
        }
    }

    /// The summary's lines on the adaptive refinement and the stall search,
    /// where the scene has them.
    fn write_searches(&self, out: &mut String) {
        if let Some(refine) = &self.refine {
            let _ = writeln!(
                out,
                "refined adaptively: a {} x {} coarse grid, {} levels, tolerance {:e} m; only \
                 the points near regime changes are integrated (the cost below is that of \
                 the whole finest grid, an upper bound)",
                refine.coarse[0], refine.coarse[1], refine.levels, refine.tolerance
            );
        }
        if let Some(stall) = &self.stall {
            let a = AXIS_NAMES[stall.axis];
            let _ = writeln!(
                out,
                "stall search along {a}: for every instance the load along {a}, against its \
                 unloaded step, at which the {a} step stops, within {} N, by bracketing ({} \
                 probes at most) and bisection in waves (each instance integrates 1 + the \
                 probes it needs: 8.1 on average on sweeps/stall.toml, 14.3 where the step is \
                 not 0; the cost below is the unloaded run's alone)",
                fmt_short(stall.tolerance),
                super::stall::BRACKET.len()
            );
        }
    }

    /// The summary's scene-wide settings: baselines, trajectories, the
    /// integrator, replicas (steady scenes) and the size of the output maps.
    fn write_settings(&self, out: &mut String) {
        let _ = writeln!(
            out,
            "baselines: {}",
            if self.baselines {
                "yes (the two 1-DOF runs of every instance)"
            } else {
                "no"
            }
        );
        if self.settings.backward {
            let _ = writeln!(
                out,
                "backward travel: yes (/maps/backward_* and backward_ratio_*, on the CPU in f64, \
                 each instance a run of its own)"
            );
        }
        if !self.trajectories.is_empty() {
            let names: Vec<&str> = self.trajectories.iter().map(|t| t.name.as_str()).collect();
            let _ = writeln!(
                out,
                "trajectories ({} samples per period): {}",
                self.trajectory_samples_per_cycle,
                names.join("; ")
            );
        }
        let _ = writeln!(
            out,
            "integrator: {}, at most {} steps per period",
            self.tolerance_text(),
            self.settings.max_steps_per_period
        );
        if self.plan.mode == super::keys::Mode::Steady {
            let _ = writeln!(
                out,
                "replicas: {} (split steady measurements whose phase ladder is on)",
                match self.settings.replicas {
                    _ if self.settings.backward => "1, none (output.backward)".to_string(),
                    crate::laws::settings::Replicas::Auto => {
                        "auto, as many as idle threads or lanes allow".to_string()
                    }
                    crate::laws::settings::Replicas::Count(1) => "1, none".to_string(),
                    crate::laws::settings::Replicas::Count(n) => format!("{n} per instance"),
                }
            );
        }
        let bytes = self.instance_count() as u128 * self.bytes_per_instance() as u128;
        let human = human_bytes(bytes as f64);
        if bytes < 1024 {
            let _ = writeln!(out, "output maps: {human}");
        } else {
            let _ = writeln!(out, "output maps: {human} ({bytes} bytes)");
        }
    }
}

/// The summary's "instance 0:" block: the mechanism (its load only where
/// there is one), each axis and the measurement.
fn write_first_instance(out: &mut String, first: &Instance) {
    let m = first.mechanism;
    let _ = writeln!(out, "instance 0:");
    // The load only where there is one: unloaded scenes read as
    // they did before it existed.
    let load = if m.load == [0.0; 2] {
        String::new()
    } else {
        format!(
            ", load_x {} N, load_y {} N",
            fmt_short(m.load[0]),
            fmt_short(m.load[1])
        )
    };
    // Karnopp's band, or LuGre's parameters (docs/model.md section 8).
    let law = match Law::of(&m.friction) {
        law if law == Law::default() => law_parameters(&m),
        law => format!("friction {}: {}", law.name(), law_parameters(&m)),
    };
    let _ = writeln!(
        out,
        "  mechanism: slider_mass {} kg, static_friction {} N, coulomb_friction {} N, {law}{load}",
        fmt_short(m.slider_mass),
        fmt_short(m.static_friction),
        fmt_short(m.coulomb_friction),
    );
    for (axis, name) in first.axes.iter().zip(AXIS_NAMES) {
        let _ = writeln!(
            out,
            "  axis.{name}: stage_mass {} kg, stiffness {} N/m, damping {} N s/m \
             (resonance {:.4} Hz, Q {:.4}), gain {} N/V, voltage {} V, frequency {} Hz, \
             {}, phase {} cycles",
            fmt_short(axis.stage_mass),
            fmt_short(axis.stiffness),
            fmt_short(axis.damping),
            axis.resonance_hz(),
            axis.quality_factor(),
            fmt_short(axis.gain),
            fmt_short(axis.voltage),
            fmt_short(axis.frequency),
            drive_words(axis),
            fmt_short(axis.phase)
        );
    }
    let _ = writeln!(out, "  simulation: {}", describe_measure(first));
}

/// An axis' waveform and slew limit in words: "duty 0.98", "trapezoid
/// rise 0.3, hold 0, fall 0.1", "table of 4 entries", each with ", slew
/// rate 1e5 V/s" where the amplifier limits it.
pub fn drive_words(axis: &crate::model::Axis) -> String {
    use crate::model::Shape;
    let shape = match axis.shape {
        Shape::Sawtooth => format!("duty {}", fmt_short(axis.duty)),
        Shape::Trapezoid => format!(
            "trapezoid rise {}, hold {}, fall {}",
            fmt_short(axis.rise),
            fmt_short(axis.hold),
            fmt_short(axis.fall)
        ),
        Shape::Table(table) => format!("table of {} entries", table.entries().len()),
    };
    if axis.slew_rate == crate::model::NO_SLEW_LIMIT {
        shape
    } else {
        format!("{shape}, slew rate {} V/s", fmt_short(axis.slew_rate))
    }
}

/// How an instance is measured, for the summary: "window, cycles 10,
/// settle 2" or "steady measurement, settle >= 2, step tolerance 1e-8 m, at
/// most 10000 periods".
pub(super) fn describe_measure(instance: &Instance) -> String {
    match instance.measure {
        Measure::Window => format!(
            "window, cycles {}, settle {}",
            instance.cycles, instance.settle
        ),
        Measure::Steady { step_tolerance } => format!(
            "steady measurement, settle >= {}, step tolerance {} m, at most {} periods",
            instance.settle,
            fmt_short(step_tolerance),
            instance.cycles
        ),
    }
}

/// Describes the values of a grid axis: all of them when few, else the
/// count, ends and spacing.
pub(super) fn describe_values(values: &[f64], units: &str) -> String {
    let unit = if units == "1" {
        String::new()
    } else {
        format!(" {units}")
    };
    let n = values.len();
    if n <= 6 {
        let list: Vec<String> = values.iter().map(|&v| fmt_short(v)).collect();
        return format!("[{}]{unit}", list.join(", "));
    }
    let (first, last) = (values[0], values[n - 1]);
    let step = (last - first) / (n - 1) as f64;
    let linear = values
        .iter()
        .enumerate()
        .all(|(i, &v)| (v - (first + step * i as f64)).abs() <= 1e-9 * first.abs().max(last.abs()));
    let spacing = if linear {
        format!("linear, step {}", fmt_short(step))
    } else if first > 0.0 && last > 0.0 {
        let ratio = (last / first).powf(1.0 / (n - 1) as f64);
        let log = values
            .iter()
            .enumerate()
            .all(|(i, &v)| (v / (first * ratio.powi(i as i32)) - 1.0).abs() <= 1e-9);
        if log {
            format!("log, ratio {ratio:.6}")
        } else {
            "list".to_owned()
        }
    } else {
        "list".to_owned()
    };
    format!(
        "{n} values from {}{unit} to {}{unit} ({spacing})",
        fmt_short(first),
        fmt_short(last)
    )
}

/// The friction law's own parameters of mechanism `m` ([`Law::parameters`]),
/// as `pidm check` and the result file's `friction_parameters` write them.
pub(crate) fn law_parameters(m: &crate::model::Mechanism) -> String {
    let parts: Vec<String> = Law::of(&m.friction)
        .parameters(m)
        .iter()
        .map(|p| {
            let derived = p.derived.map(|d| format!(" ({d})")).unwrap_or_default();
            format!("{} {} {}{derived}", p.key, fmt_short(p.value), p.unit)
        })
        .collect();
    parts.join(", ")
}
