// Where an llvmpipe lane holds its instance's parameters, its Rodas4
// stages and W (`pidm::gpu::lugre`, `Arithmetic::Native`): in private
// variables, which llvmpipe keeps as the CPU's code does. Device memory
// there ran the 61 x 61 LuGre map 2.9 times slower (issue 57).
// hold_memory.wgsl defines the same functions for hardware. The stages
// are six vectors of their own, picked by switches: nothing is indexed at
// run time.

var<private> model: Model;
var<private> k0: Vector;
var<private> k1: Vector;
var<private> k2: Vector;
var<private> k3: Vector;
var<private> k4: Vector;
var<private> k5: Vector;
var<private> w_held: W;

// Copies instance `index`'s parameters into `model`.
fn load_model(index: u32) {
    model = models[index];
}

// Rodas4's stage j of the step in hand, and keeping stage i.
fn stage(j: u32) -> Vector {
    switch j {
        case 0u: { return k0; }
        case 1u: { return k1; }
        case 2u: { return k2; }
        case 3u: { return k3; }
        case 4u: { return k4; }
        default: { return k5; }
    }
}

fn keep_stage(i: u32, k: Vector) {
    switch i {
        case 0u: { k0 = k; }
        case 1u: { k1 = k; }
        case 2u: { k2 = k; }
        case 3u: { k3 = k; }
        case 4u: { k4 = k; }
        default: { k5 = k; }
    }
}

// The step's W entry by entry (its LU factorisation and pivots, g, and
// the Jacobian's position and time columns on the reduced rows), and
// keeping it.
fn w_lu(i: u32, k: u32) -> Real {
    return w_held.lu.a[i][k];
}

fn w_pivot(k: u32) -> u32 {
    return w_held.lu.pivot[k];
}

fn w_g() -> Real {
    return w_held.g;
}

fn w_j_xp(r: u32, c: u32) -> Real {
    return w_held.j_xp[r][c];
}

fn w_j_t(r: u32) -> Real {
    return w_held.j_t[r];
}

fn keep_stage_matrix(w: W) {
    w_held = w;
}
