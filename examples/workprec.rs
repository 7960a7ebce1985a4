use pidm::cpu::integrate::*;
use pidm::model::*;
fn run(inst: &Instance, tol: f64) -> ([f64; 2], u32, f64) {
    let settings = Settings { tolerance: tol, ..Settings::default() };
    let t0 = std::time::Instant::now();
    let st = run_instance(inst, &settings);
    let dt = t0.elapsed().as_secs_f64();
    let d = displacement(inst, &st);
    ([inst.measure(0, d[0]).1 * 1e6, inst.measure(1, d[1]).1 * 1e6], st.steps, dt)
}
fn main() {
    let mut cases = vec![];
    let mut a = Instance::TABLE1; a.axes[1].frequency = 20.0; cases.push(a);
    let mut b = a; b.axes = [Axis::TEXT, Axis::TEXT]; b.axes[1].frequency = 20.0; cases.push(b);
    let mut c = Instance::TABLE1; c.axes[1].phase = 0.25; c.axes[1].voltage = 80.0; cases.push(c);
    for inst in &cases {
        let (r, _, _) = run(inst, 1e-11);
        println!("reference {:.9} {:.9}", r[0], r[1]);
        for tol in [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8] {
            let (v, steps, dt) = run(inst, tol);
            println!("tol {tol:8.0e} err {:9.2e} {:9.2e} steps {steps:7} time {:.2} ms", v[0] - r[0], v[1] - r[1], dt * 1e3);
        }
    }
}
