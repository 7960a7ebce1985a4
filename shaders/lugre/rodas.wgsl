// Mirror of `laws::lugre::rodas`: Rodas4 (Hairer and Wanner), linearly
// implicit, L-stable and stiffly accurate, of order 4 with an embedded
// order-3 solution that controls the steps, on the exact Jacobian
// (`jacobian`); the step attempts of one segment (between drive corners
// and period ends, inside which the drive is linear in time) and the LU
// factorisation the stages solve with. The coefficients GAMMA, RODAS_A and
// RODAS_C, and the reduced system's R and REDUCED, come from the Rust
// consts through the prelude.

// One Rodas4 step: the new state and the local error estimate (k6).
struct Step {
    next: Vector,
    error: Vector,
}

alias Reduced = array<Real, R>;
alias ReducedMatrix = array<array<Real, R>, R>;

// An LU factorisation with partial pivoting of the R x R reduced matrix.
struct Lu {
    a: ReducedMatrix,
    pivot: array<u32, R>,
}

// The stages' matrix W = I - gamma h J, reduced to the velocities and
// deflections (REDUCED) and LU-factored (`w_matrix`).
struct W {
    lu: Lu,
    g: Real,
    // J's columns of the stage positions and of the time, on the reduced
    // rows.
    j_xp: array<array<Real, 2>, R>,
    j_t: Reduced,
}

// One Rodas4 step of size `h` from `y`. The stages solve (I / (gamma h) -
// J) k = rhs, that is gamma h (I - gamma h J)^-1 rhs. The CPU's loops stay
// loops (one rhs, one solve and one sum of each kind in the code), the
// stages and W are kept where the lane holds them (`stage`, `keep_stage`,
// `w_lu` and its kin: hold_memory.wgsl or hold_registers.wgsl), and the sums
// over a vector's components are written out (`axpy`, `add_quotients`,
// from the host).
fn rodas4(drive: Drive, y: Vector, h: Real) -> Step {
    keep_stage_matrix(w_matrix(drive, y, GAMMA * h));
    var start = y;
    for (var i = 0u; i < 6u; i++) {
        if i >= 1u && i < 5u {
            let a = stage_a(i);
            start = y;
            for (var j = 0u; j < i; j++) {
                start = axpy(start, pick(a, j), stage(j));
            }
        } else if i == 5u {
            start = add(start, stage(4u));
        }
        var f = rhs(start, drive);
        if i > 0u {
            let c = stage_c(i);
            for (var j = 0u; j < i; j++) {
                f = add_quotients(f, pick(c, j), stage(j), h);
            }
        }
        keep_stage(i, scaled(GAMMA * h, solve(f)));
    }
    let k5 = stage(5u);
    return Step(add(start, k5), k5);
}

// Entry j of a coefficient row, by literal indices.
fn pick(row: array<Real, 5>, j: u32) -> Real {
    switch j {
        case 0u: { return row[0]; }
        case 1u: { return row[1]; }
        case 2u: { return row[2]; }
        case 3u: { return row[3]; }
        default: { return row[4]; }
    }
}

// Stage i's row of RODAS_A (1 <= i < 5; padded with zeros to RODAS_C's
// width by the prelude) and of RODAS_C (1 <= i < 6), by literal indices.
fn stage_a(i: u32) -> array<Real, 5> {
    switch i {
        case 1u: { return RODAS_A[0]; }
        case 2u: { return RODAS_A[1]; }
        case 3u: { return RODAS_A[2]; }
        default: { return RODAS_A[3]; }
    }
}

fn stage_c(i: u32) -> array<Real, 5> {
    switch i {
        case 1u: { return RODAS_C[0]; }
        case 2u: { return RODAS_C[1]; }
        case 3u: { return RODAS_C[2]; }
        case 4u: { return RODAS_C[3]; }
        default: { return RODAS_C[4]; }
    }
}

