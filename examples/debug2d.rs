use pidm::cpu::integrate::*;
use pidm::model::*;
fn main() {
    let tol: f64 = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(1e-6);
    let mut inst = Instance::TABLE1;
    inst.axes[1].frequency = 20.0;
    let settings = Settings { tolerance: tol, ..Settings::default() };
    let mut st = initial_state(&inst);
    let mut by_mode = [0u32; 3];
    let mut hist = std::collections::BTreeMap::new();
    let mut near = 0; let mut rej = 0;
    while !is_finished(&inst, &st) {
        let before = st;
        advance(&inst, &settings, &mut st, 1);
        by_mode[before.mode as usize] += 1;
        rej += st.steps - before.steps - 1;
        let dt = if st.period == before.period { st.time - before.time } else { 0.0 };
        if before.mode == 1 {
            let b = if dt > 0.0 { dt.log10().floor() as i32 } else { -99 };
            *hist.entry(b).or_insert(0) += 1;
            let vr = ((before.v_p[0]-before.v_s[0]).powi(2) + (before.v_p[1]-before.v_s[1]).powi(2)).sqrt();
            if vr < 1e-4 { near += 1; }
        }
    }
    println!("steps {} by mode stick/slip/band {:?} rejections {} slip steps with |vrel|<1e-4: {}", st.steps, by_mode, rej, near);
    println!("slip step-size histogram (log10 s): {:?}", hist);
}
