//! Replicas against one run and a long reference (docs/steady.md,
//! "Replicas"): for each instance of an n x n two-frequency map (Table 1
//! at 100 V on both axes, x over 7.13-25.97 Hz, y over 9.71-33.29 Hz, the
//! grid of `results/pipeline/twofreq6.toml`), measured steady to 0.01 um
//! within 20,000 periods, it prints the run of its own (periods, kind of
//! motion, each axis' distance to the reference and standard error [um]),
//! the same instance as R replicas on the CPU (the longest replica's
//! periods, their share of the run's, the kind of motion, the distances
//! and errors, the largest disagreement of its merges), and a "!" where a
//! value lies beyond 3 standard errors + 0.002 um of the reference, a
//! fixed window of 20,000 periods.
//!
//! ```text
//! cargo run --release --example replicas_validate -- 8 6
//! ```
//! (R = 8 replicas, n = 6; about 5 minutes on 2 cores.)

use pidm::laws::{Replicas, Settings};
use pidm::measurement::{Measured, reduce};
use pidm::model::{Instance, Measure};
use pidm::replicas::{self, cpu::run_group};
use rayon::prelude::*;

/// One whole run of `inst` with its law's integrator.
fn run_instance(inst: &Instance, settings: &Settings) -> pidm::laws::Run {
    pidm::laws::run_until(inst, settings, || false).expect("never asked to stop")
}

/// Table 1 at 100 V on both axes, x at `fx` and y at `fy` Hz, steady to
/// 0.01 um within 20,000 periods.
fn instance(fx: f64, fy: f64) -> Instance {
    let mut inst = Instance::TABLE1;
    inst.axes[0].frequency = fx;
    inst.axes[1].frequency = fy;
    inst.axes[1].voltage = 100.0;
    inst.cycles = 20_000;
    inst.measure = Measure::Steady {
        step_tolerance: 1e-8,
    };
    inst
}

/// Each axis' distance to `reference` and standard error [um], "!" beyond
/// 3 standard errors + 0.002 um.
fn against(inst: &Instance, m: &Measured, reference: [f64; 2]) -> String {
    (0..2)
        .map(|i| {
            let step = inst.measure_over(i, m.travel[i], m.span).1 * 1e6;
            let (d, se) = (step - reference[i], m.se[i] * 1e6);
            let mark = if d.abs() <= 3.0 * se + 0.002 { "" } else { "!" };
            format!("{d:+.4}/{se:.4}{mark}")
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn row(fx: f64, fy: f64, count: u32) -> String {
    let inst = instance(fx, fy);
    let settings = Settings {
        replicas: Replicas::Count(count),
        ..Settings::default()
    };
    let alone = reduce(&inst, &run_instance(&inst, &settings));
    let mut long = inst;
    long.measure = Measure::Window;
    long.cycles = 20_002;
    long.settle = 2;
    let lr = reduce(&long, &run_instance(&long, &settings));
    let reference = [0, 1].map(|i| long.measure_over(i, lr.travel[i], lr.span).1 * 1e6);
    let own = format!(
        "{fx:6.2} {fy:6.2} alone {:5} {:13} {}",
        alone.periods,
        alone.motion.name(),
        against(&inst, &alone, reference)
    );
    match replicas::split_of(&inst, &settings, count) {
        Some(split) => {
            let g = run_group(&inst, &settings, split, &|| false).expect("never stopped");
            format!(
                "{own} | x{} {:5} ({:.3}) {:13} {} disagreement {:.2}",
                g.replicas,
                g.measured.periods,
                g.measured.periods as f64 / alone.periods as f64,
                g.measured.motion.name(),
                against(&inst, &g.measured, reference),
                g.disagreement
            )
        }
        None => format!("{own} | not split"),
    }
}

fn main() {
    let arg = |k: usize, default: u32| {
        std::env::args()
            .nth(k)
            .and_then(|a| a.parse().ok())
            .unwrap_or(default)
    };
    let (count, n) = (arg(1, 8), arg(2, 6).max(2) as usize);
    let grid: Vec<(f64, f64)> = (0..n * n)
        .map(|k| {
            let (i, j) = ((k / n) as f64, (k % n) as f64);
            let step = (n - 1) as f64;
            (
                7.13 + (25.97 - 7.13) * i / step,
                9.71 + (33.29 - 9.71) * j / step,
            )
        })
        .collect();
    let rows: Vec<String> = grid
        .par_iter()
        .with_max_len(1)
        .map(|&(fx, fy)| row(fx, fy, count))
        .collect();
    for r in rows {
        println!("{r}");
    }
}
