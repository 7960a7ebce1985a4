//! What a sweep prepares for the device ahead of a batch: batch and chunk
//! sizes from the adapter's limits, and the batch's coefficients packed on the
//! host ([`Packed`]) while the batch before it integrates.

use super::*;

/// Largest number of instances one dispatch batch may hold on a device.
pub fn max_batch_instances(
    limits: &wgpu::Limits,
    coefficients_size: usize,
    state_size: usize,
    options: &BatchOptions,
) -> usize {
    let largest = coefficients_size.max(state_size);
    let mut n = batch_limit(limits, largest, workgroup_size());
    if let Some(m) = options.max_batch {
        n = n.min(m);
    }
    n.max(1)
}

/// The most instances one batch of any law may hold: what a storage
/// binding and a buffer hold of its largest per-instance entry (`largest`
/// bytes) and what one dispatch of `workgroup_size` invocations reaches
/// (Karnopp's through [`max_batch_instances`], LuGre's in `gpu::lugre`).
pub fn batch_limit(limits: &wgpu::Limits, largest: usize, workgroup_size: u32) -> usize {
    let binding = limits.max_storage_buffer_binding_size;
    let buffer = limits.max_buffer_size;
    let by_memory = binding.min(buffer) / largest as u64;
    let dim = limits.max_compute_workgroups_per_dimension as u64;
    let by_dispatch = dim * dim * workgroup_size as u64;
    by_memory.min(by_dispatch).min(usize::MAX as u64).max(1) as usize
}

/// Accumulator entries per steady instance: two where the shader updates
/// a lane's scratch entry and copies it back (`loop_limiter`: a cut update
/// must leave no trace), one where it updates the instance's own in place.
pub(super) fn measure_entries(loop_limiter: bool) -> usize {
    if loop_limiter { 2 } else { 1 }
}

/// Instances per sweep chunk on `ctx` in `precision`: the lanes the
/// adapter keeps busy ([`GpuContext::lanes`]) [`CHUNK_ROUNDS`] times over
/// ([`SOFTWARE_CHUNK_ROUNDS`] on a software adapter),
/// so that lanes take instances from the queue for most of a chunk, but at
/// most what one batch of steady instances may hold on the device
/// ([`max_batch_instances`] of its limits). A map larger than that is
/// several chunks, so the device integrates one while the host writes the
/// one before and expands the one after (`crate::sweep::run_chunks`).
pub fn chunk_instances(ctx: &GpuContext, precision: Precision) -> usize {
    let limiter = ctx.variant(precision, Parts::default()).loop_limiter;
    fn of<L: Layout>(limits: &wgpu::Limits, limiter: bool) -> usize {
        let measure = size_of::<L::Measure>() * measure_entries(limiter);
        let state = size_of::<L::State>().max(measure);
        max_batch_instances(
            limits,
            size_of::<L::Coefficients>(),
            state,
            &BatchOptions::default(),
        )
    }
    let batch = match precision {
        Precision::F32 => of::<Single>(&ctx.limits, limiter),
        Precision::F64 => of::<Double>(&ctx.limits, limiter),
    };
    let rounds = if ctx.is_hardware() {
        CHUNK_ROUNDS
    } else {
        SOFTWARE_CHUNK_ROUNDS
    };
    batch.min(rounds * ctx.lanes()).max(1)
}

/// The coefficients of a batch's instances, packed for the device ahead of
/// its turn ([`pack`]): the sweep's driver packs chunk k+1 while the
/// device integrates chunk k.
pub struct Packed {
    settings: Settings,
    coefficients: PackedCoefficients,
}

/// Each precision's coefficients, as the device takes them.
enum PackedCoefficients {
    F32(Vec<<Single as Lanes>::Coefficients>),
    F64(Vec<<Double as Lanes>::Coefficients>),
}

impl Packed {
    /// The bytes to upload, where they were packed for `count` instances
    /// in `precision` under `settings`.
    pub(super) fn bytes_for(
        &self,
        count: usize,
        precision: Precision,
        settings: &Settings,
    ) -> Option<&[u8]> {
        if self.settings != *settings {
            return None;
        }
        match (&self.coefficients, precision) {
            (PackedCoefficients::F32(c), Precision::F32) if c.len() == count => {
                Some(bytemuck::cast_slice(c))
            }
            (PackedCoefficients::F64(c), Precision::F64) if c.len() == count => {
                Some(bytemuck::cast_slice(c))
            }
            _ => None,
        }
    }
}

/// Packs `instances`' coefficients for a batch in `precision` under
/// `settings`, in parallel: what [`run_batch_packed`] would otherwise do
/// first.
pub fn pack(instances: &[Instance], settings: &Settings, precision: Precision) -> Packed {
    fn of<L: Layout>(instances: &[Instance], settings: &Settings) -> Vec<L::Coefficients> {
        instances
            .par_iter()
            .map(|inst| L::pack(inst, settings))
            .collect()
    }
    Packed {
        settings: *settings,
        coefficients: match precision {
            Precision::F32 => PackedCoefficients::F32(of::<Single>(instances, settings)),
            Precision::F64 => PackedCoefficients::F64(of::<Double>(instances, settings)),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_respect_binding_limits() {
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: 1000,
            ..wgpu::Limits::default()
        };
        assert_eq!(
            max_batch_instances(&limits, 100, 200, &BatchOptions::default()),
            5
        );
        let small = BatchOptions {
            max_batch: Some(3),
            ..BatchOptions::default()
        };
        assert_eq!(max_batch_instances(&limits, 100, 200, &small), 3);
    }
}
