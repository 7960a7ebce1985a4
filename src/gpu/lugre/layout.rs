//! The structs the shader shares with the host, `#[repr(C)]` and `Pod`:
//! one instance's parameters, a lane's state, and the probes of the
//! function-by-function comparisons.

use super::{LANE_FRESH, LANE_STOPPED};
use bytemuck::{Pod, Zeroable};

use crate::gpu::layout::double::{Gaps, Measure as GpuMeasure, gaps, measure_to_cpu};
use crate::gpu::layout::{F64x2, U32x2};
use crate::laws::floor::Setup;
use crate::laws::floor::measure::SNAPSHOTS;
use crate::laws::floor::phase::LEVELS;
use crate::laws::lugre::run::{Clock, Kept, Linear, N, PeriodStart, Periods, R, State, first_step};
use crate::model::AXES;

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
    /// 1: the shader's `keep` multiplies by it.
    pub one: f64,
    /// Each axis' drive cycles per scene period and phase [cycles]
    /// (`Clock::of`).
    pub cycles: [f64; AXES],
    pub phase: [f64; AXES],
    /// The recurrence test's tolerances and common period
    /// (`Periods::recurrence_test`).
    pub repeat: State,
    pub common_period: u32,
    /// Each axis' first corner and corner count in a waveform variant's
    /// corner buffer (binding 16, [`corner_buffer`]); 0 elsewhere.
    pub corner_first: [u32; AXES],
    pub corner_count: [u32; AXES],
    pub _pad: u32,
}

impl Params {
    /// The parameters of a run's instance.
    pub(super) fn of(book: &Periods) -> Params {
        let inst = &book.inst;
        let m = &book.model;
        let axis = |f: fn(&crate::model::Axis) -> f64| [f(&inst.axes[0]), f(&inst.axes[1])];
        let (repeat, common_period) = book.recurrence_test();
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
            one: 1.0,
            cycles: Clock::cycles_per_period(inst),
            phase: axis(|a| a.phase),
            repeat,
            common_period,
            corner_first: [0; AXES],
            corner_count: [0; AXES],
            _pad: 0,
        }
    }
}

/// One corner of a waveform (`corners.wgsl`'s `Corner`): the cycle phase
/// [cycles] and the level (a fraction of the voltage).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Corner {
    pub u: f64,
    pub level: f64,
}

/// A waveform variant's corner buffer (binding 16): every run's corners
/// (`Periods::drives`, what the CPU's clock reads), x then y, each axis'
/// first entry and count set in its parameters. An axis with more than
/// `MAX_CORNERS` corners is refused.
pub(super) fn corner_buffer(
    books: &[Periods],
    params: &mut [Params],
) -> Result<Vec<Corner>, String> {
    let mut out = Vec::new();
    for (book, p) in books.iter().zip(params.iter_mut()) {
        for (axis, corners) in book.drives.iter().enumerate() {
            let n = corners.points.len();
            if n > super::MAX_CORNERS {
                return Err(format!(
                    "axis {axis} of an instance has {n} drive corners, more than the LuGre \
                     shader's {}",
                    super::MAX_CORNERS
                ));
            }
            p.corner_first[axis] = out.len() as u32;
            p.corner_count[axis] = n as u32;
            out.extend(corners.points.iter().map(|&[u, level]| Corner { u, level }));
        }
    }
    Ok(out)
}

/// One instance's run between dispatches (`entry.wgsl`'s `Lane`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Lane {
    pub y: State,
    /// The state at the last period end (zero before the first): where
    /// the current period started, and the motion the result reports.
    pub last: State,
    /// The next trial step [s], and the one at the current period's start.
    pub h: f64,
    pub start_h: f64,
    /// The current segment's end [s] and drive (a, b per axis).
    pub end: f64,
    pub drive: [f64; 2 * AXES],
    /// The drive's clock of the current scene period [cycles].
    pub clock: [f64; AXES],
    /// The slider's position at the settling periods' end [m].
    pub settle_x_s: [f64; AXES],
    /// Steps the run may still take, now and at the current period's
    /// start.
    pub budget: u32,
    pub start_budget: u32,
    /// Steps of the completed segments (saturating), now and before the
    /// current period.
    pub steps: u32,
    pub start_steps: u32,
    /// Attempts in the current segment.
    pub segment_steps: u32,
    /// 1 after a rejected attempt in the current segment.
    pub rejected: u32,
    /// 1 inside a segment.
    pub in_segment: u32,
    /// `STATUS_OK`, or why the run failed.
    pub status: u32,
    /// Scene periods completed, and the measurement's verdict
    /// (`State::measured`: 0 while running).
    pub period: u32,
    pub measured: u32,
    /// `LANE_FRESH`, `LANE_RUNNING` or `LANE_STOPPED`.
    pub flag: u32,
    pub _pad: u32,
}

