//! [`Law`]: the one place outside a law's own folders that names the
//! friction laws. Scene parsing, planning, backends, replicas, fit,
//! commands and plots ask a `Law` what differs between laws (its keys, its
//! tolerance's meaning, its precisions, what `--backend auto` knows of it)
//! instead of branching on one; the device side's twin is
//! `crate::gpu` (its `mod.rs`). ARCHITECTURE.md's checklist says what a third law
//! touches.

use super::floor::variation::Variation;
use super::floor::{Record, Run};
use super::karnopp::integrate;
use super::observe::Observer;
use super::{Precision, Replica, Settings};
use super::{karnopp, lugre};
use crate::model::{Friction, Instance, Lugre, Mechanism};

/// A friction law at the slider's interface (`mechanism.friction`, one for
/// a whole scene; docs/model.md sections 3 and 8).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Law {
    /// Coulomb friction with stiction in Karnopp's form (the default):
    /// two modes, integrated in closed form with events located exactly.
    #[default]
    Karnopp,
    /// The 2-D LuGre bristle model: no modes, a stiff right-hand side,
    /// Rodas4 in f64.
    Lugre,
}

/// A fixed-step integration of an instance ([`Law::fixed_step_baseline`]):
/// the travel over the measured periods [m] at about `step` seconds per
/// step, and the steps taken.
pub type FixedStep = fn(inst: &Instance, step: f64) -> ([f64; crate::model::AXES], u64);

/// One of a law's own parameters, as `pidm check` and the result file
/// describe it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Parameter {
    /// The scene key, in `[mechanism]`.
    pub key: &'static str,
    /// Its value in SI units.
    pub value: f64,
    /// The unit of `value`.
    pub unit: &'static str,
    /// How the value was derived, where the scene did not give it.
    pub derived: Option<&'static str>,
}

impl Law {
    /// Every law, in the order messages list them.
    pub const ALL: [Law; 2] = [Law::Karnopp, Law::Lugre];

