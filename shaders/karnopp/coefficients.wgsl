// Mirror of `laws::karnopp::integrate::coefficients`: the per-instance constants,
// computed once in f64 by the host and packed in the shader's units
// (src/gpu/layout.rs), so the shader divides by no parameter and takes no
// square root of one. Booleans are u32 (0 or 1): storage buffers hold no
// bool.

// One mode's oscillator per axis: m x'' + c x' + k x = g.
struct Oscillator {
    mass: V2,
    sigma: V2,
    w2: V2,
    rate: V2,
    inv_mass: V2,
    inv_w2: V2,
}

struct Coefficients {
    stiffness: V2,
    damping: V2,
    inv_stiffness: V2,
    stick: Oscillator,
    slip: Oscillator,
    amplitude: V2,
    frequency: V2,
    duty: V2,
    inv_duty: V2,
    inv_fall: V2,
    rise_slope: V2,
    fall_slope: V2,
    phase: V2,
    cycles_per_period: V2,
    // The corner clock (f32, CORNER_CLOCK; drive.wgsl): segment durations
    // and the first corner's time, each in two parts.
    rise_time: V2,
    rise_time_lo: V2,
    fall_time: V2,
    fall_time_lo: V2,
    first_corner: V2,
    first_corner_lo: V2,
    stage_share: V2,
    slider_share: V2,
    slip_scale: V2,
    slip_b: V2,
    // The load on the slider (docs/model.md section 7), each form subtracted,
    // +0 at L = 0: m_p L / (m_p + m_s), L / m_s, -L and -L / m_s.
    load_need: V2,
    load_accel: V2,
    neg_load: V2,
    neg_load_accel: V2,
    slip_b_max: Real,
    hold2: Real,
    // (max(f_s, f_c) - |L|)^2: the stick energy bound's limit.
    safe_hold2: Real,
    ms2: Real,
    two_ms2: Real,
    coulomb: Real,
    fc_over_ms: Real,
    band: Real,
    band2: Real,
    period: Real,
    period_lo: Real,
    event_step_stuck: Real,
    event_step_slip: Real,
    min_step: Real,
    tolerance: Real,
    collocation_tolerance: Real,
    cycles: u32,
    settle: u32,
    budget: u32,
    frictionless: u32,
    driven: vec2<u32>,
    // The phase and the cycles per period in fixed point (2^-32 and 2^-64
    // cycles): the f32 period starts (drive.wgsl, fixed_start_phase).
    phase_fixed: vec2<u32>,
    cycles_fixed: vec2<u32>,
    cycles_fixed_lo: vec2<u32>,
    segment_first: vec2<u32>,
    segment_count: vec2<u32>,
    // The steady measurement (`laws::karnopp::integrate::measure`).
    se_limit2: V2,
    repeat_x: Real,
    repeat_v: Real,
    steady: u32,
    common_period: u32,
    batch_length: u32,
    min_batch: u32,
    // The phase ladder (`laws::karnopp::integrate::phase`): the levels that may
    // stop the run and those judged without their quarters, a bit each,
    // and each window length's three-gap table.
    phase_levels: u32,
    phase_lattice: u32,
    replica: u32,
    replicas: u32,
    gaps: array<Gaps, LEVELS>,
}