/// A run's constants (`measure.wgsl`'s `Coefficients`): the floor's
/// measurement constants ([`Setup`]), by the names the floor's shader
/// reads, and the periods the run may integrate.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Coefficients {
    pub se_limit2: F64x2,
    pub period: f64,
    pub period_lo: f64,
    pub repeat_x: f64,
    pub repeat_v: f64,
    pub cycles: u32,
    pub settle: u32,
    pub steady: u32,
    pub common_period: u32,
    pub batch_length: u32,
    pub min_batch: u32,
    pub phase_levels: u32,
    pub phase_lattice: u32,
    pub replica: u32,
    pub replicas: u32,
    pub _pad: U32x2,
    pub gaps: [Gaps; LEVELS],
}

impl Coefficients {
    /// The constants of a run of `cycles` periods with measurement `g`.
    pub fn of(g: &Setup, cycles: u32) -> Coefficients {
        Coefficients {
            se_limit2: F64x2 {
                x: g.se_limit2.x,
                y: g.se_limit2.y,
            },
            period: g.period,
            period_lo: g.period_lo,
            repeat_x: g.repeat_x,
            repeat_v: g.repeat_v,
            cycles,
            settle: g.settle,
            steady: g.steady as u32,
            common_period: g.common_period,
            batch_length: g.batch_length,
            min_batch: g.min_batch,
            phase_levels: g.phase_levels,
            phase_lattice: g.phase_lattice,
            replica: g.replica,
            replicas: g.replicas,
            _pad: U32x2::default(),
            gaps: gaps(&g.gaps),
        }
    }
}

impl crate::gpu::layout::HostLayout for Coefficients {
    const NAME: &'static str = "Coefficients";
    fn members() -> Vec<(&'static str, usize)> {
        use std::mem::offset_of;
        vec![
            ("se_limit2", offset_of!(Coefficients, se_limit2)),
            ("period", offset_of!(Coefficients, period)),
            ("period_lo", offset_of!(Coefficients, period_lo)),
            ("repeat_x", offset_of!(Coefficients, repeat_x)),
            ("repeat_v", offset_of!(Coefficients, repeat_v)),
            ("cycles", offset_of!(Coefficients, cycles)),
            ("settle", offset_of!(Coefficients, settle)),
            ("steady", offset_of!(Coefficients, steady)),
            ("common_period", offset_of!(Coefficients, common_period)),
            ("batch_length", offset_of!(Coefficients, batch_length)),
            ("min_batch", offset_of!(Coefficients, min_batch)),
            ("phase_levels", offset_of!(Coefficients, phase_levels)),
            ("phase_lattice", offset_of!(Coefficients, phase_lattice)),
            ("replica", offset_of!(Coefficients, replica)),
            ("replicas", offset_of!(Coefficients, replicas)),
            ("_pad", offset_of!(Coefficients, _pad)),
            ("gaps", offset_of!(Coefficients, gaps)),
        ]
    }
}

impl crate::gpu::layout::HostLayout for Lane {
    const NAME: &'static str = "Lane";
    fn members() -> Vec<(&'static str, usize)> {
        use std::mem::offset_of;
        vec![
            ("y", offset_of!(Lane, y)),
            ("last", offset_of!(Lane, last)),
            ("h", offset_of!(Lane, h)),
            ("start_h", offset_of!(Lane, start_h)),
            ("end", offset_of!(Lane, end)),
            ("drive", offset_of!(Lane, drive)),
            ("clock", offset_of!(Lane, clock)),
            ("settle_x_s", offset_of!(Lane, settle_x_s)),
            ("budget", offset_of!(Lane, budget)),
            ("start_budget", offset_of!(Lane, start_budget)),
            ("steps", offset_of!(Lane, steps)),
            ("start_steps", offset_of!(Lane, start_steps)),
            ("segment_steps", offset_of!(Lane, segment_steps)),
            ("rejected", offset_of!(Lane, rejected)),
            ("in_segment", offset_of!(Lane, in_segment)),
            ("status", offset_of!(Lane, status)),
            ("period", offset_of!(Lane, period)),
            ("measured", offset_of!(Lane, measured)),
            ("flag", offset_of!(Lane, flag)),
        ]
    }
}

impl Lane {
    /// A run at rest before its first period, as the CPU's starts: the
    /// device starts its measurement and first period (`LANE_FRESH`).
    pub(super) fn start(book: &Periods) -> Lane {
        Lane {
            h: first_step(&book.inst),
            budget: book.budget,
            flag: LANE_FRESH,
            ..Lane::zeroed()
        }
    }

