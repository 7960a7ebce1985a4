//! Host mirrors of the shader's storage structs, one set per precision, and
//! the packing of instances into them.
//!
//! Every struct here has a WGSL twin of the same name in
//! `shaders/integrate.wgsl`. Padding is explicit, so the structs are `Pod`
//! and their bytes are exactly what the shader reads; the test
//! `shader_layout_matches_host_structs` checks every size and member offset
//! against naga's layouter, so the two cannot drift apart.
//!
//! The f32 shader runs in micrometres and milliseconds (see [`Units`]), which
//! keeps every intermediate of the integrator, notably the derivatives of the
//! stage Taylor series (rate^n), inside the f32 range. The f64 shader runs in
//! SI units, exactly like the CPU.

use crate::cpu::integrate::{STATUS_OK, Settings};
use crate::model::AXES;

/// The unit system of one precision: how many length units make a metre and
/// how many time units make a second. Masses stay in kilograms, so forces
/// scale by [`Units::newton`]; voltages, phases and duties are unchanged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Units {
    /// Length units per metre.
    pub metre: f64,
    /// Time units per second.
    pub second: f64,
}

impl Units {
    /// SI units: the f64 shader computes exactly what the CPU computes.
    pub const SI: Units = Units {
        metre: 1.0,
        second: 1.0,
    };

    /// Micrometres and milliseconds: every quantity of the paper's
    /// mechanism is then of order one (the stage resonance is 20 rad/ms,
    /// the stroke 60 um, the force unit stays one newton).
    pub const MICRO_MILLI: Units = Units {
        metre: 1.0e6,
        second: 1.0e3,
    };

    /// Force units per newton (mass units are kilograms).
    pub fn newton(&self) -> f64 {
        self.metre / (self.second * self.second)
    }
}

/// A struct shared with the shader: its WGSL name and the byte offset of
/// every member, in declaration order.
pub trait HostLayout: bytemuck::Pod {
    /// The name of the WGSL struct it mirrors.
    const NAME: &'static str;
    /// (member name, byte offset) in declaration order.
    fn members() -> Vec<(&'static str, usize)>;
}

/// Declares a `#[repr(C)]` `Pod` struct and its [`HostLayout`].
macro_rules! host_struct {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$field_meta:meta])* pub $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
        pub struct $name {
            $( $(#[$field_meta])* pub $field: $ty ),*
        }

        impl $crate::gpu::layout::HostLayout for $name {
            const NAME: &'static str = stringify!($name);
            fn members() -> Vec<(&'static str, usize)> {
                vec![$( (stringify!($field), std::mem::offset_of!($name, $field)) ),*]
            }
        }
    };
}

/// Passes of the shader's loop-limiter probe (`loop_limiter_intact`): more
/// than the two a truncated loop can still make when the compiler has
/// peeled its first pass.
pub const PROBE_PASSES: u32 = 4;

/// The per-dispatch controls (precision independent).
pub mod control {
    host_struct! {
        /// The controls of one dispatch (a read-only storage buffer).
        pub struct Control {
            /// Iterations of `advance` in the dispatch.
            pub max_iterations: u32,
            /// 1 when the shader must first set every state to its initial
            /// value.
            pub initialize: u32,
            /// Always 1.0: a factor the shader compiler cannot fold, which
            /// keeps the compensated time sum exact.
            pub one: f32,
            /// Passes of the shader's loop-limiter probe, hidden from the
            /// shader compiler ([`super::PROBE_PASSES`] but in tests).
            pub probe: u32,
            /// Passes the probe must complete for the iteration to stand;
            /// equal to `probe`.
            pub probe_min: u32,
            /// Always 0: hidden from the shader compiler like `probe`.
            pub zero: u32,
        }
    }
}

