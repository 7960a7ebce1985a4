//! The LuGre integrator on the GPU (MODEL.md section 8) in f64: the WGSL
//! in `shaders/lugre/`, a function-for-function mirror of
//! [`crate::cpu::lugre`] (`model.wgsl` of `model.rs`, `rodas.wgsl` of
//! `rodas.rs`), and its host, which runs a batch period by period.
//!
//! * One invocation per instance. Each dispatch advances every running
//!   instance by at most a fixed number of Rodas4 step attempts
//!   ([`LugreGpu::attempts`]), and no further than the end of its current
//!   scene period. The integrator's state (the 11 numbers, the step size,
//!   the budget, the segment in hand) stays in a storage buffer between
//!   dispatches ([`Lane`]); the per-instance parameters are packed once
//!   ([`Params`]).
//! * At a period's end the host reads the lane back and measures the
//!   period exactly as the CPU's run does, with the same function
//!   (`cpu::lugre::run::Periods::period_end`: `measure::period_end` and
//!   the recurrence test that compares z), then starts the next period.
//!   The result is an `integrate::Run` per instance, which
//!   `measurement::reduce` turns into the record the CPU gives.
//! * llvmpipe (lavapipe) ends every loop of an invocation once all its
//!   loops together have run 65,535 passes, silently, and counts the
//!   passes of a SIMD group's lanes together. One step attempt makes about
//!   [`LOOP_PASSES_PER_ATTEMPT`] loop passes (the 11 x 11 LU and its
//!   solves mostly), and the entry's loop makes at most one attempt per
//!   pass, so a software adapter gets [`SOFTWARE_ATTEMPTS`] attempts per
//!   dispatch: well below the limit. `tests/it/gpu_lugre.rs` checks the
//!   numbers against the CPU's (a loop cut short would show there).
//! * WGSL's f64 has no `exp`: [`exp_nonpositive`] builds it from + - * and
//!   fma (the shader's `exp_nonpositive` is its mirror, with the constants
//!   generated here). f64 division and square roots go through the
//!   Karnopp prelude's `div` and `root` ([`crate::gpu::shader::prelude`]),
//!   as NVIDIA's compiler requires.
//!
//! Not wired into the backend yet (`crate::backend::gpu` refuses LuGre
//! instances): [`LugreGpu`] is the piece it will call.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::readback::{mappable, read_buffer};
use super::shader::{self, Parts, Variant};
use super::{GpuContext, GpuError, Precision};
use crate::cpu::integrate::{Run, Settings};
use crate::cpu::lugre::run::{
    A, C, GAMMA, N, Periods, SMALLEST_STEP, State, T, VP, VS, XP, XS, Z, first_step,
};
use crate::model::{AXES, Instance};

/// The shader files, in the order they are concatenated after the prelude.
pub const FILES: [(&str, &str); 3] = [
    ("model.wgsl", include_str!("../../shaders/lugre/model.wgsl")),
    ("rodas.wgsl", include_str!("../../shaders/lugre/rodas.wgsl")),
    ("entry.wgsl", include_str!("../../shaders/lugre/entry.wgsl")),
];

/// The compute entry point of the integrator.
pub const ENTRY_POINT: &str = "lugre_advance";

/// The compute entry point that evaluates `exp_nonpositive` (tests).
pub const EXP_ENTRY_POINT: &str = "lugre_exp";

/// llvmpipe's limit on the loop passes of one invocation (all its loops
/// together, a SIMD group's lanes counted together).
pub const LOOP_LIMIT: u32 = 65_535;

/// The loop passes of one step attempt, counted in the shader's source:
/// the Jacobian 14, I - gamma h J 132, the LU factorisation 506, six
/// solves of 143, the stages' sums 327 and the right-hand sides 12, the
/// error's 11 and the entry's pass 1 (a segment's start adds at most 10).
pub const LOOP_PASSES_PER_ATTEMPT: u32 = 14 + 132 + 506 + 6 * 143 + 327 + 12 + 11 + 1 + 10;

/// Step attempts per dispatch on a software adapter: the loop passes stay
/// within a third of [`LOOP_LIMIT`].
pub const SOFTWARE_ATTEMPTS: u32 = LOOP_LIMIT / 3 / LOOP_PASSES_PER_ATTEMPT;

/// Step attempts per dispatch on a hardware adapter (no loop limit; about
/// a few milliseconds of work per lane).
pub const HARDWARE_ATTEMPTS: u32 = 1024;