// x^(1/4) for x >= 0 (Rust's powf(0.25)): sqrt(sqrt(x)) with one Newton
// correction on the exact residual, so that it is correctly rounded but
// in rare cases (glibc's pow but in about one argument in a thousand).
// Shader only; mirrored by `pidm::gpu::lugre::fourth_root`.
fn fourth_root(x: Real) -> Real {
    let s = square_root(square_root(x));
    let p = two_prod(s, s);
    let q = two_prod(p.hi, p.hi);
    let rho = (keep(q.hi - x) + q.lo) + Real(2.0) * p.hi * p.lo;
    let refined = s - quotient(rho, Real(4.0) * s * s * s);
    return select(s, refined, is_finite(refined));
}

// One pass of the CPU's `segment` loop: one step attempt from `y` towards
// time `end` (an exact boundary), unless `y` is there already. `h` carries
// the step size from segment to segment, `budget` the steps (accepted and
// rejected) the run has left, `steps` the segment's attempts, `rejected`
// whether the last attempt was rejected (false at a segment's start).
// Returns SEGMENT_DONE once `y` is at `end`, SEGMENT_GOING after an
// attempt, or the status that ends the run: the budget spent, a
// non-finite state, or a step that underflowed. The entry point's loop is
// the CPU's `while`, so that each of its passes makes at most one attempt
// (llvmpipe counts the loop passes of a SIMD group's lanes together).
fn segment(
    drive: Drive,
    y: ptr<function, Vector>,
    end: Real,
    h: ptr<function, Real>,
    budget: ptr<function, u32>,
    steps: ptr<function, u32>,
    rejected: ptr<function, bool>,
) -> u32 {
    if !((*y)[T] < end) {
        return SEGMENT_DONE;
    }
    if *budget == 0u {
        return STATUS_STEP_BUDGET;
    }
    *budget -= 1u;
    *steps += 1u;
    let last = (*y)[T] + *h >= end * (Real(1.0) - Real(1e-15));
    let step = select(*h, end - (*y)[T], last);
    let attempt = rodas4(drive, *y, step);
    // The largest weighted error, NaN ignored (as Rust's f64::max); the
    // time's weight is infinite, so it is left out.
    let err = largest_error(attempt.error);
    if !is_finite(err) || !all_finite(attempt.next) {
        if step <= SMALLEST_STEP * max(abs(end), MIN_POSITIVE) {
            return STATUS_NON_FINITE;
        }
        *h = step * Real(0.1);
        *rejected = true;
        return SEGMENT_GOING;
    }
    if err <= Real(1.0) {
        if BACKWARD {
            // The backward travel follows the accepted step
            // (variation.wgsl), from its ends as the CPU's `observe` sees
            // them.
            var next = attempt.next;
            if last {
                next[T] = end;
            }
            follow_step(*y, next);
        }
        *y = attempt.next;
        if last {
            (*y)[T] = end;
        }
    } else if step <= SMALLEST_STEP * abs(end) {
        return STATUS_STEP_UNDERFLOW;
    }
    // A third-order estimate: the error scales with the step's fourth
    // power. No growth right after a rejection (Hairer and Wanner's rule).
    let most = select(Real(4.0), Real(1.0), *rejected);
    let factor = clamp(quotient(Real(0.9), fourth_root(max(err, Real(1e-16)))), Real(0.2), most);
    *rejected = err > Real(1.0);
    if !(last && err <= Real(1.0)) {
        *h = step * factor;
    }
    return SEGMENT_GOING;
}

// The stages' matrix W = I - gamma h J with the exact Jacobian J of
// `rhs`, reduced and LU-factored. The rows of the positions and the time
// are trivial (x' = v, t' = 1, and nothing depends on the slider's
// position), so W x = b is solved on the six velocities and deflections
// alone, with x_XP = b_XP + g x_VP, x_XS = b_XS + g x_VS and x_T = b_T
// substituted (g = gamma h).
fn w_matrix(drive: Drive, y: Vector, g: Real) -> W {
    var j = jacobian(y, drive);
    var w: W;
    var a: ReducedMatrix;
    // The CPU's loop over the reduced rows, a call per row with literal
    // indices (no array indexed at run time once inlined).
    const_assert R == 6u;
    w_row(&w, &a, &j, g, 0u);
    w_row(&w, &a, &j, g, 1u);
    w_row(&w, &a, &j, g, 2u);
    w_row(&w, &a, &j, g, 3u);
    w_row(&w, &a, &j, g, 4u);
    w_row(&w, &a, &j, g, 5u);
    w.lu = factor(a);
    w.g = g;
    return w;
}