/// Declares the storage structs of one precision in a module, with the
/// packing of instances and the unpacking of results.
macro_rules! precision_structs {
    ($module:ident, $real:ty, $units:expr) => {
        /// Storage structs of one precision.
        pub mod $module {
            use super::*;

            /// The scalar type of this precision.
            pub type Real = $real;

            /// The unit system this precision computes in.
            pub const UNITS: Units = $units;

            host_struct! {
                /// `pidm::model::Axis` in shader units.
                pub struct Axis {
                    pub stage_mass: Real,
                    pub stiffness: Real,
                    pub damping: Real,
                    pub gain: Real,
                    pub voltage: Real,
                    pub frequency: Real,
                    pub duty: Real,
                    pub phase: Real,
                }
            }

            host_struct! {
                /// `pidm::model::Mechanism` in shader units.
                pub struct Mechanism {
                    pub slider_mass: Real,
                    pub holding_friction: Real,
                    pub coulomb_friction: Real,
                    pub velocity_band: Real,
                }
            }

            host_struct! {
                /// `pidm::model::Instance` in shader units, with its scene
                /// period and each axis' drive cycles per period.
                pub struct Instance {
                    pub mechanism: Mechanism,
                    pub axes: [Axis; AXES],
                    pub period: Real,
                    pub cycles_per_period: [Real; AXES],
                    pub cycles: u32,
                    pub settle: u32,
                }
            }

            host_struct! {
                /// `pidm::cpu::integrate::Settings`.
                pub struct Settings {
                    pub tolerance: Real,
                    pub max_steps_per_period: u32,
                    pub _pad: u32,
                }
            }

            host_struct! {
                /// Everything the shader reads about one instance.
                pub struct Params {
                    pub inst: Instance,
                    pub settings: Settings,
                }
            }

            host_struct! {
                /// `pidm::cpu::integrate::State` in shader units, plus the
                /// low part of the two-part time.
                pub struct State {
                    pub x_p: [Real; AXES],
                    pub v_p: [Real; AXES],
                    pub x_s: [Real; AXES],
                    pub v_s: [Real; AXES],
                    pub held: [Real; AXES],
                    pub settle_x_s: [Real; AXES],
                    pub cycle_phase: [Real; AXES],
                    pub next_corner: [Real; AXES],
                    pub time: Real,
                    pub time_lo: Real,
                    pub h_slip: Real,
                    pub rising: [u32; AXES],
                    pub mode: u32,
                    pub period: u32,
                    pub status: u32,
                    pub steps: u32,
                    pub stalled: u32,
                    pub _pad: u32,
                }
            }

            /// Packs one instance and the batch settings in shader units.
            /// Derived quantities (the period, drive cycles per period) are
            /// computed in f64 and rounded once.
            pub fn pack(inst: &crate::model::Instance, settings: &super::Settings) -> Params {
                let u = UNITS;
                let newton = u.newton();
                let period = inst.period();
                let axis = |a: &crate::model::Axis| Axis {
                    stage_mass: a.stage_mass as Real,
                    stiffness: (a.stiffness * newton / u.metre) as Real,
                    damping: (a.damping * newton * u.second / u.metre) as Real,
                    gain: (a.gain * newton) as Real,
                    voltage: a.voltage as Real,
                    frequency: (a.frequency / u.second) as Real,
                    duty: a.duty as Real,
                    phase: a.phase as Real,
                };
                let m = &inst.mechanism;
                let mut cycles_per_period = [0.0; AXES];
                for (i, c) in cycles_per_period.iter_mut().enumerate() {
                    *c = (inst.axes[i].frequency * period) as Real;
                }
                Params {
                    inst: Instance {
                        mechanism: Mechanism {
                            slider_mass: m.slider_mass as Real,
                            holding_friction: (m.holding_friction() * newton) as Real,
                            coulomb_friction: (m.coulomb_friction * newton) as Real,
                            velocity_band: (m.velocity_band * u.metre / u.second) as Real,
                        },
                        axes: [axis(&inst.axes[0]), axis(&inst.axes[1])],
                        period: (period * u.second) as Real,
                        cycles_per_period,
                        cycles: inst.cycles,
                        settle: inst.settle,
                    },
                    settings: Settings {
                        tolerance: settings.tolerance as Real,
                        max_steps_per_period: settings.max_steps_per_period,
                        _pad: 0,
                    },
                }
            }

            /// The outcome of a finished state, back in SI units: the slider
            /// displacement over the measured periods, or zero where the
            /// instance did not finish normally (as the CPU reports it).
            pub fn unpack(inst: &crate::model::Instance, st: &State) -> super::super::GpuOutcome {
                let mut displacement = [0.0; AXES];
                if st.status == STATUS_OK && st.period >= inst.cycles {
                    for (i, d) in displacement.iter_mut().enumerate() {
                        *d = (st.x_s[i] as f64 - st.settle_x_s[i] as f64) / UNITS.metre;
                    }
                }
                super::super::GpuOutcome {
                    displacement,
                    status: st.status,
                    steps: st.steps,
                }
            }
        }
    };
}

precision_structs!(single, f32, Units::MICRO_MILLI);
precision_structs!(double, f64, Units::SI);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Instance;

    #[test]
    fn units_keep_the_force_unit_one_newton() {
        assert_eq!(Units::MICRO_MILLI.newton(), 1.0);
        assert_eq!(Units::SI.newton(), 1.0);
    }

    #[test]
    fn packing_scales_the_paper_mechanism_to_order_one() {
        let p = single::pack(&Instance::TABLE1, &Settings::default());
        let a = p.inst.axes[0];
        // w2 = k / m = 4e8 s^-2 = 400 ms^-2.
        assert!((a.stiffness / a.stage_mass - 400.0).abs() < 1e-3);
        assert!((a.frequency - 0.01).abs() < 1e-9);
        assert!((p.inst.period - 100.0).abs() < 1e-5);
        assert!((p.inst.mechanism.velocity_band - 1e-3).abs() < 1e-9);
        let d = double::pack(&Instance::TABLE1, &Settings::default());
        assert_eq!(d.inst.axes[0].stiffness, 1.0e6);
        assert_eq!(d.inst.period, Instance::TABLE1.period());
        assert_eq!(d.inst.cycles_per_period, [1.0, 1.0]);
    }
}
