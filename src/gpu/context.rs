//! The GPU context: the chosen adapter's device and queue, their health
//! (device loss and uncaptured errors), the pipelines of each precision and
//! their self-test against the CPU before any instance is integrated.

use super::*;

/// What making a pipeline ready cost, for the user's information.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preparation {
    /// Finding the adapter and opening the device [s].
    pub open_s: f64,
    /// The part of `open_s` spent loading the drivers and enumerating
    /// their adapters, before the device is requested [s].
    pub adapters_s: f64,
    /// Creating the pipeline: the driver's compile, or a pipeline-cache hit
    /// [s].
    pub pipeline_s: f64,
    /// The self-test batch [s].
    pub self_test_s: f64,
}

/// Errors the device reported outside any error scope, and its loss.
#[derive(Default)]
pub(super) struct DeviceHealth {
    failure: Mutex<Option<String>>,
}

impl DeviceHealth {
    fn record(&self, message: String) {
        let mut failure = self.failure.lock().unwrap_or_else(|e| e.into_inner());
        if failure.is_none() {
            *failure = Some(message);
        }
    }

    fn failure(&self) -> Option<String> {
        self.failure
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// An open device with what the batches need to know about it.
pub struct GpuContext {
    pub(super) device: wgpu::Device,
    pub(super) queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    f64: bool,
    pub(super) limits: wgpu::Limits,
    health: Arc<DeviceHealth>,
    /// The driver's pipeline cache, where the adapter offers one.
    cache: Option<cache::DiskCache>,
    /// Compiled and self-tested pipelines by variant, built on first use,
    /// with what building them cost.
    pipelines: Mutex<HashMap<Variant, (wgpu::ComputePipeline, Preparation)>>,
    /// Other laws' pipelines by name (LuGre's), compiled on first use, so a
    /// run's batches share one compile.
    law_pipelines: Mutex<HashMap<&'static str, wgpu::ComputePipeline>>,
    /// Time to find the adapter and open the device [s].
    opened_in: f64,
    /// The part of `opened_in` before the device was requested [s].
    adapters_in: f64,
    /// Held while a batch runs: batches on one context take turns (wgpu's
    /// GL backend does not survive two threads submitting at once).
    pub(super) busy: Mutex<()>,
}

impl GpuContext {
    /// Opens the best adapter: a hardware one when there is one, a software
    /// one (lavapipe and the like) only when `allow_software`.
    pub fn new(allow_software: bool) -> Result<GpuContext, GpuError> {
        let started = std::time::Instant::now();
        let mut tried = Vec::new();
        let mut best: Option<wgpu::Adapter> = None;
        // The first software adapter refused, to say so plainly when it is
        // the only kind there is.
        let mut software_seen: Option<String> = None;
        // Unless WGPU_BACKEND says otherwise, the primary backends
        // (Vulkan, Metal, DX12) first: opening GL costs a tenth of a second,
        // and a GL adapter has no f64.
        let candidates = match wgpu::Backends::from_env() {
            Some(backends) => adapters_on(backends),
            None => {
                let mut found = adapters_on(wgpu::Backends::PRIMARY);
                let usable = |a: &wgpu::Adapter| allow_software || !is_software(&a.get_info());
                if !found.iter().any(usable) {
                    found.extend(adapters_on(wgpu::Backends::SECONDARY));
                }
                found
            }
        };
        for adapter in candidates {
            let info = adapter.get_info();
            let label = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
            let compute = adapter
                .get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS);
            if !compute {
                tried.push(format!("{label}: no compute shaders"));
                continue;
            }
            if is_software(&info) && !allow_software {
                tried.push(format!("{label}: software, not allowed"));
                software_seen.get_or_insert_with(|| {
                    let kind = if has_loop_limiter(&info) {
                        "lavapipe: "
                    } else {
                        ""
                    };
                    format!("{kind}{}, {:?}", info.name, info.backend)
                });
                continue;
            }
            tried.push(format!("{label}: usable"));
            if best.as_ref().is_none_or(|b| rank(&adapter) > rank(b)) {
                best = Some(adapter);
            }
        }
        let adapters_in = started.elapsed().as_secs_f64();
        if best.is_none()
            && let Some(software) = software_seen
        {
            return Err(GpuError::OnlySoftware { software });
        }
        let Some(adapter) = best else {
            let backends = wgpu::Backends::from_env()
                .map(|b| format!("WGPU_BACKEND={b:?}"))
                .unwrap_or_else(|| "all backends".to_string());
            let tried = if tried.is_empty() {
                format!("{backends}: none enumerated")
            } else {
                format!("{backends}: {}", tried.join("; "))
            };
            return Err(GpuError::NoAdapter { tried });
        };
        let mut ctx = Self::from_adapter(&adapter)?;
        ctx.opened_in = started.elapsed().as_secs_f64();
        ctx.adapters_in = adapters_in;
        Ok(ctx)
    }

    /// Opens a device on a given adapter, with its full limits, and
    /// `SHADER_F64` and `PIPELINE_CACHE` where offered.
    pub fn from_adapter(adapter: &wgpu::Adapter) -> Result<GpuContext, GpuError> {
        let started = std::time::Instant::now();
        let info = adapter.get_info();
        let offered = adapter.features();
        let f64 = offered.contains(wgpu::Features::SHADER_F64);
        let limits = adapter.limits();
        let features = offered & (wgpu::Features::SHADER_F64 | wgpu::Features::PIPELINE_CACHE);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("pidm"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::DeviceRequest {
            adapter: info.name.clone(),
            message: e.to_string(),
        })?;
        // wgpu panics on errors outside any error scope unless a handler
        // takes them: record them (and the device's loss) instead, and turn
        // them into errors where the work checks.
        let health = Arc::new(DeviceHealth::default());
        let on_error = health.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            on_error.record(e.to_string())
        }));
        let on_lost = health.clone();
        device.set_device_lost_callback(move |reason, message| {
            on_lost.record(format!("device lost ({reason:?}): {message}"))
        });
        let cache = if features.contains(wgpu::Features::PIPELINE_CACHE) {
            cache::DiskCache::open(&device, &info)
        } else {
            None
        };
        Ok(GpuContext {
            device,
            queue,
            info,
            f64,
            limits,
            health,
            cache,
            pipelines: Mutex::new(HashMap::new()),
            law_pipelines: Mutex::new(HashMap::new()),
            opened_in: started.elapsed().as_secs_f64(),
            adapters_in: 0.0,
            busy: Mutex::new(()),
        })
    }

    /// "NVIDIA H100 (Vulkan, DiscreteGpu)": the adapter, its backend and
    /// its type.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }

    /// The driver and its version.
    pub fn driver(&self) -> String {
        driver_of(&self.info)
    }

    /// True unless the adapter is a software rasteriser.
    pub fn is_hardware(&self) -> bool {
        !is_software(&self.info)
    }

    /// True when the device runs f64 shaders.
    pub fn supports_f64(&self) -> bool {
        self.f64
    }

    /// Whether creating a pipeline took it from pidm's cache file rather
    /// than compiling it (true also where there is no pipeline cache, so
    /// that every run compiles): a run's preparation then measures what
    /// later runs pay.
    pub fn pipeline_from_cache(&self) -> bool {
        self.cache.as_ref().is_none_or(|c| c.loaded())
    }

    /// Where compiled pipelines are kept between runs, if anywhere.
    pub fn pipeline_cache_path(&self) -> Option<&std::path::Path> {
        self.cache.as_ref().map(|c| c.path())
    }

    /// The device's limits (the adapter's best).
    pub fn limits(&self) -> &wgpu::Limits {
        &self.limits
    }

    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The shader variant this adapter runs in a precision with `parts`.
    pub fn variant(&self, precision: Precision, parts: Parts) -> Variant {
        Variant {
            precision,
            loop_limiter: has_loop_limiter(&self.info),
            parts,
        }
    }

    /// The variants this context has compiled and self-tested so far.
    pub fn prepared_variants(&self) -> Vec<Variant> {
        let pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        let mut out: Vec<Variant> = pipelines.keys().copied().collect();
        out.sort_by_key(|v| (v.precision == Precision::F64, v.parts));
        out
    }

    /// The lanes a batch keeps busy at once ([`lanes_for`]: the
    /// `PIDM_GPU_LANES` knob, else what this kind of adapter runs at once).
    pub fn lanes(&self) -> usize {
        lanes_for(self.is_hardware())
    }

    /// An error if the device failed or was lost so far.
    pub(super) fn check_health(&self) -> Result<(), GpuError> {
        match self.health.failure() {
            Some(message) => Err(GpuError::Device {
                adapter: self.describe(),
                message,
            }),
            None => Ok(()),
        }
    }

    /// Compiles the pipeline of a precision with every part and tests it
    /// against the CPU, once per context (see [`GpuContext::prepare_parts`]).
    pub fn prepare(&self, precision: Precision) -> Result<wgpu::ComputePipeline, GpuError> {
        self.prepare_parts(precision, Parts::ALL).map(|(p, _)| p)
    }

    /// The pipeline for a batch that needs `needs`: one already prepared
    /// whose parts cover them (the fewest parts first), else a new one
    /// with exactly `needs`, compiled and self-tested
    /// ([`GpuContext::prepare_timed`]). Returns it with its variant.
    /// The pipeline a law other than Karnopp's keeps under `name`, built by
    /// `compile` (given the driver's pipeline cache, where there is one) on
    /// first use, self-tested by `test` before any instance runs on it, and
    /// kept for the context's life; the cache is saved after a compile. A
    /// pipeline whose self-test fails is not kept.
    pub fn law_pipeline(
        &self,
        name: &'static str,
        compile: impl FnOnce(Option<&wgpu::PipelineCache>) -> Result<wgpu::ComputePipeline, GpuError>,
        test: impl FnOnce(&wgpu::ComputePipeline) -> Result<(), GpuError>,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        let mut pipelines = self.law_pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(pipeline) = pipelines.get(name) {
            return Ok(pipeline.clone());
        }
        let pipeline = compile(self.cache.as_ref().map(|c| c.cache()))?;
        if let Some(cache) = &self.cache {
            cache.save();
        }
        test(&pipeline)?;
        pipelines.insert(name, pipeline.clone());
        Ok(pipeline)
    }

    pub fn pipeline_for(
        &self,
        precision: Precision,
        needs: Parts,
    ) -> Result<(wgpu::ComputePipeline, Variant), GpuError> {
        {
            let pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
            let best = pipelines
                .iter()
                .filter(|(v, _)| v.precision == precision && v.parts.covers(needs))
                .min_by_key(|(v, _)| v.parts);
            if let Some((variant, (pipeline, _))) = best {
                return Ok((pipeline.clone(), *variant));
            }
            // A run that prepared its pipeline up front meets instances
            // with a part it lacks: say why this batch waits for a compile.
            if let Some(had) = pipelines.keys().find(|v| v.precision == precision) {
                eprintln!(
                    "pidm: a batch needs the GPU pipeline's {} parts where the run prepared {}: \
                     compiling and self-testing that variant",
                    needs.name(),
                    had.parts.name()
                );
            }
        }
        let variant = self.variant(precision, needs);
        self.prepare_timed(variant).map(|(p, _)| (p, variant))
    }

    /// [`GpuContext::prepare_timed`] of the variant with `parts`.
    pub fn prepare_parts(
        &self,
        precision: Precision,
        parts: Parts,
    ) -> Result<(wgpu::ComputePipeline, Preparation), GpuError> {
        self.prepare_timed(self.variant(precision, parts))
    }

    /// Compiles the pipeline of a variant and tests it against the CPU,
    /// once per context; a later call returns the first outcome's pipeline,
    /// with what the preparation cost (the first call's, also on later
    /// calls). Every driver failure becomes an error here, before any
    /// instance of a run is integrated on it.
    pub fn prepare_timed(
        &self,
        variant: Variant,
    ) -> Result<(wgpu::ComputePipeline, Preparation), GpuError> {
        let precision = variant.precision;
        if precision == Precision::F64 && !self.f64 {
            return Err(GpuError::F64Unsupported {
                adapter: self.describe(),
            });
        }
        let mut pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = pipelines.get(&variant) {
            return Ok(p.clone());
        }
        let started = std::time::Instant::now();
        let pipeline = create_pipeline(
            &self.device,
            variant,
            self.cache.as_ref().map(|c| c.cache()),
        )?;
        self.check_health()?;
        let compiled = started.elapsed().as_secs_f64();
        self.self_test(
            &pipeline,
            variant,
            Skew {
                step: 0.0,
                backward: 0.0,
            },
        )?;
        let tested = started.elapsed().as_secs_f64();
        if let Some(cache) = &self.cache {
            cache.save();
        }
        let preparation = Preparation {
            open_s: self.opened_in,
            adapters_s: self.adapters_in,
            pipeline_s: compiled,
            self_test_s: tested - compiled,
        };
        pipelines.insert(variant, (pipeline.clone(), preparation));
        Ok((pipeline, preparation))
    }

    /// Compiles the pipeline of a precision (without caching it in this
    /// context) and runs the self-test against a CPU reference whose steps
    /// are shifted by `skew` [m]: a test hook for the refusal path (a skew
    /// beyond the precision's allowance must fail with
    /// [`GpuError::SelfTest`]).
    pub fn self_test_skewed(&self, precision: Precision, skew: f64) -> Result<(), GpuError> {
        self.self_test_fresh(
            precision,
            Parts::ALL,
            Skew {
                step: skew,
                backward: 0.0,
            },
        )
    }

    /// [`GpuContext::self_test_skewed`] of the f64 variant that measures
    /// the backward travel, the CPU reference's backward travel (not its
    /// steps) shifted by `skew` [m]: beyond [`BACKWARD_ALLOWANCE_M`] it
    /// must fail.
    pub fn self_test_backward_skewed(&self, skew: f64) -> Result<(), GpuError> {
        let parts = Parts::ALL.with_settings(&Settings {
            backward: true,
            ..Settings::default()
        });
        self.self_test_fresh(
            Precision::F64,
            parts,
            Skew {
                step: 0.0,
                backward: skew,
            },
        )
    }

    /// The self-test on a pipeline of `parts` compiled for it alone.
    fn self_test_fresh(
        &self,
        precision: Precision,
        parts: Parts,
        skew: Skew,
    ) -> Result<(), GpuError> {
        if precision == Precision::F64 && !self.f64 {
            return Err(GpuError::F64Unsupported {
                adapter: self.describe(),
            });
        }
        let variant = self.variant(precision, parts);
        let pipeline = create_pipeline(
            &self.device,
            variant,
            self.cache.as_ref().map(|c| c.cache()),
        )?;
        self.check_health()?;
        self.self_test(&pipeline, variant, skew)
    }

    /// Runs the self-test batch (docs/model.md's Fig. 8 case, two periods, and
    /// its 1-DOF x baseline; with steady measurements a steady one; with a
    /// load the Fig. 8 case under one) on a fresh pipeline of `variant` and
    /// compares with the CPU. `skew` [m] is added to the CPU reference's
    /// steps: zero for the real test; [`GpuContext::self_test_skewed`] lets
    /// tests feed a wrong reference to check that the pipeline is refused.
    fn self_test(
        &self,
        pipeline: &wgpu::ComputePipeline,
        variant: Variant,
        skew: Skew,
    ) -> Result<(), GpuError> {
        let precision = variant.precision;
        let mut fig8 = Instance::TABLE1;
        fig8.axes[1].frequency = 20.0;
        fig8.cycles = 2;
        fig8.settle = 1;
        // A steady measurement of 10 Hz against 14 Hz: periodic with a lag
        // of 5 periods (a common period) after about 7.
        let mut steady = Instance::TABLE1;
        steady.axes[1].frequency = 14.0;
        steady.cycles = 40;
        steady.measure = Measure::Steady {
            step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
        };
        let mut loaded = fig8;
        loaded.mechanism.load = [0.3, -0.2];
        let mut instances = vec![fig8, fig8.baseline(0)];
        if variant.parts.steady {
            instances.push(steady);
        }
        if variant.parts.load {
            instances.push(loaded);
        }
        // A variant that measures the backward travel is tested measuring
        // it (`backward_self_test`).
        let settings = Settings {
            backward: variant.parts.backward,
            ..Settings::default()
        };
        let fail = |message: String| GpuError::SelfTest {
            precision,
            adapter: self.describe(),
            message,
        };
        let outcomes = execute_gpu_inner(
            &self.device,
            &self.queue,
            (pipeline, variant),
            &self.limits,
            &instances,
            &settings,
            precision,
            // No CPU tail, whatever PIDM_GPU_TAIL asks of the run's
            // batches: the shader must finish every instance itself.
            &BatchOptions {
                check: F32Check::Off,
                cpu_tail: Some(0),
                ..BatchOptions::default()
            },
            &mut |_, _| {},
        );
        self.check_health()?;
        let outcomes = outcomes.map_err(|e| fail(e.to_string()))?;
        // f64 mirrors the CPU to rounding; f32 to its own precision.
        let allowance = match precision {
            Precision::F32 => 0.01e-6,
            Precision::F64 => 1e-12,
        };
        for (inst, got) in instances.iter().zip(&outcomes) {
            // An instance the batch handed to the CPU (a failure or a graze
            // in f32, the loop limiter) would compare the CPU with itself:
            // the shader must finish every self-test instance on its own.
            if got.cpu_fallback || got.finished_on_cpu {
                return Err(fail(format!(
                    "the shader ended an instance with status {} and left it to the CPU",
                    got.shader_status
                )));
            }
            let want = reduce(inst, &run_instance(inst, &settings).ended());
            if got.status != want.status || got.lag != want.lag {
                return Err(fail(format!(
                    "status {} and cycle {} periods where the CPU ends with {} and {}",
                    got.status, got.lag, want.status, want.lag
                )));
            }
            for axis in 0..2 {
                let step = |m: &GpuOutcome| inst.measure_over(axis, m.displacement[axis], m.span).1;
                let (g, w) = (
                    step(got),
                    inst.measure_over(axis, want.travel[axis], want.span).1 + skew.step,
                );
                let err = (g - w).abs();
                if err.is_nan() || err > allowance {
                    return Err(fail(format!(
                        "axis {axis} steps {g:.6e} m where the CPU gives {w:.6e} m, {err:.2e} m \
                         apart, more than the {allowance:.0e} m allowed in {precision}"
                    )));
                }
            }
            if settings.backward {
                backward_self_test(
                    inst,
                    &settings,
                    got.variation,
                    (skew.backward, BACKWARD_ALLOWANCE_M),
                )
                .map_err(fail)?;
            }
        }
        Ok(())
    }
}

