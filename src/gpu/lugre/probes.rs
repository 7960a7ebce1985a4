//! The comparisons the tests run on a device: the shader's functions and
//! steps against the CPU's, from the same inputs.

use super::layout::drive_of;
use super::runner::{Lugre, compile};
use super::{
    Arithmetic, FUNCTIONS_ENTRY_POINT, LANE_FRESH, LANE_STOPPED, Lane, LugreGpu,
    MIRROR_ENTRY_POINT, MirrorCheck, Params, Probe, Probed,
};
use crate::gpu::lanes::Work;
use crate::gpu::runner::Runner;

use bytemuck::Zeroable;
use wgpu::util::DeviceExt;

use crate::gpu::GpuError;
use crate::gpu::readback::{mappable, read_buffer};
use crate::laws::Settings;
use crate::laws::lugre::run::{Clock, Linear, Periods, T, rodas4, segment};
use crate::laws::status::STATUS_OK;
use crate::model::{AXES, Instance};

impl LugreGpu<'_> {
    /// Follows `inst`'s run for `attempts` step attempts, one per dispatch,
    /// and compares the shader with the CPU function by function from the
    /// same inputs: each segment's end and drive (`next_corner`,
    /// `drive_on`), each attempt's state and next step (`segment`), and at
    /// the state before each attempt the right-hand side, the Jacobian and
    /// the Rodas4 step.
    pub fn mirror_check(
        &self,
        inst: &Instance,
        settings: &Settings,
        attempts: usize,
    ) -> Result<MirrorCheck, GpuError> {
        let book = Periods::new(inst, settings);
        let params = Params::of(&book);
        let mut lane = Lane::start(&book);
        // The lane through the engine's protocol, one attempt a dispatch.
        let options = self.options();
        let (coefficients, states, extra) = self.upload(std::slice::from_ref(&book))?;
        let bound: Vec<(u32, &wgpu::Buffer)> =
            extra.iter().map(|(b, buffer)| (*b, buffer)).collect();
        let runner = Runner::on(self.ctx, settings, &options);
        let work = Work {
            instances: std::slice::from_ref(inst),
            coefficients: &coefficients,
            states: Some(&states),
        };
        let stepper = runner.stepper::<Lugre>(work, self.kernel(&bound), 1);
        let mut check = MirrorCheck::default();
        let mut probes = Vec::new();
        let mut drives = Vec::new();
        let period = inst.period();
        let corners = inst
            .axes
            .map(|a| crate::laws::floor::drive::axis_corners(&a));
        while check.attempts < attempts && lane.flag != LANE_STOPPED {
            let mut before = lane;
            let after = stepper.step::<Lugre>()?[0];
            lane = after;
            if after.clock != Clock::of(inst, after.period).start {
                check.segment_mismatches += 1;
            }
            let in_segment = before.in_segment == 1 && before.y[T] < before.end;
            let at_end = !in_segment && before.y[T] >= period;
            if before.flag == LANE_FRESH || at_end {
                if after.flag == LANE_STOPPED && after.status == STATUS_OK {
                    // The run ended there, without an attempt.
                    continue;
                }
                // The device started a period (measuring the one that
                // ended): compare the attempt from that start.
                before.y[T] = 0.0;
                before.clock = after.clock;
                before.in_segment = 0;
            }
            let clock = Clock {
                start: before.clock,
            };
            let within = before.in_segment == 1 && before.y[T] < before.end;
            let (end, drive) = if within {
                (before.end, drive_of(&before.drive))
            } else {
                // The segment the lane starts, as the CPU's run starts it.
                let end = (0..AXES)
                    .map(|i| clock.next_corner(inst, &corners[i], i, before.y[T]))
                    .fold(period, f64::min);
                let mid = 0.5 * (before.y[T] + end);
                let drive = [0, 1].map(|i| clock.drive_on(inst, &corners[i], i, mid));
                check.segments += 1;
                if after.end != end
                    || drive_of(&after.drive).map(|l| (l.a, l.b)) != drive.map(|l| (l.a, l.b))
                {
                    check.segment_mismatches += 1;
                }
                (end, drive)
            };
            // The CPU's segment from the same state, for one attempt (its
            // `rejected` starts false: the step size compares where the
            // lane's was too).
            let (mut y, mut h, mut budget) = (before.y, before.h, 1);
            let last = y[T] + h >= end * (1.0 - 1e-15);
            let step = if last { end - y[T] } else { h };
            let _ = segment(
                &book.model,
                &drive,
                &book.scale,
                &mut y,
                end,
                (&mut h, &mut budget),
                &mut |_, _| {},
            );
            check.attempts += 1;
            if y != after.y {
                check.state_mismatches += 1;
            }
            if !within || before.rejected == 0 {
                check.step_sizes += 1;
                if h != after.h {
                    check.step_size_mismatches += 1;
                }
            }
            probes.push(Probe {
                y: before.y,
                drive: [drive[0].a, drive[0].b, drive[1].a, drive[1].b],
                h: step,
            });
            drives.push(drive);
        }
        let probed = self.mirror_on_gpu(&params, &probes)?;
        compare_probes(&book, &probes, &drives, &probed, &mut check);
        Ok(check)
    }

    /// The shader's `rhs`, `jacobian` and `rodas4` for the instance with
    /// `params` at each of `probes` (the tests compare them with the CPU's
    /// functions).
    pub fn mirror_on_gpu(
        &self,
        params: &Params,
        probes: &[Probe],
    ) -> Result<Vec<Probed>, GpuError> {
        if probes.is_empty() {
            return Ok(Vec::new());
        }
        let device = self.ctx.device();
        let shape = (self.workgroup_size, self.arithmetic, self.form);
        let pipeline = compile(device, shape, MIRROR_ENTRY_POINT, None)?;
        let storage = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | usage,
            })
        };
        // The model once per probe: each invocation reads its own
        // (`models[held]`), as a batch's lanes do.
        let models = storage(
            "lugre probe model",
            bytemuck::cast_slice(&vec![*params; probes.len()]),
            wgpu::BufferUsages::empty(),
        );
        let input = storage(
            "lugre probes",
            bytemuck::cast_slice(probes),
            wgpu::BufferUsages::empty(),
        );
        let bytes = (probes.len() * size_of::<Probed>()) as u64;
        let output = storage(
            "lugre probed",
            &vec![0; bytes as usize],
            wgpu::BufferUsages::COPY_SRC,
        );
        let read = mappable(device, "lugre probed read", bytes);
        // Room for each probe's stages and W where the lane holds them in
        // device memory (hold_memory.wgsl).
        let stages = storage(
            "lugre probe stages",
            &vec![0; probes.len() * super::layout::STAGE_BYTES],
            wgpu::BufferUsages::empty(),
        );
        let matrices = storage(
            "lugre probe stage matrices",
            &vec![0; probes.len() * size_of::<super::layout::StageMatrix>()],
            wgpu::BufferUsages::empty(),
        );
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 9,
                resource: models.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 12,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 13,
                resource: output.as_entire_binding(),
            },
        ];
        if self.arithmetic == Arithmetic::Fused {
            entries.extend([
                wgpu::BindGroupEntry {
                    binding: 14,
                    resource: stages.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 15,
                    resource: matrices.as_entire_binding(),
                },
            ]);
        }
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lugre mirror"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups((probes.len() as u32).div_ceil(self.workgroup_size), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&output, 0, &read, 0, bytes);
        self.ctx.queue().submit([encoder.finish()]);
        let out = read_buffer(device, &read)?;
        Ok(out
            .chunks_exact(size_of::<Probed>())
            .map(bytemuck::pod_read_unaligned)
            .collect())
    }

    /// The shader's `exp_nonpositive(x)`, `hypot(x, y)` and
    /// `fourth_root(|y|)` of each (x, y) of `args`, computed on the device
    /// (the tests compare them with `exp_nonpositive`, `hypot` and
    /// `fourth_root`).
    pub fn functions_on_gpu(&self, args: &[(f64, f64)]) -> Result<Vec<[f64; 3]>, GpuError> {
        if args.is_empty() {
            return Ok(Vec::new());
        }
        let device = self.ctx.device();
        let shape = (self.workgroup_size, self.arithmetic, self.form);
        let pipeline = compile(device, shape, FUNCTIONS_ENTRY_POINT, None)?;
        let values: Vec<f64> = args
            .iter()
            .flat_map(|&(x, y)| [x, y, 0.0, 0.0, 0.0])
            .collect();
        let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lugre functions"),
            contents: bytemuck::cast_slice(&values),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let bytes = buffer.size();
        let read = mappable(device, "lugre functions read", bytes);
        let one = Params {
            one: 1.0,
            ..Params::zeroed()
        };
        let models = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lugre functions' one"),
            contents: bytemuck::bytes_of(&one),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lugre functions"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 9,
                    resource: models.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 11,
                    resource: buffer.as_entire_binding(),
                },
            ],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups((args.len() as u32).div_ceil(self.workgroup_size), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&buffer, 0, &read, 0, bytes);
        self.ctx.queue().submit([encoder.finish()]);
        let out: Vec<f64> = read_buffer(device, &read)?
            .chunks_exact(8)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        Ok(out.chunks_exact(5).map(|v| [v[2], v[3], v[4]]).collect())
    }
}