// Reduced row `r` of W (the body of the CPU's loop over the rows).
fn w_row(w: ptr<function, W>, a: ptr<function, ReducedMatrix>, j: ptr<function, Matrix>, g: Real, r: u32) {
    let n = REDUCED[r];
    (*a)[r][0] = -g * (*j)[n][REDUCED[0]];
    (*a)[r][1] = -g * (*j)[n][REDUCED[1]];
    (*a)[r][2] = -g * (*j)[n][REDUCED[2]];
    (*a)[r][3] = -g * (*j)[n][REDUCED[3]];
    (*a)[r][4] = -g * (*j)[n][REDUCED[4]];
    (*a)[r][5] = -g * (*j)[n][REDUCED[5]];
    (*a)[r][r] += Real(1.0);
    // x_XP,i = b_XP,i + g x_VP,i: its column folds into VP,i's.
    (*a)[r][0] -= g * g * (*j)[n][XP];
    (*w).j_xp[r][0] = (*j)[n][XP];
    (*a)[r][1] -= g * g * (*j)[n][XP + 1u];
    (*w).j_xp[r][1] = (*j)[n][XP + 1u];
    (*w).j_t[r] = (*j)[n][T];
}

// W::solve: W x = b, with the step's W (`w_lu` and its kin). The CPU's loops
// over the reduced rows and the axes are written out, with literal indices.
fn solve(b: Vector) -> Vector {
    let g = w_g();
    var reduced: Reduced;
    reduced[0] = reduced_entry(b, 0u);
    reduced[1] = reduced_entry(b, 1u);
    reduced[2] = reduced_entry(b, 2u);
    reduced[3] = reduced_entry(b, 3u);
    reduced[4] = reduced_entry(b, 4u);
    reduced[5] = reduced_entry(b, 5u);
    let v = solve_lu(reduced);
    var x: Vector;
    x[REDUCED[0]] = v[0];
    x[REDUCED[1]] = v[1];
    x[REDUCED[2]] = v[2];
    x[REDUCED[3]] = v[3];
    x[REDUCED[4]] = v[4];
    x[REDUCED[5]] = v[5];
    x[XP] = b[XP] + g * x[VP];
    x[XS] = b[XS] + g * x[VS];
    x[XP + 1u] = b[XP + 1u] + g * x[VP + 1u];
    x[XS + 1u] = b[XS + 1u] + g * x[VS + 1u];
    x[T] = b[T];
    return x;
}

// Reduced row `r` of the right-hand side `b` (Rust's sum over the axes,
// from -0.0, which adds nothing).
fn reduced_entry(b: Vector, r: u32) -> Real {
    let g = w_g();
    let from_xp = w_j_xp(r, 0) * b[XP] + w_j_xp(r, 1) * b[XP + 1u];
    return b[REDUCED[r]] + g * from_xp + g * w_j_t(r) * b[T];
}

// Lu::factor (`factor`) is written out by the host too
// (`pidm::gpu::lugre`'s `factor_source`): partial pivoting on the largest
// magnitude (the last of equal ones, as Rust's max_by), whole rows swapped
// by selects, every entry a value of its own.

// Lu::solve: A x = b (`solve_lu`) is written out by the host
// (`pidm::gpu::lugre`'s `solve_lu_source`): the factorisation swapped
// whole rows, multipliers included (as LAPACK's getrf), so every swap
// applies to `b` before the forward substitution; selects make the swaps
// and constant indices the substitutions, so no lane indexes `b` at run
// time.
