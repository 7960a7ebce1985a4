//! Rodas4 (Hairer and Wanner), linearly implicit, L-stable and stiffly
//! accurate, of order 4 with an embedded order-3 solution that controls
//! the steps, on the exact Jacobian ([`Model::jacobian`]). The steps of one
//! segment (between drive corners and period ends, inside which the drive
//! is linear in time) and the LU factorisation the stages solve with.

use super::libm::fourth_root;
use super::model::{Linear, Model, N, State, T, VP, VS, XP, XS, Z};
use crate::laws::status::{STATUS_NON_FINITE, STATUS_STEP_BUDGET, STATUS_STEP_UNDERFLOW};
use crate::model::AXES;

/// Rodas4's coefficients (Hairer and Wanner, "Solving Ordinary Differential
/// Equations II", section IV.7; the values of their RODAS code): gamma,
/// the stages' a_ij (stage i starts from y + sum_j a_ij k_j; stage 6 from
/// stage 5's start + k5) and C_ij (stage i's right-hand side adds sum_j
/// C_ij k_j / h). The method is stiffly accurate: y_n+1 is stage 6's
/// start + k6, and k6 is the embedded third-order solution's difference.
pub(crate) const GAMMA: f64 = 0.25;
pub(crate) const A: [[f64; 4]; 4] = [
    [1.544, 0.0, 0.0, 0.0],
    [0.9466785280815826, 0.2557011698983284, 0.0, 0.0],
    [
        3.314825187068521,
        2.896124015972201,
        0.9986419139977817,
        0.0,
    ],
    [
        1.221224509226641,
        6.019134481288629,
        12.53708332932087,
        -0.687886036105895,
    ],
];
pub(crate) const C: [[f64; 5]; 5] = [
    [-5.6688, 0.0, 0.0, 0.0, 0.0],
    [-2.430093356833875, -0.2063599157091915, 0.0, 0.0, 0.0],
    [
        -0.1073529058151375,
        -9.594562251023355,
        -20.47028614809616,
        0.0,
        0.0,
    ],
    [
        7.496443313967647,
        -10.24680431464352,
        -33.99990352819905,
        11.7089089320616,
        0.0,
    ],
    [
        8.083246795921522,
        -7.981132988064893,
        -31.52159432874371,
        16.31930543123136,
        -6.058818238834054,
    ],
];

/// One Rodas4 step of size `h` from `y`: the new state and the local
/// error estimate (k6). The stages solve (I / (gamma h) - J) k = rhs, that
/// is gamma h (I - gamma h J)^-1 rhs.
pub(crate) fn rodas4(model: &Model, drive: &[Linear; AXES], y: &State, h: f64) -> (State, State) {
    let w = w_matrix(model, drive, y, GAMMA * h);
    let mut k = [[0.0; N]; 6];
    let mut start = *y;
    for i in 0..6 {
        if (1..5).contains(&i) {
            start = *y;
            for (j, kj) in k.iter().enumerate().take(i) {
                for n in 0..N {
                    start[n] += A[i - 1][j] * kj[n];
                }
            }
        } else if i == 5 {
            for n in 0..N {
                start[n] += k[4][n];
            }
        }
        let mut rhs = model.rhs(&start, drive);
        if i > 0 {
            for (j, kj) in k.iter().enumerate().take(i) {
                for n in 0..N {
                    rhs[n] += C[i - 1][j] * kj[n] / h;
                }
            }
        }
        let solved = w.solve(rhs);
        k[i] = solved.map(|x| GAMMA * h * x);
    }
    let mut next = start;
    for n in 0..N {
        next[n] += k[5][n];
    }
    (next, k[5])
}

/// The smallest step relative to the segment's end time: below it the
/// run stops with `STATUS_STEP_UNDERFLOW` instead of creeping.
pub(crate) const SMALLEST_STEP: f64 = 1e-14;

/// Rodas4 steps from `y` to time `end` (an exact boundary); `h` carries the
/// step size from segment to segment, `budget` the steps (accepted and
/// rejected) the period has left. Returns the steps taken, or the status
/// that ended the run: the budget spent, a non-finite state, or a step
/// that underflowed.
pub(crate) fn segment(
    model: &Model,
    drive: &[Linear; AXES],
    scale: &State,
    y: &mut State,
    end: f64,
    (h, budget): (&mut f64, &mut u32),
    observe: &mut impl FnMut(&State, &State),
) -> Result<u32, u32> {
    let mut steps = 0;
    let mut rejected = false;
    while y[T] < end {
        if *budget == 0 {
            return Err(STATUS_STEP_BUDGET);
        }
        *budget -= 1;
        steps += 1;
        let last = y[T] + *h >= end * (1.0 - 1e-15);
        let step = if last { end - y[T] } else { *h };
        let (next, e) = rodas4(model, drive, y, step);
        let err = (0..N).fold(0.0_f64, |m, n| m.max((e[n] / scale[n]).abs()));
        if !err.is_finite() || !next.iter().all(|v| v.is_finite()) {
            if step <= SMALLEST_STEP * end.abs().max(f64::MIN_POSITIVE) {
                return Err(STATUS_NON_FINITE);
            }
            *h = step * 0.1;
            rejected = true;
            continue;
        }
        if err <= 1.0 {
            let before = *y;
            *y = next;
            if last {
                y[T] = end;
            }
            observe(&before, y);
        } else if step <= SMALLEST_STEP * end.abs() {
            return Err(STATUS_STEP_UNDERFLOW);
        }
        // A third-order estimate: the error scales with the step's fourth
        // power.
        // No growth right after a rejection (Hairer and Wanner's rule):
        // the error jumps where |v_rel| turns through 0, and growing at
        // once there rejects the next step again.
        let most = if rejected { 1.0 } else { 4.0 };
        let factor = (0.9 / fourth_root(err.max(1e-16))).clamp(0.2, most);
        rejected = err > 1.0;
        if !(last && err <= 1.0) {
            *h = step * factor;
        }
    }
    Ok(steps)
}

