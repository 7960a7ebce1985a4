//! The WGSL source of the integrator and its per-variant prelude.
//!
//! `shaders/karnopp/*.wgsl` is written against a `Real` type, a `V2`
//! vector of two `Real`s, the integrator's constants and a few arithmetic
//! helpers; the prelude defines them for one [`Variant`]. The constants come
//! from [`crate::laws::karnopp::integrate::constants`], the one place they are
//! written. Every shader file but `entry.wgsl` mirrors the Rust file of the
//! same name in `src/laws/karnopp/integrate/` (`advance.wgsl` mirrors `mod.rs`).

use crate::gpu::prelude::read_where_used;
use crate::gpu::{GpuError, Precision, STATUS_LOOP_LIMIT, workgroup_size};
use crate::laws::Settings;
use crate::laws::floor::Vec2;
use crate::laws::karnopp::integrate::Coefficients;
use crate::laws::karnopp::integrate::constants::{self, TAYLOR_STAGE_TERMS, TAYLOR_TERMS};
use crate::model::Instance;

/// The shader files, in the order they are concatenated (WGSL declarations
/// may come in any order; this one reads top-down), with their text and
/// the part of the shader each belongs to (`File::part`).
pub const FILES: [(&str, &str); 16] = [
    (
        "karnopp/arith.wgsl",
        include_str!("../../../shaders/karnopp/arith.wgsl"),
    ),
    (
        "shared/setup.wgsl",
        include_str!("../../../shaders/shared/setup.wgsl"),
    ),
    (
        "karnopp/coefficients.wgsl",
        include_str!("../../../shaders/karnopp/coefficients.wgsl"),
    ),
    (
        "karnopp/flow.wgsl",
        include_str!("../../../shaders/karnopp/flow.wgsl"),
    ),
    (
        "karnopp/drive.wgsl",
        include_str!("../../../shaders/karnopp/drive.wgsl"),
    ),
    (
        "karnopp/segments.wgsl",
        include_str!("../../../shaders/karnopp/segments.wgsl"),
    ),
    (
        "karnopp/events.wgsl",
        include_str!("../../../shaders/karnopp/events.wgsl"),
    ),
    (
        "karnopp/step.wgsl",
        include_str!("../../../shaders/karnopp/step.wgsl"),
    ),
    (
        "karnopp/advance.wgsl",
        include_str!("../../../shaders/karnopp/advance.wgsl"),
    ),
    (
        "shared/measure.wgsl",
        include_str!("../../../shaders/shared/measure.wgsl"),
    ),
    (
        "shared/phase.wgsl",
        include_str!("../../../shaders/shared/phase.wgsl"),
    ),
    (
        "karnopp/steady.wgsl",
        include_str!("../../../shaders/karnopp/steady.wgsl"),
    ),
    (
        "shared/variation.wgsl",
        include_str!("../../../shaders/shared/variation.wgsl"),
    ),
    (
        "shared/pieces.wgsl",
        include_str!("../../../shaders/shared/pieces.wgsl"),
    ),
    (
        "karnopp/variation.wgsl",
        include_str!("../../../shaders/karnopp/variation.wgsl"),
    ),
    (
        "karnopp/entry.wgsl",
        include_str!("../../../shaders/karnopp/entry.wgsl"),
    ),
];

/// Where a lane holds a step's flow and samples: in private variables
/// (registers), or, for an f64 hardware lane, in device memory read where
/// used (bindings 9 to 11; [`Variant::holds_in_memory`]).
const HOLDERS: [(&str, &str); 2] = [
    (
        "karnopp/hold_registers.wgsl",
        include_str!("../../../shaders/karnopp/hold_registers.wgsl"),
    ),
    (
        "karnopp/hold_memory.wgsl",
        include_str!("../../../shaders/karnopp/hold_memory.wgsl"),
    ),
];

/// Where an f64 hardware lane holds a step's flow, samples and
/// propagators, one entry per lane, the one home of each: its binding
/// (after the engine's 0 to 8), the private variable of
/// `hold_registers.wgsl` that this variant reads instead, the storage
/// buffer [`source`] declares for it and the struct of its entries.
pub const HELD_IN_MEMORY: [(u32, &str, &str, &str); 3] = [
    (9, "flow", "flows", "Flow"),
    (10, "samples", "step_samples", "Samples"),
    (11, "props", "step_props", "SamplePropagators"),
];