    /// The law's value of `mechanism.friction`.
    pub fn name(self) -> &'static str {
        match self {
            Law::Karnopp => "karnopp",
            Law::Lugre => "lugre",
        }
    }

    /// The law a value of `mechanism.friction` names.
    pub fn from_name(name: &str) -> Option<Law> {
        Law::ALL.into_iter().find(|law| law.name() == name)
    }

    /// The section of docs/model.md that defines the law.
    pub fn section(self) -> u32 {
        match self {
            Law::Karnopp => 3,
            Law::Lugre => 8,
        }
    }

    /// The law of an interface.
    pub fn of(friction: &Friction) -> Law {
        match friction {
            Friction::Karnopp => Law::Karnopp,
            Friction::Lugre(_) => Law::Lugre,
        }
    }

    /// The law of an instance's interface.
    pub fn of_instance(inst: &Instance) -> Law {
        Law::of(&inst.mechanism.friction)
    }

    /// The `[mechanism]` keys that apply to this law only: a scene with
    /// another law refuses them.
    pub fn keys(self) -> &'static [&'static str] {
        match self {
            Law::Karnopp => &["velocity_band"],
            Law::Lugre => &[
                "bristle_stiffness",
                "bristle_damping",
                "viscous_friction",
                "stribeck_velocity",
            ],
        }
    }

    /// Why [`Law::keys`] belong to this law, for the refusal of one of them
    /// in a scene of another law.
    pub fn keys_why(self) -> &'static str {
        match self {
            Law::Karnopp => {
                "the velocity band is Karnopp's stick detection, and LuGre has no modes \
                 (docs/model.md section 8)"
            }
            Law::Lugre => "the bristle keys belong to the LuGre model (docs/model.md section 8)",
        }
    }

    /// The interface of this law from the values of its own keys
    /// ([`Law::keys`] of LuGre, in that order; a NaN `bristle_damping` is
    /// derived). Karnopp's velocity band is the mechanism's own.
    pub fn friction(self, lugre: [f64; 4]) -> Friction {
        match self {
            Law::Karnopp => Friction::Karnopp,
            Law::Lugre => {
                let [
                    bristle_stiffness,
                    bristle_damping,
                    viscous_friction,
                    stribeck_velocity,
                ] = lugre;
                Friction::Lugre(Lugre {
                    bristle_stiffness,
                    bristle_damping: (!bristle_damping.is_nan()).then_some(bristle_damping),
                    viscous_friction,
                    stribeck_velocity,
                })
            }
        }
    }

    /// The law's own parameters of mechanism `m` (whose law this is).
    pub fn parameters(self, m: &Mechanism) -> Vec<Parameter> {
        let p = |key, value, unit| Parameter {
            key,
            value,
            unit,
            derived: None,
        };
        match &m.friction {
            Friction::Karnopp => vec![p("velocity_band", m.velocity_band, "m/s")],
            Friction::Lugre(l) => vec![
                p("bristle_stiffness", l.bristle_stiffness, "N/m"),
                Parameter {
                    derived: l
                        .bristle_damping
                        .is_none()
                        .then_some("derived: sqrt(bristle_stiffness slider_mass)"),
                    ..p("bristle_damping", l.damping(m.slider_mass), "N s/m")
                },
                p("viscous_friction", l.viscous_friction, "N s/m"),
                p("stribeck_velocity", l.stribeck_velocity, "m/s"),
            ],
        }
    }

    /// What `simulation.tolerance` = `tolerance` bounds under this law,
    /// after the number: Karnopp's direction error, or LuGre's local error
    /// per step (`laws::lugre::LENGTH_PER_TOLERANCE`).
    pub fn tolerance_unit(self, tolerance: f64) -> String {
        match self {
            Law::Karnopp => "rad".into(),
            Law::Lugre => format!(
                "(LuGre: {:e} m local error per step)",
                tolerance * lugre::LENGTH_PER_TOLERANCE
            ),
        }
    }

    /// The tolerance as `pidm accuracy` names its ladder.
    pub fn tolerance_setting(self) -> &'static str {
        match self {
            Law::Karnopp => "tolerance [rad]",
            Law::Lugre => "tolerance [x 0.1 um local error per step]",
        }
    }

    /// The law's integrator, as `pidm accuracy` names it.
    pub fn integrator(self) -> &'static str {
        match self {
            Law::Karnopp => "event-locating",
            Law::Lugre => "LuGre Rodas4",
        }
    }

    /// The paper's fixed-step RK4 of this law, where it exists
    /// (`laws::karnopp::paper_rk4`), a baseline for `pidm accuracy`: the
    /// slider's travel over the measured periods [m] at a step of about
    /// the given seconds, and the steps taken.
    pub fn fixed_step_baseline(self) -> Option<FixedStep> {
        match self {
            Law::Karnopp => Some(karnopp::paper_rk4::run_fixed_step),
            Law::Lugre => None,
        }
    }

    /// The margin of the f32 formulation's band graze in |v_rel|^2, in
    /// units of the band's square (`status::STATUS_GRAZE`), where the law
    /// has one.
    pub fn graze_margin(self) -> Option<f64> {
        match self {
            Law::Karnopp => Some(integrate::constants::GRAZE_MARGIN),
            Law::Lugre => None,
        }
    }

    /// Why the law has no f32 formulation, where it has none: every
    /// backend then integrates it in f64 and `--precision f32` is refused
    /// with this reason.
    pub fn no_f32(self) -> Option<&'static str> {
        match self {
            Law::Karnopp => None,
            Law::Lugre => Some(
                "LuGre friction (mechanism.friction = \"lugre\", docs/model.md section 8) runs \
                 in f64 only, on the CPU or on a GPU with f64; leave --precision out or give f64",
            ),
        }
    }

    /// Why `--backend auto` keeps the law's scenes on the CPU, where its
    /// cost model does not weigh them; `None` where it does.
    pub fn auto_on_cpu(self) -> Option<&'static str> {
        match self {
            Law::Karnopp => None,
            Law::Lugre => Some(
                "LuGre scenes stay on the CPU: the cost model is Karnopp's; --backend gpu \
                 runs the f64 LuGre shader",
            ),
        }
    }

    /// Whether a steady measurement under this law may be split into
    /// replicas at other phases of the faster drive (`simulation.replicas`,
    /// `crate::replicas`): every law's, as the phase ladder reads positions
    /// only.
    pub fn splits_by_phase(self) -> bool {
        true
    }

    /// Whether it may be split into pieces of its drives' common period,
    /// joined end to start: Karnopp's only, whose state at a period end is
    /// its positions and velocities; LuGre's bristles (z) would have to
    /// join too, and the join rules were measured on Karnopp's runs.
    pub fn splits_by_cycle(self) -> bool {
        self == Law::Karnopp
    }

    /// The law this law tends to in a limit of its own parameters (LuGre
    /// to Karnopp as the bristles stiffen, docs/model.md section 8).
    pub fn limit(self) -> Option<Law> {
        match self {
            Law::Karnopp => None,
            Law::Lugre => Some(Law::Karnopp),
        }
    }

    /// The instance whose law this law tends to in a limit of its
    /// parameters (LuGre to Karnopp as the bristles stiffen, docs/model.md
    /// section 8), for plots that draw the limit beside a map; `None` for
    /// a law that is no other's limit form.
    pub fn limit_of(inst: &Instance) -> Option<Instance> {
        let limit = Law::of_instance(inst).limit()?;
        let mut twin = *inst;
        twin.mechanism.friction = limit.friction([f64::NAN; 4]);
        Some(twin)
    }

    /// Integrates `inst` (of any law) in f64 to the end, or until `stop`
    /// says so (then `None`).
    pub fn run_until(inst: &Instance, settings: &Settings, stop: impl Fn() -> bool) -> Option<Run> {
        match Law::of_instance(inst) {
            Law::Karnopp => integrate::run_instance_until(inst, settings, stop).map(|r| r.ended()),
            Law::Lugre => lugre::run_instance_until(inst, settings, stop),
        }
    }

    /// [`Law::run_until`], keeping the slider's total variation beside
    /// the step's measurement (`crate::laws::floor::variation`): the same
    /// run, bit for bit, and its variation.
    pub fn run_with_variation_until(
        inst: &Instance,
        settings: &Settings,
        stop: impl Fn() -> bool,
    ) -> Option<(Run, Variation)> {
        match Law::of_instance(inst) {
            Law::Karnopp => {
                karnopp::variation::run_until(inst, settings, stop).map(|(run, v)| (run.ended(), v))
            }
            Law::Lugre => lugre::run::run_with_variation_until(inst, settings, stop),
        }
    }

    /// Integrates `inst` (of any law) on the CPU in `precision` to the end,
    /// or until `stop` says so (then `None`), with the f32 status that sent
    /// an f32 run to the f64 reference, if one did. A law without f32
    /// ([`Law::no_f32`]) integrates in f64 whatever was asked (the backend
    /// selection refuses f32 for its scenes).
    pub fn run_in_until(
        inst: &Instance,
        settings: &Settings,
        precision: Precision,
        stop: impl Fn() -> bool + Copy,
    ) -> Option<(Run, Option<u32>)> {
        match Law::of_instance(inst) {
            Law::Karnopp => karnopp::run_in_until(inst, settings, precision, stop)
                .map(|(run, sent)| (run.ended(), sent)),
            Law::Lugre => lugre::run_instance_until(inst, settings, stop).map(|run| (run, None)),
        }
    }

    /// Integrates `inst` (of any law) in f64 to its end, showing `observer`
    /// every step's motion (`crate::trajectory`), and returns the record it
    /// ends with: the map run's, bit for bit.
    pub fn run_observed(
        inst: &Instance,
        settings: &Settings,
        observer: &mut dyn Observer,
    ) -> Record {
        match Law::of_instance(inst) {
            Law::Karnopp => karnopp::run_observed(inst, settings, observer).record(),
            Law::Lugre => lugre::run::run_observed(inst, settings, observer),
        }
    }

    /// The profile table's lines of the CPU integrators' iterations by kind
    /// (Karnopp's, both precisions together); empty where none were
    /// counted (LuGre's integrator is not counted).
    pub fn iteration_lines() -> String {
        karnopp::iteration_lines()
    }
}

