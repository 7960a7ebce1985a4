//! Which of a steady batch's accumulators come back to the host.
//!
//! Every steady instance has 2,048 bytes of accumulators in f64 (1,112 in
//! f32), and reading 1,264 of them back (before the phase ladder) cost an
//! H200 0.6 s of a 1000 x 1000 map whose shader ran 0.1-0.25 s
//! (results/gpu.md, "Where a steady map's GPU time goes"). The reduction
//! of a periodic verdict, which most runs at equal drive frequencies
//! reach, and of a phase-resolved one, which most two-frequency runs
//! reach, reads only the `Head` the shader writes when an instance
//! finishes (48 bytes in f64). So the host reads every head, and the whole
//! accumulators only of the instances that need them: those that ended
//! otherwise, and those the CPU continues. Also the mapping of any
//! readback buffer.

use super::{GpuError, Lanes};
use crate::model::{Instance, Measure};

/// How a steady batch's accumulators are read back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accumulators {
    /// The heads alone: every instance's reduction reads only its head.
    Heads,
    /// The heads, and the whole accumulators of the instances that need
    /// them, copied on the device into one buffer, a copy per run of
    /// consecutive instances.
    Gather,
    /// Every instance's whole accumulators, in one copy.
    Whole,
}

/// The largest share of a batch whose accumulators are gathered, as a
/// divisor: a sixteenth. Beyond it the batch reads them whole, in one
/// copy, rather than recording up to one copy per instance (their cost on
/// a GPU is not measured).
pub const GATHER_DIVISOR: usize = 16;

/// How to read back the accumulators of a batch of `n` steady instances of
/// which `needed` need theirs whole; `whole` forces [`Accumulators::Whole`]
/// (tests compare the others with it).
pub fn plan(n: usize, needed: usize, whole: bool) -> Accumulators {
    if whole || needed * GATHER_DIVISOR > n {
        Accumulators::Whole
    } else if needed == 0 {
        Accumulators::Heads
    } else {
        Accumulators::Gather
    }
}

/// The runs of consecutive indices in `sorted` (ascending, distinct), as
/// (first, length): one device copy each.
pub fn runs(sorted: &[usize]) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    for &k in sorted {
        match out.last_mut() {
            Some((first, length)) if *first + *length == k => *length += 1,
            _ => out.push((k, 1)),
        }
    }
    out
}

/// The accumulators of a steady batch's instances
/// ([`Accumulators`]): every instance's head, mapped from
/// `heads_read` (already copied there), and the whole accumulators from
/// `measures` of those that need them: the steady instances that did
/// not finish with a periodic or phase-resolved verdict, whose reduction reads more than
/// the head, or did not finish at all (the CPU may continue them).
pub(super) fn accumulators<L: Lanes>(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    whole: bool,
    instances: &[Instance],
    states: &[L::State],
    (heads_read, measures): (&wgpu::Buffer, &wgpu::Buffer),
    read: &mut AccumulatorsRead,
) -> Result<Vec<L::Measure>, GpuError> {
    let n = instances.len();
    let heads: Vec<L::Head> = with_mapped(device, heads_read, |bytes| {
        bytes
            .chunks_exact(size_of::<L::Head>())
            .map(bytemuck::pod_read_unaligned)
            .collect()
    })?;
    let needed: Vec<usize> = (0..n)
        .filter(|&k| {
            matches!(instances[k].measure, Measure::Steady { .. })
                && !(L::finished(&instances[k], &states[k]) && L::head_suffices(&heads[k]))
        })
        .collect();
    read.plan = plan(n, needed.len(), whole);
    let size = size_of::<L::Measure>() as u64;
    // The copies (source instance, length) into one mappable buffer.
    let copies = match read.plan {
        Accumulators::Heads => {
            return Ok(heads.iter().map(L::from_head).collect());
        }
        Accumulators::Gather => runs(&needed),
        Accumulators::Whole => vec![(0, n)],
    };
    read.count = copies.iter().map(|&(_, length)| length).sum();
    let target = mappable(device, "measures readback", read.count as u64 * size);
    let mut encoder = device.create_command_encoder(&Default::default());
    let mut at = 0u64;
    for &(first, length) in &copies {
        let bytes = length as u64 * size;
        encoder.copy_buffer_to_buffer(measures, first as u64 * size, &target, at, bytes);
        at += bytes;
    }
    queue.submit([encoder.finish()]);
    let copied: Vec<L::Measure> = with_mapped(device, &target, |bytes| {
        bytes
            .chunks_exact(size_of::<L::Measure>())
            .map(bytemuck::pod_read_unaligned)
            .collect()
    })?;
    if read.plan == Accumulators::Whole {
        return Ok(copied);
    }
    let mut list: Vec<L::Measure> = heads.iter().map(L::from_head).collect();
    for (&k, m) in needed.iter().zip(copied) {
        list[k] = m;
    }
    Ok(list)
}

