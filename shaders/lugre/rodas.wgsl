// Mirror of src/cpu/lugre/rodas.rs: Rodas4 (Hairer and Wanner), linearly
// implicit, L-stable and stiffly accurate, of order 4 with an embedded
// order-3 solution that controls the steps, on the exact Jacobian
// (`jacobian`); the step attempts of one segment (between drive corners
// and period ends, inside which the drive is linear in time) and the LU
// factorisation the stages solve with. The coefficients GAMMA, RODAS_A and
// RODAS_C come from the Rust consts through the prelude.

// One Rodas4 step: the new state and the local error estimate (k6).
struct Step {
    next: State,
    error: State,
}

// An LU factorisation with partial pivoting of an N x N matrix.
struct Lu {
    a: Matrix,
    pivot: array<u32, N>,
}

// One Rodas4 step of size `h` from `y`. The stages solve (I / (gamma h) -
// J) k = rhs, that is gamma h (I - gamma h J)^-1 rhs.
fn rodas4(drive: Drive, y: State, h: Real) -> Step {
    var w = w_matrix(drive, y, GAMMA * h);
    var k: array<State, 6>;
    var start = y;
    for (var i = 0u; i < 6u; i++) {
        if i >= 1u && i < 5u {
            start = y;
            for (var j = 0u; j < i; j++) {
                let a = RODAS_A[i - 1u][j];
                for (var n = 0u; n < N; n++) {
                    start[n] += a * k[j][n];
                }
            }
        } else if i == 5u {
            for (var n = 0u; n < N; n++) {
                start[n] += k[4][n];
            }
        }
        var f = rhs(start, drive);
        if i > 0u {
            for (var j = 0u; j < i; j++) {
                let c = RODAS_C[i - 1u][j];
                for (var n = 0u; n < N; n++) {
                    f[n] += div(c * k[j][n], h);
                }
            }
        }
        let solved = solve(&w, f);
        for (var n = 0u; n < N; n++) {
            k[i][n] = GAMMA * h * solved[n];
        }
    }
    var next = start;
    for (var n = 0u; n < N; n++) {
        next[n] += k[5][n];
    }
    return Step(next, k[5]);
}

fn is_finite(x: Real) -> bool {
    return x == x && abs(x) <= INFINITY;
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
    y: ptr<function, State>,
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
    var err = Real(0.0);
    var finite = true;
    for (var n = 0u; n < N; n++) {
        if n != T {
            let e = abs(div(attempt.error[n], model.scale[n]));
            if e > err {
                err = e;
            }
        }
        finite = finite && is_finite(attempt.next[n]);
    }
    if !is_finite(err) || !finite {
        if step <= SMALLEST_STEP * max(abs(end), MIN_POSITIVE) {
            return STATUS_NON_FINITE;
        }
        *h = step * Real(0.1);
        *rejected = true;
        return SEGMENT_GOING;
    }
    if err <= Real(1.0) {
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
    let factor = clamp(div(Real(0.9), root(root(max(err, Real(1e-16))))), Real(0.2), most);
    *rejected = err > Real(1.0);
    if !(last && err <= Real(1.0)) {
        *h = step * factor;
    }
    return SEGMENT_GOING;
}

// I - gamma h J with the exact Jacobian J of `rhs`, LU-factored.
fn w_matrix(drive: Drive, y: State, gh: Real) -> Lu {
    var w: Lu;
    w.a = jacobian(y, drive);
    for (var i = 0u; i < N; i++) {
        for (var k = 0u; k < N; k++) {
            w.a[i][k] = -gh * w.a[i][k];
        }
        w.a[i][i] += Real(1.0);
    }
    factor(&w);
    return w;
}

// Lu::factor, in place: partial pivoting on the largest magnitude (the
// last of equal ones, as Rust's max_by), whole rows swapped.
fn factor(lu: ptr<function, Lu>) {
    for (var k = 0u; k < N; k++) {
        var p = k;
        var best = abs((*lu).a[k][k]);
        for (var i = k + 1u; i < N; i++) {
            let v = abs((*lu).a[i][k]);
            if v >= best {
                best = v;
                p = i;
            }
        }
        let row = (*lu).a[k];
        (*lu).a[k] = (*lu).a[p];
        (*lu).a[p] = row;
        (*lu).pivot[k] = p;
        for (var i = k + 1u; i < N; i++) {
            let l = div((*lu).a[i][k], (*lu).a[k][k]);
            (*lu).a[i][k] = l;
            for (var c = k + 1u; c < N; c++) {
                (*lu).a[i][c] -= l * (*lu).a[k][c];
            }
        }
    }
}

// Solves A x = b. The factorisation swapped whole rows, multipliers
// included (as LAPACK's getrf), so every swap applies to `b` before the
// forward substitution.
fn solve(lu: ptr<function, Lu>, rhs_b: State) -> State {
    var b = rhs_b;
    for (var k = 0u; k < N; k++) {
        let p = (*lu).pivot[k];
        let t = b[k];
        b[k] = b[p];
        b[p] = t;
    }
    for (var k = 0u; k < N; k++) {
        for (var i = k + 1u; i < N; i++) {
            b[i] -= (*lu).a[i][k] * b[k];
        }
    }
    for (var kk = 0u; kk < N; kk++) {
        let k = N - 1u - kk;
        for (var j = k + 1u; j < N; j++) {
            b[k] -= (*lu).a[k][j] * b[j];
        }
        b[k] = div(b[k], (*lu).a[k][k]);
    }
    return b;
}
