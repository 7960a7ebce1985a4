use pidm::cpu::integrate::{
    Coefficients, NoObserver, Settings, initial_state, is_finished, iterate,
};
use pidm::model::{Instance, Measure};

fn positions(inst: &Instance, periods: u32) -> Vec<[f64; 2]> {
    let mut i = *inst;
    i.measure = Measure::Window;
    i.cycles = periods;
    i.settle = 0;
    let c = Coefficients::of(&i, &Settings::default());
    let mut st = initial_state(&c);
    let mut out = vec![[0.0, 0.0]];
    let mut p = 0;
    loop {
        if is_finished(&c, &st) {
            break;
        }
        if st.time >= c.period && st.period == p {
            out.push(st.x_s.to_array());
            p += 1;
        }
        iterate(&c, &mut st, &mut NoObserver);
    }
    out
}

// trapezoid over (phase, d) pairs on the circle
fn trapezoid(mut pts: Vec<(f64, [f64; 2])>) -> [f64; 2] {
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = pts.len();
    let mut s = [0.0; 2];
    for k in 0..n {
        let prev = if k == 0 {
            pts[n - 1].0 - 1.0
        } else {
            pts[k - 1].0
        };
        let next = if k == n - 1 {
            pts[0].0 + 1.0
        } else {
            pts[k + 1].0
        };
        let w = 0.5 * (next - prev);
        for a in 0..2 {
            s[a] += w * pts[k].1[a];
        }
    }
    s
}

fn main() {
    if std::env::var("Q").is_ok() {
        quality();
        return;
    }
    if std::env::var("CMP").is_ok() {
        compare_g();
        return;
    }
    if std::env::var("UNION").is_ok() {
        check_union();
        return;
    }
    if std::env::var("LONG").is_ok() {
        long_shifted();
        return;
    }
    let mut inst = Instance::TABLE1;
    inst.axes[1].frequency = std::env::var("FY")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10.0 * 2f64.sqrt());
    inst.axes[1].voltage = 100.0;
    let rho = (inst.axes[1].frequency / inst.axes[0].frequency).fract();
    let s: usize = std::env::var("S")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2);
    let reference_n = 20000u32;
    let x = positions(&inst, reference_n + s as u32);
    let ph0 = inst.axes[1].phase;
    let refpts: Vec<(f64, [f64; 2])> = (s..(reference_n as usize + s))
        .map(|k| {
            (
                ((ph0 + k as f64 * rho).fract()),
                [x[k + 1][0] - x[k][0], x[k + 1][1] - x[k][1]],
            )
        })
        .collect();
    let reference = trapezoid(refpts);
    println!(
        "reference (20000 periods) step x {:.6} um y {:.6} um",
        reference[0] * 1e6,
        reference[1] * 1e6
    );
    let big_r: usize = std::env::var("R")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(8);
    for ell in [85usize, 170, 340, 680] {
        // single run of R*ell periods
        let single: Vec<(f64, [f64; 2])> = (s..s + big_r * ell)
            .map(|k| {
                (
                    ((ph0 + k as f64 * rho).fract()),
                    [x[k + 1][0] - x[k][0], x[k + 1][1] - x[k][1]],
                )
            })
            .collect();
        let single = trapezoid(single);
        let mut pts = Vec::new();
        let mut own = Vec::new();
        for r in 0..big_r {
            let mut ri = inst;
            let m: f64 = std::env::var("M")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(0.0);
            ri.axes[1].phase = (ph0 + r as f64 * (rho + m) / big_r as f64).fract();
            let xr = positions(&ri, (s + ell) as u32);
            let mine: Vec<(f64, [f64; 2])> = (s..s + ell)
                .map(|k| {
                    (
                        ((ri.axes[1].phase + k as f64 * rho).fract()),
                        [xr[k + 1][0] - xr[k][0], xr[k + 1][1] - xr[k][1]],
                    )
                })
                .collect();
            own.push(trapezoid(mine.clone()));
            pts.extend(mine);
        }
        let merged = trapezoid(pts);
        let own_s: Vec<String> = own.iter().map(|o| format!("{:.4}", o[1] * 1e6)).collect();
        println!(
            "ell {ell}: single {}: err x {:.5} y {:.5} | replicas: err x {:.5} y {:.5} | own y: {}",
            big_r * ell,
            (single[0] - reference[0]) * 1e6,
            (single[1] - reference[1]) * 1e6,
            (merged[0] - reference[0]) * 1e6,
            (merged[1] - reference[1]) * 1e6,
            own_s.join(" ")
        );
    }
}

#[allow(dead_code)]
pub fn long_shifted() {
    let mut inst = Instance::TABLE1;
    inst.axes[1].frequency = 10.0 * 2f64.sqrt();
    inst.axes[1].voltage = 100.0;
    let rho = (inst.axes[1].frequency / inst.axes[0].frequency).fract();
    for shift in [0.0, 0.05, 0.3, 0.7] {
        let mut i = inst;
        i.axes[1].phase = shift;
        let n = 20000usize;
        let x = positions(&i, n as u32 + 2);
        let pts: Vec<(f64, [f64; 2])> = (2..n + 2)
            .map(|k| {
                (
                    ((shift + k as f64 * rho).fract()),
                    [x[k + 1][0] - x[k][0], x[k + 1][1] - x[k][1]],
                )
            })
            .collect();
        let t = trapezoid(pts);
        let mean = [
            (x[n + 2][0] - x[2][0]) / n as f64,
            (x[n + 2][1] - x[2][1]) / n as f64,
        ];
        println!(
            "shift {shift}: trapezoid x {:.6} y {:.6}; running mean x {:.6} y {:.6}",
            t[0] * 1e6,
            t[1] * 1e6,
            mean[0] * 1e6,
            mean[1] * 1e6
        );
    }
}