/// The stages' matrix W = I - gamma h J with the exact Jacobian J of
/// [`Model::rhs`], reduced and LU-factored. The rows of the positions and
/// the time are trivial (x' = v, t' = 1, and nothing depends on the
/// slider's position), so W x = b is solved on the six velocities and
/// deflections alone, with x_XP = b_XP + g x_VP, x_XS = b_XS + g x_VS and
/// x_T = b_T substituted (g = gamma h): a 6 x 6 factorisation in place of
/// 11 x 11, the same solution.
struct W {
    lu: Lu,
    g: f64,
    /// J's columns of the stage positions and of the time, on the reduced
    /// rows.
    j_xp: [[f64; AXES]; R],
    j_t: [f64; R],
}

/// The reduced unknowns: v_p, v_s and z of each axis, in this order.
pub(crate) const R: usize = 3 * AXES;
pub(crate) const REDUCED: [usize; R] = [VP, VP + 1, VS, VS + 1, Z, Z + 1];

fn w_matrix(model: &Model, drive: &[Linear; AXES], y: &State, g: f64) -> W {
    let j = model.jacobian(y, drive);
    let mut a = [[0.0; R]; R];
    let mut j_xp = [[0.0; AXES]; R];
    let mut j_t = [0.0; R];
    for (r, &n) in REDUCED.iter().enumerate() {
        for (c, &m) in REDUCED.iter().enumerate() {
            a[r][c] = -g * j[n][m];
        }
        a[r][r] += 1.0;
        for i in 0..AXES {
            // x_XP,i = b_XP,i + g x_VP,i: its column folds into VP,i's.
            a[r][i] -= g * g * j[n][XP + i];
            j_xp[r][i] = j[n][XP + i];
        }
        j_t[r] = j[n][T];
    }
    W {
        lu: Lu::factor(a),
        g,
        j_xp,
        j_t,
    }
}

impl W {
    /// Solves W x = b.
    fn solve(&self, b: State) -> State {
        let g = self.g;
        let reduced: [f64; R] = std::array::from_fn(|r| {
            let n = REDUCED[r];
            let from_xp: f64 = (0..AXES).map(|i| self.j_xp[r][i] * b[XP + i]).sum();
            b[n] + g * from_xp + g * self.j_t[r] * b[T]
        });
        let v = self.lu.solve(reduced);
        let mut x = [0.0; N];
        for (r, &n) in REDUCED.iter().enumerate() {
            x[n] = v[r];
        }
        for i in 0..AXES {
            x[XP + i] = b[XP + i] + g * x[VP + i];
            x[XS + i] = b[XS + i] + g * x[VS + i];
        }
        x[T] = b[T];
        x
    }
}

/// An LU factorisation with partial pivoting of the R x R reduced matrix.
struct Lu {
    a: [[f64; R]; R],
    pivot: [usize; R],
}

impl Lu {
    fn factor(mut a: [[f64; R]; R]) -> Lu {
        let mut pivot = [0; R];
        for k in 0..R {
            let p = (k..R)
                .max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))
                .unwrap_or(k);
            a.swap(k, p);
            pivot[k] = p;
            let (top, rest) = a.split_at_mut(k + 1);
            let row = &top[k];
            for below in rest.iter_mut() {
                let l = below[k] / row[k];
                below[k] = l;
                for (x, r) in below[k + 1..].iter_mut().zip(&row[k + 1..]) {
                    *x -= l * r;
                }
            }
        }
        Lu { a, pivot }
    }

    /// Solves A x = b. The factorisation swapped whole rows, multipliers
    /// included (as LAPACK's getrf), so every swap applies to `b` before
    /// the forward substitution, not between its columns.
    fn solve(&self, mut b: [f64; R]) -> [f64; R] {
        for k in 0..R {
            b.swap(k, self.pivot[k]);
        }
        for k in 0..R {
            for i in k + 1..R {
                b[i] -= self.a[i][k] * b[k];
            }
        }
        for k in (0..R).rev() {
            for j in k + 1..R {
                b[k] -= self.a[k][j] * b[j];
            }
            b[k] /= self.a[k][k];
        }
        b
    }
}
