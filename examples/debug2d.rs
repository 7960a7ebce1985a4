use pidm::cpu::integrate::*;
use pidm::model::*;
fn main() {
    let mut inst = Instance::TABLE1;
    inst.axes[1].frequency = 20.0;
    let settings = Settings::default();
    let mut st = initial_state(&inst);
    let mut last = Vec::new();
    while !is_finished(&inst, &st) {
        advance(&inst, &settings, &mut st, 1);
        last.push(st);
        if last.len() > 30 { last.remove(0); }
    }
    for s in &last { println!("p{} t={:.12e} mode={} h={:.3e} vrel=({:.3e},{:.3e}) held={:?} status={}", s.period, s.time, s.mode, s.h_slip, s.v_p[0]-s.v_s[0], s.v_p[1]-s.v_s[1], s.held, s.status); }
}