/// Each buffer of [`HELD_IN_MEMORY`] with the bytes of its entry, a lane's,
/// from the shader's own layout of its struct, where `variant` holds a
/// step in device memory; none elsewhere.
pub fn per_lane(variant: Variant) -> &'static [(u32, u64)] {
    static HELD: std::sync::OnceLock<Vec<(u32, u64)>> = std::sync::OnceLock::new();
    if !variant.holds_in_memory() {
        return &[];
    }
    HELD.get_or_init(|| {
        let (module, _) = parse_and_validate(variant).expect("the f64 hardware shader validates");
        let mut layouter = naga::proc::Layouter::default();
        layouter
            .update(module.to_ctx())
            .expect("the shader's types have a layout");
        HELD_IN_MEMORY
            .iter()
            .map(|&(binding, _, _, name)| {
                let (handle, _) = module
                    .types
                    .iter()
                    .find(|(_, t)| t.name.as_deref() == Some(name))
                    .expect("the held struct is declared");
                let l = layouter[handle];
                (binding, l.to_stride() as u64)
            })
            .collect()
    })
}

/// The name of the compute entry point.
pub const ENTRY_POINT: &str = "advance_slice";

/// The optional parts of the shader: a pipeline carries a part only where
/// a batch's instances use it, so the driver compiles, and the device
/// reserves registers for, only what the scene needs (issue 38). Whatever a
/// variant leaves out, the instances it runs give the results of the whole
/// shader, bit for bit (`tests/it/variants.rs`). Trajectories are never the
/// shader's: the f64 CPU integrator records them (`crate::trajectory`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Parts {
    /// Steady measurements (`measure.wgsl`, `steady.wgsl`: the per-period
    /// bookkeeping, the accumulators and heads buffers).
    pub steady: bool,
    /// The phase ladder of two-frequency steady measurements
    /// (`phase.wgsl`); only with `steady`.
    pub phase: bool,
    /// A load on the slider (docs/model.md section 7): without it the load terms
    /// are the +0 they are at zero load, folded by the compiler.
    pub load: bool,
    /// A drive other than a sawtooth (issue 59: a trapezoid, a table, a
    /// slew limit): its segments from a buffer (`segments.wgsl`, binding
    /// 12); without it the sawtooth's rise and fall from the coefficients.
    pub waveform: bool,
    /// The backward travel (`Settings::backward`, issue 59:
    /// `variation.wgsl`): every step's total variation and its
    /// accumulators in the second half of the measures buffer. Only with
    /// `steady`, whose accumulators it follows and whose buffer it shares
    /// (a window instance's variation needs its entry too).
    pub backward: bool,
}

impl Parts {
    /// Every part an instance may need: the whole shader but the backward
    /// travel, which a run's settings ask for ([`Parts::with_settings`]).
    pub const ALL: Parts = Parts {
        steady: true,
        phase: true,
        load: true,
        waveform: true,
        backward: false,
    };

    /// Every combination instances may need (`phase` only with
    /// `steady`); the backward travel, a run's setting, is
    /// [`Parts::with_backward`]'s.
    pub fn every() -> Vec<Parts> {
        let mut out = Vec::new();
        for steady in [false, true] {
            for phase in [false, true] {
                for load in [false, true] {
                    for waveform in [false, true] {
                        if phase && !steady {
                            continue;
                        }
                        out.push(Parts {
                            steady,
                            phase,
                            load,
                            waveform,
                            backward: false,
                        });
                    }
                }
            }
        }
        out
    }

    /// Every combination with the backward travel (f64 only): those of
    /// [`Parts::every`] that it leaves (it takes the steady and waveform
    /// parts: [`Parts::with_settings`]).
    pub fn with_backward() -> Vec<Parts> {
        let backward = Settings {
            backward: true,
            ..Settings::default()
        };
        let mut out: Vec<Parts> = Parts::every()
            .into_iter()
            .map(|p| p.with_settings(&backward))
            .collect();
        out.sort();
        out.dedup();
        out
    }

    /// The parts both need.
    pub fn union(self, other: Parts) -> Parts {
        Parts {
            steady: self.steady || other.steady,
            phase: self.phase || other.phase,
            load: self.load || other.load,
            waveform: self.waveform || other.waveform,
            backward: self.backward || other.backward,
        }
    }