/// Invocations per workgroup on a software adapter (llvmpipe spreads
/// workgroups over its threads: small groups share a small batch among
/// the cores) and on a hardware one.
pub const SOFTWARE_WORKGROUP_SIZE: u32 = 4;
pub const HARDWARE_WORKGROUP_SIZE: u32 = 64;

/// The attempts a next corner's search makes before it takes what it has
/// (the CPU recurses; a corner rounded onto t once is already rare).
pub const CORNER_RETRIES: u32 = 4;

/// What `segment` returns after a step attempt that leaves the run going,
/// and once the segment is complete (the other values are statuses).
pub const SEGMENT_GOING: u32 = u32::MAX;
pub const SEGMENT_DONE: u32 = u32::MAX - 1;

/// The flags of a [`Lane`] (`entry.wgsl`'s LANE_*).
pub const LANE_RUNNING: u32 = 0;
pub const LANE_PERIOD_END: u32 = 1;
pub const LANE_STOPPED: u32 = 2;

// ---- exp for x <= 0 -------------------------------------------------------

/// The degree of [`exp_nonpositive`]'s Taylor polynomial: its truncation
/// error on |r| <= ln 2 / 2 is 4e-18 relative.
pub const EXP_DEGREE: usize = 13;

/// 1 / n! for n = 0..=EXP_DEGREE, each correctly rounded (n! is exact in
/// f64).
pub const EXP_TAYLOR: [f64; EXP_DEGREE + 1] = {
    let mut c = [0.0; EXP_DEGREE + 1];
    let mut factorial = 1u64;
    let mut n = 0;
    while n <= EXP_DEGREE {
        if n > 0 {
            factorial *= n as u64;
        }
        c[n] = 1.0 / factorial as f64;
        n += 1;
    }
    c
};

/// ln 2 in two parts (fdlibm's): the high part's last 32 bits are zero, so
/// k ln2_hi is exact for every k the reduction meets.
pub const EXP_LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
pub const EXP_LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);

/// Below this argument exp rounds to 0 (exp(-745.2) < 2^-1075).
pub const EXP_MIN: f64 = -745.2;

/// 2^-(2^j) for j = 0..10, exact.
pub const EXP_HALVINGS: [f64; 10] = {
    let mut h = [0.0; 10];
    let mut j = 0;
    while j < 10 {
        h[j] = f64::from_bits((1023 - (1u64 << j)) << 52);
        j += 1;
    }
    h
};

/// exp(x) for x <= 0 (NaN stays NaN) from + - * and fma, as the shader's
/// `exp_nonpositive` computes it: x = k ln 2 + r with |r| <= ln 2 / 2, a
/// Taylor polynomial in r (Horner's scheme in fma), then 2^k by exact
/// halvings (the small ones first, so that only the last product may
/// leave the normal range). Within 1e-15 of exp(x), relative, where
/// exp(x) is normal.
pub fn exp_nonpositive(x: f64) -> f64 {
    if !(x >= EXP_MIN) {
        return if x.is_nan() { x } else { 0.0 };
    }
    let k = x.mul_add(std::f64::consts::LOG2_E, 0.5).floor();
    let r = (-k).mul_add(EXP_LN2_LO, x - k * EXP_LN2_HI);
    let mut p = EXP_TAYLOR[EXP_DEGREE];
    for n in (0..EXP_DEGREE).rev() {
        p = p.mul_add(r, EXP_TAYLOR[n]);
    }
    let m = (-k) as u32;
    for (j, half) in EXP_HALVINGS.iter().enumerate() {
        if m & (1 << j) != 0 {
            p *= half;
        }
    }
    if m >= 1024 {
        p *= EXP_HALVINGS[9];
        p *= EXP_HALVINGS[9];
    }
    p
}

// ---- the shader's source --------------------------------------------------

/// `{:e}` of an f64: the shortest text that reads back as the same value.
fn lit(x: f64) -> String {
    format!("{x:e}")
}

/// A WGSL array of f64 literals.
fn array_lit(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|&v| lit(v)).collect();
    format!("array<Real, {}>({})", values.len(), items.join(", "))
}

