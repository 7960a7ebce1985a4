// On the laws' floor: every law's shader includes this file as it is.
// The types of the measurement's per-instance constants that every law's
// `Coefficients` holds by the names shaders/shared/measure.wgsl and
// phase.wgsl read (`pidm::laws::floor::measure::Gauge`; Karnopp's struct is
// shaders/karnopp/coefficients.wgsl, LuGre's in shaders/lugre/measure.wgsl).

// The three-gap table of one window length of the phase ladder
// (`pidm::laws::floor::phase::Gaps`).
struct Gaps {
    a: u32,
    b: u32,
    alpha: Real,
    beta: Real,
}
