// Mirror of `laws::lugre::model::Clock`'s drive over an axis' corners
// (`laws::floor::drive::Corners`, issue 59; WAVEFORM variants only): the
// waveform's one cycle of (u, level) corners, slew-limited where the
// amplifier is, of instance `held` in `corners` from
// `model.corner_first[i]`, `model.corner_count[i]` of them per axis.
// `model.wgsl`'s `drive_on` and `cycle_corner` call `piece_drive` and
// `piece_end`.

struct Corner {
    u: Real,
    level: Real,
}

@group(0) @binding(16) var<storage, read> corners: array<Corner>;

// The piece of the cycle that holds phase `p` in [0, 1) (`Corners::piece_at`):
// from the last corner at or before `p` to the first one after it (the
// first one a cycle later past the last), or, where `p` lies before the
// first corner, the last piece shifted back a cycle (its end is the CPU's
// (u + 1) - 1, kept from being folded to u). The piece found is never a
// jump: its end lies past `p`, its start at or before it. A binary search
// over the corners (`search_corners`, CORNER_SEARCH halvings written out
// by the host: no loop, so no llvmpipe loop passes; the host keeps an
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
    let hi = search_corners(first, n, p);
    let start = corners[first + hi - 1u];
    if hi == n {
        return Piece(start, Corner(head.u + Real(1.0), head.level));
    }
    return Piece(start, corners[first + hi]);
}

// `Clock::drive_on` over the corners, once `drive_on` found axis `i`
// driven at `v` [V] and its phase `p` in cycle `n` (u0 its clock): the
// drive over the piece that holds `p`, linear in time, written from its
// corner at level 0 where it has one.
fn piece_drive(i: u32, v: Real, u0: Real, n: Real, f: Real, p: Real) -> Linear {
    let piece = piece_at(i, p);
    let k = quotient(v * (piece.end.level - piece.start.level), piece.end.u - piece.start.u);
    if piece.end.level == Real(0.0) {
        return Linear(-k * (n + piece.end.u - u0), k * f);
    }
    let at = k * (u0 - n - piece.start.u);
    return Linear(select(v * piece.start.level + at, at, piece.start.level == Real(0.0)), k * f);
}

// One halving of the search's bracket b = (lo, hi) over the corners from
// `first`: corner lo lies at or before `p`, corner hi past it (hi = the
// count: the first corner a cycle later). A bracket of one piece stays.
fn halve(first: u32, b: vec2<u32>, p: Real) -> vec2<u32> {
    let mid = (b.x + b.y) / 2u;
    let past = corners[first + mid].u > p;
    let narrower = select(vec2<u32>(mid, b.y), vec2<u32>(b.x, mid), past);
    return select(b, narrower, b.y - b.x > 1u);
}

// The end of the piece that holds phase `p` [cycles]: what `model.wgsl`'s
// `next_corner` (`Clock::next_corner`) reads of the corners.
fn piece_end(i: u32, p: Real) -> Real {
    return piece_at(i, p).end.u;
}