/// The LuGre prelude: the Karnopp prelude's f64 definitions (Real, the
/// statuses, INFINITY, recip, div and root), the state's layout, Rodas4's
/// coefficients and the step control's constants from the Rust consts, and
/// `exp_taylor` / `exp_halvings` written out straight from
/// [`EXP_TAYLOR`] and [`EXP_HALVINGS`].
pub fn prelude(workgroup_size: u32) -> String {
    let base = shader::prelude(Variant {
        precision: Precision::F64,
        loop_limiter: false,
        parts: Parts::default(),
    });
    let u = |name: &str, v: usize| format!("const {name}: u32 = {v}u;\n");
    let r = |name: &str, v: f64| format!("const {name}: Real = {};\n", lit(v));
    let mut out = format!("{base}\n// LuGre prelude, generated by pidm::gpu::lugre.\n");
    for (name, v) in [
        ("N", N),
        ("XP", XP),
        ("VP", VP),
        ("XS", XS),
        ("VS", VS),
        ("Z", Z),
        ("T", T),
    ] {
        out += &u(name, v);
    }
    out += &u("LUGRE_WORKGROUP_SIZE", workgroup_size as usize);
    out += &u("CORNER_RETRIES", CORNER_RETRIES as usize);
    out += &u("SEGMENT_GOING", SEGMENT_GOING as usize);
    out += &u("SEGMENT_DONE", SEGMENT_DONE as usize);
    out += &r("GAMMA", GAMMA);
    out += &r("SMALLEST_STEP", SMALLEST_STEP);
    out += &r("MIN_POSITIVE", f64::MIN_POSITIVE);
    let rows = |m: &[&[f64]]| -> String {
        let rows: Vec<String> = m.iter().map(|row| array_lit(row)).collect();
        format!(
            "array<array<Real, {}>, {}>(\n    {},\n)",
            m[0].len(),
            m.len(),
            rows.join(",\n    ")
        )
    };
    let a: Vec<&[f64]> = A.iter().map(|row| &row[..]).collect();
    let c: Vec<&[f64]> = C.iter().map(|row| &row[..]).collect();
    out += &format!("const RODAS_A = {};\n", rows(&a));
    out += &format!("const RODAS_C = {};\n", rows(&c));
    out += &r("EXP_MIN", EXP_MIN);
    out += &r("EXP_INV_LN2", std::f64::consts::LOG2_E);
    out += &r("EXP_LN2_HI", EXP_LN2_HI);
    out += &r("EXP_LN2_LO", EXP_LN2_LO);
    // hypot's scaling: by 2^600 below 2^-300 and above 2^300 (exact).
    out += &r("HYPOT_SMALL", 2f64.powi(-300));
    out += &r("HYPOT_LARGE", 2f64.powi(300));
    out += &r("HYPOT_UP", 2f64.powi(600));
    out += &r("HYPOT_DOWN", 2f64.powi(-600));
    out += "\n// The Taylor polynomial of exp on |r| <= ln 2 / 2 (Horner, fma).\n\
            fn exp_taylor(r: Real) -> Real {\n";
    out += &format!("    var p = Real({});\n", lit(EXP_TAYLOR[EXP_DEGREE]));
    for n in (0..EXP_DEGREE).rev() {
        out += &format!("    p = fma(p, r, Real({}));\n", lit(EXP_TAYLOR[n]));
    }
    out += "    return p;\n}\n\n\
            // p 2^-m for m <= 1075: the bits of m from the lowest, 1024 as two 512s.\n\
            fn exp_halvings(p_in: Real, m: u32) -> Real {\n    var p = p_in;\n";
    for (j, half) in EXP_HALVINGS.iter().enumerate() {
        out += &format!(
            "    p = select(p, p * Real({}), (m & {}u) != 0u);\n",
            lit(*half),
            1u32 << j
        );
    }
    for _ in 0..2 {
        out += &format!(
            "    p = select(p, p * Real({}), m >= 1024u);\n",
            lit(EXP_HALVINGS[9])
        );
    }
    out += "    return p;\n}\n";
    out
}

/// The complete shader source for `workgroup_size` invocations per group.
pub fn source(workgroup_size: u32) -> String {
    let mut src = prelude(workgroup_size);
    for (name, text) in FILES {
        src += &format!("\n// ---- shaders/lugre/{name}\n");
        src += text;
    }
    src
}