#[allow(dead_code)]
pub fn check_union() {
    let mut inst = Instance::TABLE1;
    inst.axes[1].frequency = 10.0 * 2f64.sqrt();
    inst.axes[1].voltage = 100.0;
    let rho = (inst.axes[1].frequency / inst.axes[0].frequency).fract();
    let big_r = 8usize;
    let ell = 2000usize;
    let s = 10usize;
    let mut all = Vec::new();
    for r in 0..big_r {
        let mut ri = inst;
        ri.axes[1].phase = (r as f64 * rho / big_r as f64).fract();
        let xr = positions(&ri, (s + ell) as u32);
        let mine: Vec<(f64, [f64; 2])> = (s..s + ell)
            .map(|k| {
                (
                    ((ri.axes[1].phase + k as f64 * rho).fract()),
                    [xr[k + 1][0] - xr[k][0], xr[k + 1][1] - xr[k][1]],
                )
            })
            .collect();
        let own = trapezoid(mine.clone());
        println!(
            "replica {r}: own x {:.6} y {:.6}",
            own[0] * 1e6,
            own[1] * 1e6
        );
        all.extend(mine);
    }
    let u = trapezoid(all.clone());
    println!("union x {:.6} y {:.6}", u[0] * 1e6, u[1] * 1e6);
    // min gap in union
    let mut ph: Vec<f64> = all.iter().map(|p| p.0).collect();
    ph.sort_by(|a, b| a.total_cmp(b));
    let mut ming = 1.0f64;
    let mut maxg = 0.0f64;
    for w in ph.windows(2) {
        ming = ming.min(w[1] - w[0]);
        maxg = maxg.max(w[1] - w[0]);
    }
    println!("union gaps min {ming:e} max {maxg:e} n {}", ph.len());
}

#[allow(dead_code)]
pub fn compare_g() {
    let mut inst = Instance::TABLE1;
    inst.axes[1].frequency = std::env::var("FY")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10.0 * 2f64.sqrt());
    inst.axes[1].voltage = 100.0;
    let rho = (inst.axes[1].frequency / inst.axes[0].frequency).fract();
    let ell = 4000usize;
    let s = 10usize;
    let mut sets = Vec::new();
    for shift in [0.0, 0.2, 0.45] {
        let mut ri = inst;
        ri.axes[1].phase = shift;
        let xr = positions(&ri, (s + ell) as u32);
        let mut mine: Vec<(f64, [f64; 2])> = (s..s + ell)
            .map(|k| {
                (
                    ((shift + k as f64 * rho).fract()),
                    [xr[k + 1][0] - xr[k][0], xr[k + 1][1] - xr[k][1]],
                )
            })
            .collect();
        mine.sort_by(|a, b| a.0.total_cmp(&b.0));
        sets.push(mine);
    }
    // linear interpolation of set 0 at phases of set i
    let interp = |set: &Vec<(f64, [f64; 2])>, p: f64| -> [f64; 2] {
        let idx = set.partition_point(|q| q.0 < p);
        let (a, b) = if idx == 0 {
            (set[set.len() - 1], set[0])
        } else if idx == set.len() {
            (set[idx - 1], set[0])
        } else {
            (set[idx - 1], set[idx])
        };
        let (pa, pb) = (a.0, if b.0 < a.0 { b.0 + 1.0 } else { b.0 });
        let pp = if p < pa { p + 1.0 } else { p };
        let t = if pb > pa { (pp - pa) / (pb - pa) } else { 0.0 };
        [
            a.1[0] + t * (b.1[0] - a.1[0]),
            a.1[1] + t * (b.1[1] - a.1[1]),
        ]
    };
    for i in 1..3 {
        let mut sum = [0.0; 2];
        let mut big = 0;
        for q in &sets[i] {
            let g0 = interp(&sets[0], q.0);
            let d = [q.1[0] - g0[0], q.1[1] - g0[1]];
            sum[0] += d[0];
            sum[1] += d[1];
            if d[0].abs() > 1e-8 {
                big += 1;
            }
        }
        println!(
            "set {i} minus set 0 (interpolated): mean diff x {:.6} um y {:.6} um; {} of {} points differ by >0.01 um in x",
            sum[0] / ell as f64 * 1e6,
            sum[1] / ell as f64 * 1e6,
            big,
            ell
        );
    }
    // print a few points near phase 0.3
    for set in &sets {
        let idx = set.partition_point(|q| q.0 < 0.3);
        println!(
            "{:?}",
            &set[idx..idx + 3]
                .iter()
                .map(|q| (q.0, q.1[0] * 1e6))
                .collect::<Vec<_>>()
        );
    }
}

#[allow(dead_code)]
pub fn quality() {
    use pidm::cpu::integrate::phase::{gaps, ladder_length, largest_gap};
    for (name, rho) in [
        ("golden", 0.6180339887498949f64),
        ("sqrt2", 2f64.sqrt() - 1.0),
        ("sqrt3", 3f64.sqrt() - 1.0),
    ] {
        for big_r in [2u32, 4, 8] {
            let mut line = format!("{name} R={big_r}:");
            for m in 0..big_r {
                let beta = (rho + m as f64) / big_r as f64;
                let worst = (7..14)
                    .map(|j| {
                        let l = ladder_length(j);
                        largest_gap(&gaps(beta, l), l) * l as f64
                    })
                    .fold(0.0f64, f64::max);
                line += &format!(" m{m} {worst:.2}");
            }
            let single = (7..14)
                .map(|j| {
                    let l = ladder_length(j);
                    largest_gap(&gaps(rho, l), l) * l as f64
                })
                .fold(0.0f64, f64::max);
            println!("{line} | single {single:.2}");
        }
    }
}