    /// These parts and the backward travel where `settings` measure it,
    /// which takes the steady part ([`Parts::backward`]) and the waveform
    /// part: its pipelines read every drive, a sawtooth's too, from the
    /// segment buffer. With the sawtooth's own corners the f64 hardware
    /// lane asked 257-261 VGPRs and spilled 3-6 (RADV, navi31); with the
    /// segments 241-245 and none (`pidm info --registers`).
    pub fn with_settings(self, settings: &Settings) -> Parts {
        if !settings.backward {
            return self;
        }
        Parts {
            steady: true,
            waveform: true,
            backward: true,
            ..self
        }
    }

    /// Whether a variant with these parts runs everything `needs` asks
    /// for, and measures the backward travel exactly where it asks (a
    /// variant that measures it keeps a second half of accumulators and
    /// reads it back: work a run without it does not pay for).
    pub fn covers(self, needs: Parts) -> bool {
        self.union(needs) == self && self.backward == needs.backward
    }

    /// The parts an instance's f64 coefficients use (what the shader would
    /// read of them): a steady measurement, the phase ladder (levels that
    /// may stop the run), a non-zero load term.
    pub fn of_coefficients(c: &Coefficients) -> Parts {
        let nonzero = |v: Vec2| v.x != 0.0 || v.y != 0.0;
        Parts {
            steady: c.steady,
            phase: c.steady && c.phase_levels != 0,
            load: nonzero(c.load_need)
                || nonzero(c.load_accel)
                || nonzero(c.neg_load)
                || nonzero(c.neg_load_accel),
            waveform: !c
                .segments
                .iter()
                .all(|s| crate::laws::karnopp::integrate::drive::is_sawtooth(s)),
            backward: false,
        }
    }

    /// The parts `instances` use under `settings`: of every one, or of
    /// [`SAMPLED_PARTS`] evenly spread over a longer list (what a run
    /// prepares up front; each batch takes the pipeline its own
    /// instances need).
    pub fn of(instances: &[Instance], settings: &Settings) -> Parts {
        let n = instances.len();
        let picked = n.min(SAMPLED_PARTS);
        (0..picked)
            .map(|k| &instances[k * n / picked])
            .fold(Parts::default(), |parts, inst| {
                parts.union(Parts::of_coefficients(&Coefficients::of(inst, settings)))
            })
            .with_settings(settings)
    }

    /// "steady+phase+load", "window": the parts in words.
    pub fn name(self) -> String {
        let mut words = vec![if self.steady { "steady" } else { "window" }];
        if self.phase {
            words.push("phase");
        }
        if self.load {
            words.push("load");
        }
        if self.waveform {
            words.push("waveform");
        }
        if self.backward {
            words.push("backward");
        }
        words.join("+")
    }

    /// Whether `file` belongs to a variant with these parts.
    fn include(self, file: &str) -> bool {
        match file {
            "shared/measure.wgsl" | "karnopp/steady.wgsl" => self.steady,
            "shared/phase.wgsl" => self.steady && self.phase,
            "karnopp/segments.wgsl" => self.waveform,
            "shared/variation.wgsl" | "shared/pieces.wgsl" | "karnopp/variation.wgsl" => {
                self.backward
            }
            _ => true,
        }
    }
}

/// The most instances [`Parts::of`] looks at.
pub const SAMPLED_PARTS: usize = 2048;

/// What one compiled pipeline is specialised to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Variant {
    pub precision: Precision,
    /// The adapter ends every shader loop after 65,535 iterations
    /// (llvmpipe): the shader then checks every iteration and undoes those
    /// the limiter cut short. Hardware adapters leave the check out.
    pub loop_limiter: bool,
    /// The optional parts it carries.
    pub parts: Parts,
}

impl Variant {
    /// Whether its lanes hold a step's flow and samples in device memory
    /// (`shaders/karnopp/hold_memory.wgsl`): an f64 lane on hardware. In
    /// registers RADV's compiler spilled 461 VGPRs of the f64 lane
    /// (results/registers.md). llvmpipe keeps private variables as the
    /// CPU's code does, and the f32 lane fits in registers.
    pub fn holds_in_memory(self) -> bool {
        self.precision == Precision::F64 && !self.loop_limiter
    }