    /// Where the lane's current period starts (the CPU tail continues
    /// from there).
    pub(super) fn period_start(&self) -> PeriodStart {
        PeriodStart {
            y: self.last,
            h: self.start_h,
            budget: self.start_budget,
        }
    }

    /// The run as the device kept it, with its measurement's accumulators
    /// and recurrence snapshots: where the CPU continues a running lane
    /// (its steps before the current period), or a stopped lane's result.
    pub(super) fn kept(&self, measure: &GpuMeasure, recurrence: &Recurrence) -> Kept {
        Kept {
            y: self.last,
            period: self.period,
            measured: self.measured,
            steps: if self.flag == LANE_STOPPED {
                self.steps
            } else {
                self.start_steps
            },
            status: self.status,
            settle_x_s: self.settle_x_s,
            measure: measure_to_cpu(measure),
            snaps: recurrence.snaps,
            taken: recurrence.taken,
        }
    }
}

/// The bytes of one instance's Rodas4 stages in device memory
/// (`rodas.wgsl`'s `stages`, binding 14: six states): only the shader
/// reads and writes them; the host sizes the buffer.
pub const STAGE_BYTES: usize = 6 * size_of::<State>();

/// One instance's stage matrix W in device memory (`rodas.wgsl`'s `W` in
/// `ws`, binding 15): its LU factorisation (`Lu`'s `a` and `pivot`), g,
/// and the Jacobian's position and time columns on the reduced rows. Only
/// the shader reads and writes it; the host sizes the buffer.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct StageMatrix {
    pub lu: [[f64; R]; R],
    pub pivot: [u32; R],
    pub g: f64,
    pub j_xp: [[f64; 2]; R],
    pub j_t: [f64; R],
}

/// One instance's recurrence snapshots (`measure.wgsl`'s `Recurrence`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Recurrence {
    pub snaps: [State; SNAPSHOTS],
    pub taken: u32,
    pub _pad: u32,
}

/// A state, drive and step at which `mirror_on_gpu` evaluates the
/// shader's functions (`entry.wgsl`'s `Probe`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Probe {
    pub y: State,
    /// a, b per axis.
    pub drive: [f64; 2 * AXES],
    pub h: f64,
}

/// The shader's right-hand side, Jacobian and Rodas4 step at a [`Probe`]
/// (`entry.wgsl`'s `Probed`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Probed {
    pub rhs: State,
    pub jacobian: [State; N],
    pub next: State,
    pub error: State,
}

/// A lane's drive as the CPU's.
pub(super) fn drive_of(drive: &[f64; 2 * AXES]) -> [Linear; AXES] {
    std::array::from_fn(|i| Linear {
        a: drive[2 * i],
        b: drive[2 * i + 1],
    })
}

/// What `LugreGpu::mirror_check` found: counts of results that differ
/// from the CPU's in any bit, and the largest relative difference of a
/// component where they differ.
#[derive(Clone, Copy, Debug, Default)]
pub struct MirrorCheck {
    /// Step attempts followed.
    pub attempts: usize,
    /// Segments started, and those whose end or drive differed.
    pub segments: usize,
    pub segment_mismatches: usize,
    /// Attempts whose state after differed.
    pub state_mismatches: usize,
    /// Attempts whose next step size compares (the lane's `rejected`
    /// false), and those where it differed.
    pub step_sizes: usize,
    pub step_size_mismatches: usize,
    /// States at which the right-hand side, the Jacobian and the Rodas4
    /// step were evaluated, and where each differed.
    pub probes: usize,
    pub rhs_mismatches: usize,
    pub jacobian_mismatches: usize,
    pub rodas4_mismatches: usize,
    pub rhs_worst: f64,
    pub jacobian_worst: f64,
    pub next_worst: f64,
    /// The largest differences in units of the run's error control
    /// (`laws::lugre::run::error_scale`, each state's largest local error):
    /// the right-hand side's times the attempt's step, and the Rodas4
    /// step's next state and error estimate, both in units of the
    /// estimate where it exceeds its tolerance (a rejected attempt, whose
    /// next state is discarded: on the stiff instance, sigma0 1e10 N/m,
    /// such attempts run to 1e8 m/s, and the H200 put their states 3,092
    /// tolerances apart, 1.1e-7 relatively). A component that cancels
    /// (the bristle equation near its steady deflection, a force balance)
    /// differs relatively much where a compiler fuses or reorders its
    /// terms; measured so, rounding stays far below the tolerance.
    pub rhs_scaled_worst: f64,
    pub next_scaled_worst: f64,
}

#[cfg(test)]
mod tests;