/// Parses and validates the shader with naga, as wgpu will.
pub fn parse_and_validate(
    workgroup_size: u32,
) -> Result<(naga::Module, naga::valid::ModuleInfo), GpuError> {
    let src = source(workgroup_size);
    let compile = |message: String| GpuError::ShaderCompile {
        precision: Precision::F64,
        message,
    };
    let module =
        naga::front::wgsl::parse_str(&src).map_err(|e| compile(e.emit_to_string(&src)))?;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        shader::capabilities(Precision::F64),
    )
    .validate(&module)
    .map_err(|e| compile(e.emit_to_string(&src)))?;
    Ok((module, info))
}

// ---- the buffers ------------------------------------------------------------

/// One instance's parameters (`model.wgsl`'s `Model`): the model, the
/// drive and the error control's weights.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Params {
    pub gain: [f64; AXES],
    pub damping: [f64; AXES],
    pub stiffness: [f64; AXES],
    pub stage_mass: [f64; AXES],
    pub voltage: [f64; AXES],
    pub frequency: [f64; AXES],
    pub duty: [f64; AXES],
    pub load: [f64; AXES],
    pub slider_mass: f64,
    pub coulomb_friction: f64,
    pub static_friction: f64,
    pub sigma0: f64,
    pub sigma1: f64,
    pub sigma2: f64,
    pub v_s: f64,
    pub period: f64,
    pub scale: State,
}

impl Params {
    /// The parameters of a run's instance.
    fn of(book: &Periods) -> Params {
        let inst = &book.inst;
        let m = &book.model;
        let axis = |f: fn(&crate::model::Axis) -> f64| [f(&inst.axes[0]), f(&inst.axes[1])];
        Params {
            gain: axis(|a| a.gain),
            damping: axis(|a| a.damping),
            stiffness: axis(|a| a.stiffness),
            stage_mass: axis(|a| a.stage_mass),
            voltage: axis(|a| a.voltage),
            frequency: axis(|a| a.frequency),
            duty: axis(|a| a.duty),
            load: inst.mechanism.load,
            slider_mass: inst.mechanism.slider_mass,
            coulomb_friction: inst.mechanism.coulomb_friction,
            static_friction: inst.mechanism.static_friction,
            sigma0: m.sigma0,
            sigma1: m.sigma1,
            sigma2: m.sigma2,
            v_s: m.v_s,
            period: inst.period(),
            scale: book.scale,
        }
    }
}

/// One instance's integrator state between dispatches (`entry.wgsl`'s
/// `Lane`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Lane {
    pub y: State,
    /// The next trial step [s].
    pub h: f64,
    /// The current segment's end [s] and drive (a, b per axis).
    pub end: f64,
    pub drive: [f64; 2 * AXES],
    /// The drive's clock of the current scene period [cycles].
    pub clock: [f64; AXES],
    /// Steps the run may still take.
    pub budget: u32,
    /// Steps of the completed segments (saturating).
    pub steps: u32,
    /// Attempts in the current segment.
    pub segment_steps: u32,
    /// 1 after a rejected attempt in the current segment.
    pub rejected: u32,
    /// 1 inside a segment.
    pub in_segment: u32,
    /// `STATUS_OK`, or why the run failed.
    pub status: u32,
    /// [`LANE_RUNNING`], [`LANE_PERIOD_END`] or [`LANE_STOPPED`].
    pub flag: u32,
    pub _pad: u32,
}

impl Lane {
    /// A run at rest at the start of its first period (as the CPU's).
    fn start(book: &Periods) -> Lane {
        let mut lane = Lane {
            h: first_step(&book.inst),
            budget: book.budget,
            steps: book.run.state.steps,
            ..Lane::zeroed()
        };
        lane.next_period(book);
        lane
    }

    /// Sets the lane going at the start of its run's current period, or
    /// stops it where the run has ended.
    fn next_period(&mut self, book: &Periods) {
        if book.is_finished() {
            self.flag = LANE_STOPPED;
            return;
        }
        self.y[T] = 0.0;
        self.clock = book.clock().start;
        self.in_segment = 0;
        self.flag = LANE_RUNNING;
    }
}

// ---- the host ---------------------------------------------------------------

/// What a batch cost.
#[derive(Clone, Copy, Debug, Default)]
pub struct BatchReport {
    /// Dispatches (each followed by a readback).
    pub dispatches: u64,
    /// Scene periods measured on the host.
    pub periods: u64,
    /// Seconds of the whole batch, and of the dispatches with their
    /// readbacks.
    pub seconds: f64,
    pub gpu_seconds: f64,
}

