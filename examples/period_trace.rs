//! The slider's position at the start of every scene period of one
//! two-frequency instance (Table 1 at 100 V on both axes, x at FX Hz, y at
//! FY Hz, run from rest for N periods with a settle of 2), one line per
//! period: `period x_s [m] y_s [m]`. `results/replicas/trace.py` reads it
//! to compare window estimates, plain means and phase-resolved trapezoids
//! (docs/steady.md, "When a window may stop a run" and "Replicas").
//!
//! ```text
//! cargo run --release --example period_trace -- 14.666 19.142 20002 > trace.txt
//! ```

use pidm::laws::Settings;
use pidm::laws::karnopp::integrate::{
    Coefficients, advance, initial_measure, initial_state, is_finished,
};
use pidm::model::{Instance, Measure};

fn main() {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|s| s.parse().expect("FX FY N: numbers"))
        .collect();
    let [fx, fy, n] = args[..] else {
        panic!("usage: period_trace FX FY N");
    };
    let mut inst = Instance::TABLE1;
    inst.axes[0].frequency = fx;
    inst.axes[1].frequency = fy;
    inst.axes[1].voltage = 100.0;
    inst.cycles = n as u32;
    inst.settle = 2;
    inst.measure = Measure::Window;
    let c = Coefficients::of(&inst, &Settings::default());
    let mut st = initial_state(&c);
    let mut m = initial_measure(&c);
    let mut last = u32::MAX;
    while !is_finished(&c, &st) {
        if st.period != last {
            last = st.period;
            println!("{} {:.12e} {:.12e}", st.period, st.x_s.x, st.x_s.y);
        }
        advance(&c, &mut st, &mut m, 1);
    }
}
