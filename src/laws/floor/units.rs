//! The unit systems the integrator computes in: SI for f64, micrometres
//! and milliseconds for f32 (the f32 shader and its CPU mirror).

use crate::model::{Instance, Measure};

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

    /// The instance in these units (in f64).
    pub fn scale(&self, inst: &Instance) -> Instance {
        let newton = self.newton();
        let mut out = *inst;
        for a in &mut out.axes {
            a.stiffness *= newton / self.metre;
            a.damping *= newton * self.second / self.metre;
            a.gain *= newton;
            a.frequency /= self.second;
            // Volts per time unit: the slew limit's levels per cycle,
            // slew_rate / (|V| f), are the same in every unit system.
            a.slew_rate /= self.second;
        }
        if let Measure::Steady { step_tolerance } = &mut out.measure {
            *step_tolerance *= self.metre;
        }
        let m = &mut out.mechanism;
        m.static_friction *= newton;
        m.coulomb_friction *= newton;
        m.velocity_band *= self.metre / self.second;
        m.load = m.load.map(|l| l * newton);
        out
    }
}
