use pidm::cpu::integrate::*;
use pidm::model::*;
fn case(vx: f64, vy: f64, fx: f64, fy: f64, text: bool) -> Instance {
    let mut inst = Instance::TABLE1;
    if text { inst.axes = [Axis::TEXT, Axis::TEXT]; }
    inst.axes[0].voltage = vx; inst.axes[1].voltage = vy;
    inst.axes[0].frequency = fx; inst.axes[1].frequency = fy;
    inst
}
fn main() {
    let tol: f64 = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(1e-7);
    let settings = Settings { tolerance: tol, ..Settings::default() };
    let cases = [
        ("1dof 100V 10Hz", case(100.0, 0.0, 10.0, 10.0, false), [0.6159, 0.0]),
        ("1dof 50V 10Hz", case(50.0, 0.0, 10.0, 10.0, false), [0.3802, 0.0]),
        ("1dof 100V 20Hz", case(100.0, 0.0, 20.0, 20.0, false), [-1.1767, 0.0]),
        ("2dof 70.71", case(100.0/2f64.sqrt(), 100.0/2f64.sqrt(), 10.0, 10.0, false), [0.4355, 0.4355]),
        ("2dof 100/100", case(100.0, 100.0, 10.0, 10.0, false), [-0.9424, -0.9424]),
        ("2dof 100/50", case(100.0, 50.0, 10.0, 10.0, false), [0.0545, 0.0273]),
        ("2dof 10/20Hz", case(100.0, 100.0, 10.0, 20.0, false), [1.6151, -0.4950]),
        ("text 1dof 20Hz", case(100.0, 0.0, 20.0, 20.0, true), [-2.8519, 0.0]),
        ("text 2dof 100/100", case(100.0, 100.0, 10.0, 10.0, true), [-0.6042, -0.6042]),
        ("text 2dof 10/20", case(100.0, 100.0, 10.0, 20.0, true), [1.0692, -1.1754]),
        ("text 1dof 10Hz", case(100.0, 0.0, 10.0, 10.0, true), [0.0, 0.0]),
    ];
    for (name, inst, want) in cases {
        let t0 = std::time::Instant::now();
        let st = run_instance(&inst, &settings);
        let dt = t0.elapsed();
        let d = displacement(&inst, &st);
        let sx = inst.measure(0, d[0]).1 * 1e6;
        let sy = inst.measure(1, d[1]).1 * 1e6;
        println!("{name:20} {sx:10.6} {sy:10.6}  want {:8.4} {:8.4}  err {:8.5} {:8.5} status {} steps {} {:?}",
            want[0], want[1], sx - want[0], sy - want[1], st.status, st.steps, dt);
    }
}
