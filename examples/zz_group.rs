use pidm::cpu::integrate::{Settings, run_instance};
use pidm::measurement::reduce;
use pidm::model::{Instance, Measure};
use pidm::replicas::cpu::run_group;
use std::time::Instant;

fn main() {
    if std::env::var("SPREAD").is_ok() {
        spreads();
        return;
    }
    if std::env::var("LEVELS").is_ok() {
        levels();
        return;
    }
    let settings = Settings::default();
    let mut cases = Vec::new();
    for (fx, fy, vy) in [
        (10.0, 10.0 * 2f64.sqrt(), 100.0),
        (10.0, 10.0 * 3f64.sqrt(), 100.0),
        (10.0, 10.0 * 1.618033988749895, 100.0),
        (10.0, 23.7, 80.0),
        (13.1, 17.9, 100.0),
    ] {
        let mut inst = Instance::TABLE1;
        inst.axes[0].frequency = fx;
        inst.axes[1].frequency = fy;
        inst.axes[1].voltage = vy;
        inst.cycles = 20000;
        inst.measure = Measure::Steady {
            step_tolerance: 1e-8,
        };
        cases.push(inst);
    }
    let r: u32 = std::env::var("R")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(8);
    for inst in cases {
        let t = Instant::now();
        let plain = reduce(&inst, &run_instance(&inst, &settings));
        let tp = t.elapsed().as_secs_f64();
        let mut long = inst;
        long.measure = Measure::Steady {
            step_tolerance: 1e-14,
        };
        let reference = reduce(&long, &run_instance(&long, &settings));
        let t = Instant::now();
        let split = pidm::replicas::split(&inst, pidm::replicas::Replicas::Count(r), r).unwrap();
        let g = run_group(&inst, &settings, split, &|| false).unwrap();
        let tg = t.elapsed().as_secs_f64();
        let step = |m: &pidm::measurement::Measured, i: usize| {
            inst.measure_over(i, m.travel[i], m.span).1 * 1e6
        };
        println!(
            "f {:.3}/{:.3}: plain x {:.5} y {:.5} se {:.5}/{:.5} periods {} {:?} {:.2}s | R={} x {:.5} y {:.5} se {:.5}/{:.5} periods {} {:?} {:.2}s | ref x {:.5} y {:.5} (span {})",
            inst.axes[0].frequency,
            inst.axes[1].frequency,
            step(&plain, 0),
            step(&plain, 1),
            plain.se[0] * 1e6,
            plain.se[1] * 1e6,
            plain.periods,
            plain.motion,
            tp,
            g.replicas,
            step(&g.measured, 0),
            step(&g.measured, 1),
            g.measured.se[0] * 1e6,
            g.measured.se[1] * 1e6,
            g.measured.periods,
            g.measured.motion,
            tg,
            step(&reference, 0),
            step(&reference, 1),
            reference.span
        );
    }
}
#[allow(dead_code)]
fn levels() {
    use pidm::cpu::integrate::{Coefficients, Replica};
    let mut inst = Instance::TABLE1;
    inst.axes[1].frequency = 10.0 * 3f64.sqrt();
    inst.axes[1].voltage = 100.0;
    inst.cycles = 20000;
    inst.measure = Measure::Steady {
        step_tolerance: 1e-8,
    };
    let s = Settings::default();
    for count in [1, 8] {
        let c = Coefficients::of_replica(
            &inst,
            &s,
            Replica {
                index: 0,
                count,
                turns: 0,
            },
        );
        println!(
            "count {count}: levels {:b} settle {}",
            c.phase_levels, c.settle
        );
    }
}
#[allow(dead_code)]
fn spreads() {
    use pidm::cpu::integrate::phase::spread;
    for (name, rho) in [
        ("golden", 0.6180339887498949f64),
        ("sqrt2", 2f64.sqrt() - 1.0),
        ("sqrt3", 3f64.sqrt() - 1.0),
    ] {
        for r in [2u32, 4, 8] {
            let v: Vec<String> = (0..r)
                .map(|m| format!("{:.2}", spread((rho + m as f64) / r as f64)))
                .collect();
            println!("{name} R={r}: {} | own {:.2}", v.join(" "), spread(rho));
        }
    }
}