/// The LuGre pipeline on one device.
pub struct LugreGpu<'a> {
    ctx: &'a GpuContext,
    pipeline: wgpu::ComputePipeline,
    workgroup_size: u32,
    /// Step attempts per lane and dispatch.
    pub attempts: u32,
}

/// Compiles one entry point of the shader on `device` (runtime checks off:
/// every loop is bounded, every index below its array's length).
fn compile(
    device: &wgpu::Device,
    workgroup_size: u32,
    entry: &str,
) -> Result<wgpu::ComputePipeline, GpuError> {
    parse_and_validate(workgroup_size)?;
    let src = source(workgroup_size);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let internal = device.push_error_scope(wgpu::ErrorFilter::Internal);
    let mut checks = wgpu::ShaderRuntimeChecks::checked();
    checks.bounds_checks = false;
    checks.force_loop_bounding = false;
    // SAFETY: every loop of the shader is bounded by a constant or by
    // `control.attempts`; every index is a constant, a loop counter below
    // its array's length, a pivot (below N) or an instance below both
    // storage arrays' lengths.
    let module = unsafe {
        device.create_shader_module_trusted(
            wgpu::ShaderModuleDescriptor {
                label: Some("shaders/lugre"),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            },
            checks,
        )
    };
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    let internal = pollster::block_on(internal.pop());
    let validation = pollster::block_on(validation.pop());
    if let Some(e) = validation.or(internal) {
        return Err(GpuError::ShaderCompile {
            precision: Precision::F64,
            message: e.to_string(),
        });
    }
    Ok(pipeline)
}

/// Workgroups for `n` invocations of `size`, in two dimensions where one
/// is not enough.
fn groups(n: usize, size: u32, max_per_dimension: u32) -> (u32, u32) {
    let groups = (n as u64).div_ceil(size as u64).max(1);
    let x = groups.min(max_per_dimension as u64);
    (x as u32, groups.div_ceil(x) as u32)
}