    /// Every variant: both precisions, both kinds of adapter, every
    /// combination of parts (the backward travel's in f64 only).
    pub fn every() -> Vec<Variant> {
        let mut out = Vec::new();
        for precision in [Precision::F64, Precision::F32] {
            for loop_limiter in [false, true] {
                let mut every = Parts::every();
                if precision == Precision::F64 {
                    // The backward travel is measured in f64 only.
                    every.extend(Parts::with_backward());
                }
                for parts in every {
                    out.push(Variant {
                        precision,
                        loop_limiter,
                        parts,
                    });
                }
            }
        }
        out
    }
}

/// A variant without steady measurements: the steady half of the entry
/// point (`steady.wgsl`) as functions that do nothing. Its pipelines bind
/// neither the accumulators nor the heads.
const WINDOW_ONLY: &str = "\
fn start_measure(index: u32) {}

fn finish_measure(index: u32) {}

fn at_measured_end(st: State, index: u32) -> bool {
    return false;
}

fn measure_period_end(st: ptr<function, State>, index: u32, lane: u32, fresh: bool) -> bool {
    return true;
}
";

/// A variant without the backward travel: `variation.wgsl`'s functions as
/// ones that do nothing (and are never called: `BACKWARD` is false).
const NO_BACKWARD: &str = "\
fn follow_end(period: u32, time: Real, s: Sample, tau: Real) {}

fn follow_step() {}

fn follow(step: u32, lag_unit: u32) {}

fn followed_now() -> Followed {
    return Followed(V2(0.0), V2(0.0));
}

fn follow_undo(f: Followed) {}

fn variation_slot(slot: u32) -> u32 {
    return slot;
}
";

/// A steady variant without the phase ladder: `phase_period_end` judges
/// nothing (and is never called: `PHASE` is false).
const NO_LADDER: &str = "\
fn phase_period_end(slot: u32, k: u32, x: V2) -> PhaseEstimate {
    return PhaseEstimate(V2(0.0), V2(0.0), 0u, 0u);
}
";

/// A sawtooth variant: the segments' functions of `segments.wgsl` as
/// stand-ins that are never called (`WAVEFORM` is false) and bind nothing.
const SAWTOOTH_ONLY: &str = "\
struct SegmentAt {
    index: u32,
    corner: Real,
}

fn segment_drive(st: State, to_corner: V2) -> Drive {
    return Drive(V2(0.0), V2(0.0));
}

fn next_segments(st: ptr<function, State>, reached: vec2<bool>) {}

fn segment_at(first: u32, count: u32, p: Real) -> SegmentAt {
    return SegmentAt(0u, Real(0.0));
}
";

/// The load terms a variant reads (docs/model.md section 7): the coefficients'
/// with a load, else the +0 every one of them is at zero load.
fn load_terms(load: bool) -> String {
    ["load_need", "load_accel", "neg_load", "neg_load_accel"]
        .iter()
        .map(|name| {
            let value = if load {
                format!("coefficients[held].{name}")
            } else {
                "V2(0.0)".to_string()
            };
            format!("fn {name}() -> V2 {{\n    return {value};\n}}\n")
        })
        .collect()
}

/// `fn inverse_integer(n: u32) -> Real`: 1 / n as a literal for every n
/// the Taylor series use, so no series divides (the CPU multiplies by the
/// same constants), and the same literals as constants `INVERSE_n` for the
/// propagator's unrolled terms.
fn inverse_integer_fn() -> String {
    let most = TAYLOR_TERMS.max(TAYLOR_STAGE_TERMS + 1);
    let mut constants = String::new();
    for n in 1..=most {
        constants += &format!("const INVERSE_{n}: Real = Real({:e});\n", 1.0 / n as f64);
    }
    let mut cases = String::new();
    for n in 1..=most {
        cases += &format!("        case {n}u: {{ return INVERSE_{n}; }}\n");
    }
    constants
        + &format!(
            "fn inverse_integer(n: u32) -> Real {{\n    switch n {{\n{cases}        \
         default: {{ return Real(0.0); }}\n    }}\n}}\n"
        )
}