/// The largest relative difference of two arrays' components (0 where
/// they are equal).
fn relative(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0_f64, |m, (x, y)| {
        if x == y {
            m
        } else {
            m.max((x - y).abs() / x.abs().max(y.abs()))
        }
    })
}

/// The largest difference in units of `per` component.
fn scaled(a: &[f64], b: &[f64], per: &dyn Fn(usize) -> f64) -> f64 {
    a.iter()
        .zip(b)
        .enumerate()
        .fold(0.0_f64, |m, (i, (x, y))| m.max((x - y).abs() / per(i)))
}

/// Counts in `check` where the shader's `rhs`, `jacobian` and `rodas4`
/// (`probed`) differ from the CPU's at each of `probes` with its `drives`.
fn compare_probes(
    book: &Periods,
    probes: &[Probe],
    drives: &[[Linear; AXES]],
    probed: &[Probed],
    check: &mut MirrorCheck,
) {
    for ((probe, drive), gpu) in probes.iter().zip(drives).zip(probed) {
        let rhs = book.model.rhs(&probe.y, drive);
        let jacobian = book.model.jacobian(&probe.y, drive);
        let (next, error) = rodas4(&book.model, drive, &probe.y, probe.h);
        check.probes += 1;
        if rhs != gpu.rhs {
            check.rhs_mismatches += 1;
            check.rhs_worst = check.rhs_worst.max(relative(&rhs, &gpu.rhs));
            let per_step = |i: usize| book.scale[i] / probe.h;
            let worst = scaled(&rhs, &gpu.rhs, &per_step);
            check.rhs_scaled_worst = check.rhs_scaled_worst.max(worst);
        }
        if jacobian != gpu.jacobian {
            check.jacobian_mismatches += 1;
            check.jacobian_worst = check.jacobian_worst.max(relative(
                jacobian.as_flattened(),
                gpu.jacobian.as_flattened(),
            ));
        }
        if next != gpu.next || error != gpu.error {
            check.rodas4_mismatches += 1;
            check.next_worst = check.next_worst.max(relative(&next, &gpu.next));
            // An attempt whose error estimate exceeds the tolerance is
            // rejected whatever its rounding (its next state discarded):
            // there both are compared in units of the estimate itself.
            let per = |i: usize| book.scale[i].max(error[i].abs());
            let worst = scaled(&next, &gpu.next, &per).max(scaled(&error, &gpu.error, &per));
            check.next_scaled_worst = check.next_scaled_worst.max(worst);
        }
    }
}
