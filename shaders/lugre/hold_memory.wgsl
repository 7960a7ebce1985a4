// Where a hardware lane holds its instance's parameters, its Rodas4 stages
// and W (`pidm::gpu::lugre`, `Arithmetic::Fused`): in device memory, the
// instance's own (`held`'s), each written once and read where it is used,
// so that the lane's registers hold none of them (the parameters are
// `models[held]`, which the host writes for `model`). With all three in
// registers RADV's compiler asked 479 VGPRs and spilled 271; so, 237 and
// none (issue 57). A storage array may be indexed at run time; no private
// array is. hold_registers.wgsl defines the same functions for llvmpipe.

@group(0) @binding(14) var<storage, read_write> stages: array<Vector>;
@group(0) @binding(15) var<storage, read_write> stage_matrices: array<W>;

// Makes instance `index` the one the lane reads: `held` already says it,
// and the host writes `models[held]` for `model` in this variant's source
// (`read_where_used`).
fn load_model(index: u32) {}

// Rodas4's stage j of the step in hand, and keeping stage i.
fn stage(j: u32) -> Vector {
    return stages[6u * held + j];
}

fn keep_stage(i: u32, k: Vector) {
    stages[6u * held + i] = k;
}

// The step's W entry by entry (its LU factorisation and pivots, g, and
// the Jacobian's position and time columns on the reduced rows), and
// keeping it.
fn w_lu(i: u32, k: u32) -> Real {
    return stage_matrices[held].lu.a[i][k];
}

fn w_pivot(k: u32) -> u32 {
    return stage_matrices[held].lu.pivot[k];
}

fn w_g() -> Real {
    return stage_matrices[held].g;
}

fn w_j_xp(r: u32, c: u32) -> Real {
    return stage_matrices[held].j_xp[r][c];
}

fn w_j_t(r: u32) -> Real {
    return stage_matrices[held].j_t[r];
}

fn keep_stage_matrix(w: W) {
    stage_matrices[held] = w;
}