/// The prelude that defines `Real`, `V2`, the constants and the helpers of
/// one variant: the floor's (`crate::gpu::prelude`), then Karnopp's.
pub fn prelude(variant: Variant) -> String {
    // Per precision: the rest from the CPU mirror's precision module (the
    // time scale's epsilon, the smallest divisor kept away from zero and
    // the f32 formulation's switches), so shader and mirror cannot differ.
    macro_rules! from {
        ($p:path) => {{
            use $p as p;
            (
                p::TIME_EPSILON,
                format!("{:e}", p::TINY),
                [
                    p::COMPENSATED_TIME,
                    p::FIXED_PHASE,
                    p::CORNER_CLOCK,
                    p::DEFLECTION,
                    p::APPROACH_NOISE,
                    p::GRAZE_GUARD,
                ],
            )
        }};
    }
    let (time_eps, tiny, switches) = match variant.precision {
        Precision::F32 => from!(crate::laws::karnopp::single::precision),
        Precision::F64 => from!(crate::laws::karnopp::double::precision),
    };
    let [
        compensated,
        fixed_phase,
        corner_clock,
        deflection,
        approach_noise,
        graze_guard,
    ] = switches;
    format!(
        "// Prelude for {variant:?}, generated by pidm::gpu::shader.\n\
         {floor}\
         const TIME_EPSILON: Real = {time_eps:e};\n\
         const TINY: Real = {tiny};\n\
         const COMPENSATED_TIME: bool = {compensated};\n\
         const FIXED_PHASE: bool = {fixed_phase};\n\
         const CORNER_CLOCK: bool = {corner_clock};\n\
         const DEFLECTION: bool = {deflection};\n\
         const APPROACH_NOISE: bool = {approach_noise};\n\
         const GRAZE_GUARD: bool = {graze_guard};\n\
         const WORKGROUP_SIZE: u32 = {workgroup}u;\n\
         const LOOP_LIMITER: bool = {limiter};\n\
         const STEADY: bool = {steady};\n\
         const LOAD: bool = {load};\n\
         const WAVEFORM: bool = {waveform};\n\
         const BACKWARD: bool = {backward};\n\
         const STATUS_LOOP_LIMIT: u32 = {STATUS_LOOP_LIMIT}u;\n\
         {constants}\n{variation}{inverse}\n",
        floor = crate::gpu::prelude::floor(
            variant.precision,
            variant.parts.steady && variant.parts.phase
        ),
        limiter = variant.loop_limiter,
        steady = variant.parts.steady,
        load = variant.parts.load,
        waveform = variant.parts.waveform,
        backward = variant.parts.backward,
        variation = crate::laws::karnopp::variation::wgsl_constants(),
        workgroup = workgroup_size(),
        constants = constants::wgsl_constants(),
        inverse = inverse_integer_fn(),
    )
}

/// The complete shader source of one variant: the prelude, the parts'
/// stand-ins, and the files of its parts.
pub fn source(variant: Variant) -> String {
    let parts = variant.parts;
    let mut src = prelude(variant);
    src += &load_terms(parts.load);
    if !parts.steady {
        src += WINDOW_ONLY;
    } else if !parts.phase {
        src += NO_LADDER;
    }
    if !parts.waveform {
        src += SAWTOOTH_ONLY;
    }
    if !parts.backward {
        src += NO_BACKWARD;
    }
    src += &crate::gpu::engine_queue();
    let (holder, text) = HOLDERS[usize::from(variant.holds_in_memory())];
    for (name, text) in FILES.into_iter().chain([(holder, text)]) {
        if parts.include(name) {
            src += &format!("\n// ---- shaders/{name}\n");
            src += text;
        }
    }
    if variant.holds_in_memory() {
        let mut src = read_where_used(&src, "(*st)", "states[held]");
        src = read_where_used(&src, "st", "states[held]");
        for (binding, private, buffer, ty) in HELD_IN_MEMORY {
            src += &format!(
                "@group(0) @binding({binding}) var<storage, read_write> {buffer}: array<{ty}>;\n"
            );
            src = read_where_used(&src, private, &format!("{buffer}[lane_slot]"));
        }
        return src;
    }
    src
}

/// Parses and validates one variant with naga, as wgpu will, and returns
/// the module (with its type arena, for layout checks).
pub fn parse_and_validate(
    variant: Variant,
) -> Result<(naga::Module, naga::valid::ModuleInfo), GpuError> {
    let precision = variant.precision;
    let src = source(variant);
    let module = naga::front::wgsl::parse_str(&src).map_err(|e| GpuError::ShaderCompile {
        precision,
        message: e.emit_to_string(&src),
    })?;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        crate::gpu::prelude::capabilities(precision),
    )
    .validate(&module)
    .map_err(|e| GpuError::ShaderCompile {
        precision,
        message: e.emit_to_string(&src),
    })?;
    Ok((module, info))
}

#[cfg(test)]
mod tests;