/// Compiles the integrator's `variant` on a device (its precision, the
/// `loop_limiter` of llvmpipe, the parts its batches need), through the
/// driver's pipeline `cache` where there is one. The source is validated
/// with naga first, so errors come with source locations.
pub fn create_pipeline(
    device: &wgpu::Device,
    variant: Variant,
    cache: Option<&wgpu::PipelineCache>,
) -> Result<wgpu::ComputePipeline, GpuError> {
    let precision = variant.precision;
    shader::parse_and_validate(variant)?;
    let src = shader::source(variant);
    // SAFETY: every array index in the shader is a constant or a counter of
    // a loop bounded by the array's length, the storage arrays are indexed
    // only below both their `arrayLength`s, and every loop is bounded: by a
    // constant, by `max_iterations`, or (the loop-limiter probe) by
    // `control.probe` passes.
    unsafe {
        compile_trusted(
            device,
            src,
            ("shaders/integrate", shader::ENTRY_POINT),
            precision,
            cache,
        )
    }
}

/// Compiles `src` into the compute pipeline of `entry` (`label` names the
/// module in wgpu's messages) without wgpu's runtime checks, and turns any
/// validation or internal error into [`GpuError::ShaderCompile`].
///
/// wgpu's default runtime checks clamp every dynamic array index and add
/// a counter to every loop. Both keep the driver's compiler from unrolling
/// the integrators' short loops, so arrays stay in scratch memory: on
/// lavapipe the Karnopp shader then compiles six times slower and runs four
/// times slower. Compilation happens here for most drivers and at the first
/// dispatch for llvmpipe; either may take seconds.
///
/// # Safety
/// Every array index of the shader must be in bounds and every loop
/// bounded, as the caller states for its shader.
pub(crate) unsafe fn compile_trusted(
    device: &wgpu::Device,
    src: String,
    (label, entry): (&str, &str),
    precision: Precision,
    cache: Option<&wgpu::PipelineCache>,
) -> Result<wgpu::ComputePipeline, GpuError> {
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let internal = device.push_error_scope(wgpu::ErrorFilter::Internal);
    let mut checks = wgpu::ShaderRuntimeChecks::checked();
    checks.bounds_checks = false;
    checks.force_loop_bounding = false;
    // SAFETY: the caller's (this function's contract).
    let module = unsafe {
        device.create_shader_module_trusted(
            wgpu::ShaderModuleDescriptor {
                label: Some(label),
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
        cache,
    });
    let internal = pollster::block_on(internal.pop());
    let validation = pollster::block_on(validation.pop());
    if let Some(e) = validation.or(internal) {
        return Err(GpuError::ShaderCompile {
            precision,
            message: e.to_string(),
        });
    }
    Ok(pipeline)
}

/// What a self-test adds to the CPU reference [m]: its steps' and its
/// backward travels' shifts (zero but in tests of the refusal).
#[derive(Clone, Copy, Debug)]
struct Skew {
    step: f64,
    backward: f64,
}

/// The most a self-test instance's backward travel may differ from the
/// CPU's [m per own drive cycle]: it adds up the velocity zeros each step
/// locates, which fused arithmetic moves on hardware; a thousandth of the
/// cross-check's 1e-3 um (issue 59).
pub const BACKWARD_ALLOWANCE_M: f64 = 1e-10;

/// The self-test of a variant that measures the backward travel: the
/// device's backward travel `got` of `inst` per axis [m per own drive
/// cycle] against the CPU's f64 variation (`Law::run_with_variation_until`),
/// moved by `skew` [m], within `allowed` [m]; either law's.
pub(crate) fn backward_self_test(
    inst: &Instance,
    settings: &Settings,
    got: [f64; 2],
    (skew, allowed): (f64, f64),
) -> Result<(), String> {
    let (run, v) = crate::laws::Law::run_with_variation_until(inst, settings, || false)
        .expect("never asked to stop");
    let (want, _) = crate::measurement::reduce_variation(inst, &run, &v);
    for (axis, (g, w)) in got.into_iter().zip(want).enumerate() {
        let w = w + skew;
        let err = (g - w).abs();
        if err.is_nan() || err > allowed {
            return Err(format!(
                "axis {axis} backward travel {g:.6e} m where the CPU gives {w:.6e} m, {err:.2e} m \
                 apart, more than the {allowed:.0e} m allowed"
            ));
        }
    }
    Ok(())
}
