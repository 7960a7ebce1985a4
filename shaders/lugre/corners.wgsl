// Mirror of `laws::lugre::model::Clock`'s drive over an axis' corners
// (`laws::floor::drive::Corners`, issue 59; WAVEFORM variants only): the
// waveform's one cycle of (u, level) corners, slew-limited where the
// amplifier is, of instance `held` in `corners` from
// `model.corner_first[i]`, `model.corner_count[i]` of them per axis.
// `model.wgsl`'s `drive_on` and `next_corner` call these.

struct Corner {
    u: Real,
    level: Real,
}

@group(0) @binding(16) var<storage, read> corners: array<Corner>;

// The piece of the cycle that holds phase `p` in [0, 1) (`Corners::piece_at`):
// from the last corner at or before `p` to the first one after it (the
// first one a cycle later past the last), or, where `p` lies before the
// first corner, the last piece shifted back a cycle (its end is the CPU's
// (u + 1) - 1, kept from being folded to u). No piece found is a jump:
// the first corner after `p` follows one at or before it. A binary search
// over the corners, at most CORNER_SEARCH halvings (the host keeps an
// axis' corners within 2^CORNER_SEARCH).
struct Piece {
    start: Corner,
    end: Corner,
}

fn piece_at(i: u32, p: Real) -> Piece {
    var first_of = model.corner_first;
    var count_of = model.corner_count;
    let first = first_of[i];
    let n = count_of[i];
    let head = corners[first];
    let last = corners[first + n - 1u];
    if p < head.u {
        return Piece(Corner(last.u - Real(1.0), last.level), Corner(keep(head.u + Real(1.0)) - Real(1.0), head.level));
    }
    // u of corner lo is at most p; corner hi (n: the first a cycle later)
    // lies past it.
    var lo = 0u;
    var hi = n;
    for (var s = 0u; s < CORNER_SEARCH && hi - lo > 1u; s++) {
        let mid = (lo + hi) / 2u;
        if corners[first + mid].u > p {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let start = corners[first + hi - 1u];
    if hi == n {
        return Piece(start, Corner(head.u + Real(1.0), head.level));
    }
    return Piece(start, corners[first + hi]);
}

// `Clock::drive_on` over the corners: axis `i`'s drive over a segment
// that contains `t_mid` [s] and no corner, linear in time, each piece
// written from its corner at level 0 where it has one.
fn corner_drive_on(clock: Clock, i: u32, t_mid: Real) -> Linear {
    var start = clock.start;
    let v = model.voltage[i];
    if v == Real(0.0) {
        return Linear(Real(0.0), Real(0.0));
    }
    let u0 = start[i];
    let f = model.frequency[i];
    let n = floor(u0 + f * t_mid);
    let piece = piece_at(i, u0 + f * t_mid - n);
    let k = quotient(v * (piece.end.level - piece.start.level), piece.end.u - piece.start.u);
    if piece.end.level == Real(0.0) {
        return Linear(-k * (n + piece.end.u - u0), k * f);
    }
    let at = k * (u0 - n - piece.start.u);
    return Linear(select(v * piece.start.level + at, at, piece.start.level == Real(0.0)), k * f);
}

// `Clock::next_corner` over the corners: the first corner of axis `i`
// after `t` [s] (INFINITY undriven); a corner rounded onto t gives the
// next one, at most CORNER_RETRIES times, as `next_corner` does.
fn corner_next(clock: Clock, i: u32, t: Real) -> Real {
    var start = clock.start;
    if model.voltage[i] == Real(0.0) {
        return INFINITY;
    }
    let u0 = start[i];
    let f = model.frequency[i];
    var after = t;
    var at = t;
    for (var retry = 0u; retry < CORNER_RETRIES; retry++) {
        let u = u0 + f * after;
        let n = floor(u);
        let corner = n + piece_at(i, u - n).end.u;
        at = quotient(corner - u0, f);
        if at <= after + Real(1e-15) * (abs(after) + quotient(Real(1.0), f)) {
            after = at + quotient(Real(1e-12), f);
        } else {
            break;
        }
    }
    return at;
}