/// Every instance's backward-travel entry (the second half of
/// `measures`, whose first `n` entries of that half are the instances':
/// `shaders/karnopp/variation.wgsl`'s `variation_slot`).
pub(super) fn variations<L: Lanes>(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    measures: &wgpu::Buffer,
    n: usize,
) -> Result<Vec<L::Measure>, GpuError> {
    let bytes = (n * size_of::<L::Measure>()) as u64;
    let target = mappable(device, "variations readback", bytes);
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(measures, measures.size() / 2, &target, 0, bytes);
    queue.submit([encoder.finish()]);
    with_mapped(device, &target, |bytes| {
        bytes
            .chunks_exact(size_of::<L::Measure>())
            .map(bytemuck::pod_read_unaligned)
            .collect()
    })
}

/// A buffer of `size` bytes that the device copies results into and the
/// host maps to read them.
pub(super) fn mappable(device: &wgpu::Device, label: &str, size: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Copies a mappable buffer's contents to the host.
pub(super) fn read_buffer(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
) -> Result<Vec<u8>, GpuError> {
    with_mapped(device, buffer, <[u8]>::to_vec)
}

/// How a steady batch's accumulators came back ([`accumulators`]).
pub(super) struct AccumulatorsRead {
    pub plan: Accumulators,
    /// Whole accumulators copied back.
    pub count: usize,
}

impl Default for AccumulatorsRead {
    fn default() -> Self {
        AccumulatorsRead {
            plan: Accumulators::Heads,
            count: 0,
        }
    }
}

/// Maps a mappable buffer for reading and hands its bytes to `read`, with
/// no copy of them on the host.
pub(super) fn with_mapped<T>(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T, GpuError> {
    with_mapped_prefix(device, buffer, buffer.size(), read)
}

/// [`with_mapped`] of the buffer's first `len` bytes (a multiple of 4, at
/// least 4).
pub(super) fn with_mapped_prefix<T>(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    len: u64,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T, GpuError> {
    let slice = buffer.slice(..len);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::BufferMapping(e.to_string()))?;
    rx.recv()
        .map_err(|e| GpuError::BufferMapping(e.to_string()))?
        .map_err(|e| GpuError::BufferMapping(e.to_string()))?;
    let out = {
        let view = slice
            .get_mapped_range()
            .map_err(|e| GpuError::BufferMapping(e.to_string()))?;
        read(&view)
    };
    buffer.unmap();
    Ok(out)
}

/// Whether any instance of a batch measures the steady step (its batch
/// then needs one set of accumulators per instance).
pub(super) fn any_steady(instances: &[Instance]) -> bool {
    instances
        .iter()
        .any(|inst| matches!(inst.measure, Measure::Steady { .. }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `plan(n, needed, whole)` is `expected`.
    fn check(n: usize, needed: usize, whole: bool, expected: Accumulators) {
        assert_eq!(plan(n, needed, whole), expected, "{n} {needed} {whole}");
    }

    #[test]
    fn heads_alone_where_none_needs_more_then_gathered_up_to_a_sixteenth() {
        check(1000, 0, false, Accumulators::Heads);
        check(1000, 1, false, Accumulators::Gather);
        check(1600, 100, false, Accumulators::Gather);
        check(1600, 101, false, Accumulators::Whole);
        check(10, 1, false, Accumulators::Whole);
        check(1000, 0, true, Accumulators::Whole);
    }

    /// The sizes the module's documentation, docs/steady.md and results/gpu.md
    /// quote: a head of 48 bytes in f64 (32 in f32) against accumulators of
    /// 2,048 (1,112), of which the phase ladder's windows
    /// (`laws::floor::phase`) take 752 (376), a replica's sums for its
    /// group's merge 112 (56) of those.
    #[test]
    fn a_head_is_a_fortieth_of_the_accumulators_in_f64() {
        use crate::gpu::layout::{double, single};
        assert_eq!(size_of::<double::Head>(), 48);
        assert_eq!(size_of::<double::Measure>(), 2048);
        assert_eq!(size_of::<double::Phase>(), 752);
        assert_eq!(size_of::<double::LevelSums>(), 112);
        assert_eq!(size_of::<single::Head>(), 32);
        assert_eq!(size_of::<single::Measure>(), 1112);
        assert_eq!(size_of::<single::Phase>(), 376);
        assert_eq!(size_of::<single::LevelSums>(), 56);
    }

    #[test]
    fn consecutive_indices_make_one_run() {
        assert_eq!(runs(&[]), vec![]);
        assert_eq!(runs(&[4]), vec![(4, 1)]);
        assert_eq!(runs(&[0, 1, 2, 5, 7, 8]), vec![(0, 3), (5, 1), (7, 2)]);
    }
}