/// A run of either law that stops where a replica waits for its group's
/// merge (`measure::VERDICT_WAITING`) and goes on once released: the
/// replicas of a split steady measurement (`crate::replicas`). Where the
/// settings ask for the backward travel (`Settings::backward`) it keeps
/// the slider's total variation beside the step's measurement, as
/// [`Law::run_with_variation_until`] does: the same run, bit for bit.
pub enum Resumable {
    Karnopp(Box<KarnoppRun>),
    Lugre(Box<lugre::run::Resumable>),
}

/// A Karnopp replica's coefficients, run so far, and its variation
/// where it keeps one.
pub struct KarnoppRun {
    c: integrate::Coefficients,
    run: integrate::Run,
    variation: Option<Variation>,
}

impl Resumable {
    /// Replica `r` of a split run at rest (`inst` the replica's instance).
    pub fn start(inst: &Instance, settings: &Settings, r: Replica) -> Resumable {
        match Law::of_instance(inst) {
            Law::Karnopp => {
                let c = integrate::Coefficients::of_replica(inst, settings, r);
                let run = integrate::Run {
                    state: integrate::initial_state(&c),
                    measure: integrate::initial_measure(&c),
                };
                let variation = settings.backward.then(|| Variation::new(&c));
                Resumable::Karnopp(Box::new(KarnoppRun { c, run, variation }))
            }
            Law::Lugre => Resumable::Lugre(Box::new(lugre::run::Resumable::new(inst, settings, r))),
        }
    }

