// Where an f64 hardware lane holds its instance's state and a step's flow,
// samples and propagators (`pidm::gpu::karnopp::shader`): in device
// memory, each value read where it is used, so that the lane's registers
// hold none of them. The state is the instance's own entry of `states`
// (`held`'s), worked on in place; the flow, samples and propagators are
// the lane's own entries (`lane_slot`'s) of bindings 9 to 11. The host
// writes `states[held].` for `(*st).` and `st.`, `flows[lane_slot].` for
// `flow.`, `step_samples[lane_slot].` for `samples.` and
// `step_props[lane_slot].` for `props.` in this variant's source
// (`gpu::prelude::read_where_used`). In registers RADV's compiler asked
// 475 VGPRs for the f64 lane and spilled 461; so, 243 and none (issue 57).
// hold_registers.wgsl holds them in registers elsewhere.

// The buffers themselves (bindings 9 to 11) are declared by the host from
// `gpu::karnopp::shader::HELD_IN_MEMORY`, the one home of their bindings.

// Starts (`initialize`) instance `index` in its entry of `states`, which
// the lane works on in place (`held` is `index`): `st` is not read. The
// initial state is built in registers, where `DEFLECTION` (false in f64)
// would read its drive from `states[held]`.
fn take_state(index: u32, initialize: bool, st: ptr<function, State>) {
    if initialize {
        start_measure(index);
        states[index] = initial_state();
    }
}

// Instance `index`'s state is its entry of `states`: nothing to load.
fn load_state(index: u32, st: ptr<function, State>) {}

// The lane worked on instance `index`'s entry of `states`: nothing to keep.
fn keep_state(index: u32, st: ptr<function, State>) {}
