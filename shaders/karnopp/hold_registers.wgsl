// Where an llvmpipe lane, and an f32 lane, holds its instance's state and
// a step's flow, samples and propagators (`pidm::gpu::karnopp::shader`):
// in function and private variables, which the compiler keeps in
// registers, as the CPU's code does; the state goes back to `states`
// between instances and dispatches. hold_memory.wgsl holds them in device
// memory for an f64 hardware lane; the code that reads them is the same.

var<private> flow: Flow;
var<private> samples: Samples;
var<private> props: SamplePropagators;

// Starts (`initialize`) or loads instance `index` into the lane's `st`.
fn take_state(index: u32, initialize: bool, st: ptr<function, State>) {
    if !initialize {
        *st = states[index];
        return;
    }
    start_measure(index);
    *st = initial_state();
}

// Loads instance `index` into the lane's `st`.
fn load_state(index: u32, st: ptr<function, State>) {
    *st = states[index];
}

// Keeps the lane's `st` as instance `index`'s.
fn keep_state(index: u32, st: ptr<function, State>) {
    states[index] = *st;
}