impl<'a> LugreGpu<'a> {
    /// Compiles the integrator on `ctx`, which must offer f64.
    pub fn new(ctx: &'a GpuContext) -> Result<LugreGpu<'a>, GpuError> {
        if !ctx.supports_f64() {
            return Err(GpuError::F64Unsupported {
                adapter: ctx.describe(),
            });
        }
        let (workgroup_size, attempts) = if ctx.is_hardware() {
            (HARDWARE_WORKGROUP_SIZE, HARDWARE_ATTEMPTS)
        } else {
            (SOFTWARE_WORKGROUP_SIZE, SOFTWARE_ATTEMPTS)
        };
        let pipeline = compile(ctx.device(), workgroup_size, ENTRY_POINT)?;
        Ok(LugreGpu {
            ctx,
            pipeline,
            workgroup_size,
            attempts,
        })
    }

    /// Integrates LuGre `instances` to the ends of their measurements: an
    /// `integrate::Run` each, as `cpu::lugre::run_instance_until` gives.
    ///
    /// # Panics
    /// If an instance's friction is not LuGre's.
    pub fn run(
        &self,
        instances: &[Instance],
        settings: &Settings,
    ) -> Result<(Vec<Run>, BatchReport), GpuError> {
        self.run_until(instances, settings, || false)
    }

    /// [`LugreGpu::run`], asking `stop` between dispatches
    /// ([`GpuError::Interrupted`] when it says yes).
    pub fn run_until(
        &self,
        instances: &[Instance],
        settings: &Settings,
        stop: impl Fn() -> bool,
    ) -> Result<(Vec<Run>, BatchReport), GpuError> {
        let started = Instant::now();
        let mut report = BatchReport::default();
        let mut books: Vec<Periods> = instances
            .iter()
            .map(|inst| Periods::new(inst, settings))
            .collect();
        if books.is_empty() {
            return Ok((Vec::new(), report));
        }
        let params: Vec<Params> = books.iter().map(Params::of).collect();
        let mut lanes: Vec<Lane> = books.iter().map(Lane::start).collect();
        let device = self.ctx.device();
        let queue = self.ctx.queue();
        let models = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lugre models"),
            contents: bytemuck::cast_slice(&params),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let lane_bytes = std::mem::size_of_val(lanes.as_slice()) as u64;
        let lane_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lugre lanes"),
            contents: bytemuck::cast_slice(&lanes),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
        });
        let control = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lugre control"),
            contents: bytemuck::cast_slice(&[self.attempts, 0, 0, 0]),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let read = mappable(device, "lugre lanes read", lane_bytes);
        let layout = self.pipeline.get_bind_group_layout(0);
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lugre"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: models.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: lane_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: control.as_entire_binding(),
                },
            ],
        });
        let (gx, gy) = groups(
            lanes.len(),
            self.workgroup_size,
            self.ctx.limits().max_compute_workgroups_per_dimension,
        );
        // Whether the host changed a lane since the last upload.
        let mut dirty = false;
        while lanes.iter().any(|l| l.flag == LANE_RUNNING) {
            if stop() {
                return Err(GpuError::Interrupted);
            }
            let t = Instant::now();
            if dirty {
                queue.write_buffer(&lane_buffer, 0, bytemuck::cast_slice(&lanes));
                dirty = false;
            }
            let mut encoder = device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &group, &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
            encoder.copy_buffer_to_buffer(&lane_buffer, 0, &read, 0, lane_bytes);
            queue.submit([encoder.finish()]);
            let bytes = read_buffer(device, &read)?;
            report.dispatches += 1;
            report.gpu_seconds += t.elapsed().as_secs_f64();
            let after: Vec<Lane> = bytes
                .chunks_exact(size_of::<Lane>())
                .map(bytemuck::pod_read_unaligned)
                .collect();
            let moved = lanes
                .iter()
                .zip(&after)
                .any(|(before, now)| before.flag == LANE_RUNNING && before != now);
            if !moved {
                let unfinished = lanes.iter().filter(|l| l.flag == LANE_RUNNING).count();
                return Err(GpuError::Stalled {
                    unfinished: unfinished as u32,
                    slices: report.dispatches,
                });
            }
            lanes = after;
            for (lane, book) in lanes.iter_mut().zip(books.iter_mut()) {
                match lane.flag {
                    LANE_PERIOD_END => {
                        book.run.state.steps = lane.steps;
                        book.period_end(&lane.y);
                        report.periods += 1;
                        lane.next_period(book);
                        dirty = true;
                    }
                    LANE_STOPPED if lane.status != book.run.state.status => {
                        // Failed: the CPU's run keeps the steps of the
                        // completed segments and the status.
                        book.run.state.steps = lane.steps;
                        book.run.state.status = lane.status;
                    }
                    _ => {}
                }
            }
        }
        report.seconds = started.elapsed().as_secs_f64();
        Ok((books.into_iter().map(|b| b.run).collect(), report))
    }

    /// The shader's `exp_nonpositive` of each of `xs`, computed on the
    /// device (the tests compare it with [`exp_nonpositive`]).
    pub fn exp_on_gpu(&self, xs: &[f64]) -> Result<Vec<f64>, GpuError> {
        if xs.is_empty() {
            return Ok(Vec::new());
        }
        let device = self.ctx.device();
        let pipeline = compile(device, self.workgroup_size, EXP_ENTRY_POINT)?;
        let values = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lugre exp"),
            contents: bytemuck::cast_slice(xs),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let bytes = std::mem::size_of_val(xs) as u64;
        let read = mappable(device, "lugre exp read", bytes);
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lugre exp"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 3,
                resource: values.as_entire_binding(),
            }],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups((xs.len() as u32).div_ceil(self.workgroup_size), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&values, 0, &read, 0, bytes);
        self.ctx.queue().submit([encoder.finish()]);
        let out = read_buffer(device, &read)?;
        Ok(out
            .chunks_exact(8)
            .map(bytemuck::pod_read_unaligned)
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within 1e-15 of Rust's exp, relative, over the normal range, and
    /// within one subnormal unit below it; exact at 0.
    #[test]
    fn exp_nonpositive_is_exp() {
        assert_eq!(exp_nonpositive(0.0), 1.0);
        assert_eq!(exp_nonpositive(-0.0), 1.0);
        assert_eq!(exp_nonpositive(f64::NEG_INFINITY), 0.0);
        assert!(exp_nonpositive(f64::NAN).is_nan());
        assert_eq!(exp_nonpositive(-746.0), 0.0);
        let mut worst = 0.0_f64;
        let mut ulps = 0_u64;
        let mut x = 0.0_f64;
        let mut k = 0u64;
        // Dense near 0 (where the model lives), then out to the end.
        while x > -746.0 {
            let (got, want) = (exp_nonpositive(x), x.exp());
            if want >= f64::MIN_POSITIVE {
                worst = worst.max(((got - want) / want).abs());
                ulps = ulps.max(got.to_bits().abs_diff(want.to_bits()));
            } else {
                assert!((got - want).abs() <= 5e-324, "{x}: {got:e} {want:e}");
            }
            k += 1;
            // Steps that are no round numbers, finer near 0.
            x -= 1.234567e-4 * (1.0 + x.abs()) * (1.0 + (k % 7) as f64 / 7.0);
        }
        assert!(k > 10_000, "{k} points");
        assert!(worst <= 1e-15, "{worst:e} relative ({ulps} ulps)");
        assert!(ulps <= 2, "{ulps} ulps");
    }

    /// The constants: 1/n! and the halvings.
    #[test]
    fn exp_constants_are_exact() {
        assert_eq!(EXP_TAYLOR[0], 1.0);
        assert_eq!(EXP_TAYLOR[3], 1.0 / 6.0);
        for (j, h) in EXP_HALVINGS.iter().enumerate() {
            assert_eq!(*h, 2f64.powi(-(1 << j)));
        }
        assert_eq!(EXP_LN2_HI + EXP_LN2_LO, std::f64::consts::LN_2);
        assert_eq!(EXP_LN2_HI.to_bits() & 0xffff_ffff, 0);
    }

    #[test]
    fn the_shader_parses_validates_and_writes_spir_v() {
        for size in [SOFTWARE_WORKGROUP_SIZE, HARDWARE_WORKGROUP_SIZE] {
            let (module, info) = parse_and_validate(size).unwrap_or_else(|e| panic!("{e}"));
            let options = naga::back::spv::Options::default();
            let words = naga::back::spv::write_vec(&module, &info, &options, None)
                .unwrap_or_else(|e| panic!("{e}"));
            assert!(words.len() > 1000);
        }
    }

    /// Literals read back as the values they were written from.
    #[test]
    fn prelude_literals_round_trip() {
        for v in EXP_TAYLOR
            .iter()
            .chain(&EXP_HALVINGS)
            .chain(A.iter().flatten())
            .chain(C.iter().flatten())
            .chain(&[EXP_LN2_HI, EXP_LN2_LO, f64::MIN_POSITIVE, SMALLEST_STEP])
        {
            assert_eq!(lit(*v).parse::<f64>().unwrap(), *v);
        }
    }

    /// The buffers' Rust structs have the shader's layout.
    #[test]
    fn params_and_lanes_have_the_shader_layout() {
        let (module, _) = parse_and_validate(SOFTWARE_WORKGROUP_SIZE).unwrap();
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let find = |name: &str| {
            module
                .types
                .iter()
                .find(|(_, t)| t.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("no {name}"))
        };
        let offsets = |name: &str| -> (u32, Vec<(String, u32)>) {
            let (handle, ty) = find(name);
            let naga::TypeInner::Struct { members, span } = &ty.inner else {
                panic!("{name} is no struct")
            };
            assert_eq!(layouter[handle].size, *span);
            (
                *span,
                members
                    .iter()
                    .map(|m| (m.name.clone().unwrap(), m.offset))
                    .collect(),
            )
        };
        let (span, members) = offsets("Model");
        assert_eq!(span as usize, size_of::<Params>());
        let rust = [
            ("gain", std::mem::offset_of!(Params, gain)),
            ("load", std::mem::offset_of!(Params, load)),
            ("slider_mass", std::mem::offset_of!(Params, slider_mass)),
            ("period", std::mem::offset_of!(Params, period)),
            ("scale", std::mem::offset_of!(Params, scale)),
        ];
        for (name, offset) in rust {
            let (_, o) = members.iter().find(|(n, _)| n == name).unwrap();
            assert_eq!(*o as usize, offset, "Model.{name}");
        }
        let (span, members) = offsets("Lane");
        assert_eq!(span as usize, size_of::<Lane>());
        let rust = [
            ("h", std::mem::offset_of!(Lane, h)),
            ("drive", std::mem::offset_of!(Lane, drive)),
            ("clock", std::mem::offset_of!(Lane, clock)),
            ("budget", std::mem::offset_of!(Lane, budget)),
            ("status", std::mem::offset_of!(Lane, status)),
            ("flag", std::mem::offset_of!(Lane, flag)),
        ];
        for (name, offset) in rust {
            let (_, o) = members.iter().find(|(n, _)| n == name).unwrap();
            assert_eq!(*o as usize, offset, "Lane.{name}");
        }
    }
}