    /// Replica `r` where `run` stands: a Karnopp run a GPU batch handed
    /// over (`gpu::groups`; LuGre's lanes run no groups, and no lane keeps
    /// the variation).
    pub fn of_run(
        inst: &Instance,
        settings: &Settings,
        r: Replica,
        run: integrate::Run,
    ) -> Resumable {
        assert_eq!(
            Law::of_instance(inst),
            Law::Karnopp,
            "only Karnopp's lanes hand groups over"
        );
        assert!(
            !settings.backward,
            "the GPU does not measure the backward travel"
        );
        let c = integrate::Coefficients::of_replica(inst, settings, r);
        Resumable::Karnopp(Box::new(KarnoppRun {
            c,
            run,
            variation: None,
        }))
    }

    /// Integrates to the run's end or its next wait (true), or until
    /// `stop` returns true (false).
    pub fn advance(&mut self, stop: impl Fn() -> bool) -> bool {
        match self {
            Resumable::Karnopp(k) => {
                let ran = match k.variation.as_mut() {
                    Some(v) => karnopp::variation::continue_until(&k.c, k.run, v, stop),
                    None => integrate::continue_until(&k.c, k.run, stop),
                };
                ran.map(|run| k.run = run).is_some()
            }
            Resumable::Lugre(l) => l.advance(stop),
        }
    }

    /// The run so far.
    pub fn run(&self) -> Run {
        match self {
            Resumable::Karnopp(k) => k.run.ended(),
            Resumable::Lugre(l) => *l.run(),
        }
    }

    /// The slider's total variation so far, where the run keeps it.
    pub fn variation(&self) -> Option<&Variation> {
        match self {
            Resumable::Karnopp(k) => k.variation.as_ref(),
            Resumable::Lugre(l) => l.variation(),
        }
    }

    /// Lets the run go on if it waits for its group's merge.
    pub fn release(&mut self) {
        match self {
            Resumable::Karnopp(k) => {
                let run = &mut k.run;
                super::floor::record::release(&mut run.state, &mut run.measure);
                if let Some(v) = k.variation.as_mut() {
                    v.release();
                }
            }
            Resumable::Lugre(l) => l.release(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each law's name reads back as the law, and each key belongs to one
    /// law only.
    #[test]
    fn names_and_keys_are_one_law_each() {
        for law in Law::ALL {
            assert_eq!(Law::from_name(law.name()), Some(law));
            for key in law.keys() {
                let owners = Law::ALL.iter().filter(|l| l.keys().contains(key)).count();
                assert_eq!(owners, 1, "{key}");
            }
        }
        assert_eq!(Law::from_name("coulomb"), None);
        assert_eq!(Law::default().name(), "karnopp");
    }

    /// An interface built from a law's key values is of that law.
    #[test]
    fn friction_is_of_its_law() {
        for law in Law::ALL {
            assert_eq!(Law::of(&law.friction([1e7, f64::NAN, 0.0, 1e-3])), law);
        }
    }
}
