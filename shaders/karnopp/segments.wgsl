// Mirror of the segments of `laws::karnopp::integrate::drive` (WAVEFORM
// variants only): each axis' cycle as linear segments, the instance's in
// `segments` from `segment_first`, `segment_count` of them per axis.

struct Segment {
    end: Real,
    length: Real,
    level: Real,
    per_cycle: Real,
    slope: Real,
    time: Real,
    time_lo: Real,
    _pad: Real,
}

@group(0) @binding(12) var<storage, read> segments: array<Segment>;

// The drive force and slope on each axis' current segment: level -
// to_corner x per_cycle, as `drive_force` has it.
fn segment_drive(st: State, to_corner: V2) -> Drive {
    let c = &coefficients[held];
    let x = segments[c.segment_first.x + st.segment.x];
    let y = segments[c.segment_first.y + st.segment.y];
    let w = V2(x.level, y.level) - to_corner * V2(x.per_cycle, y.per_cycle);
    return Drive(c.amplitude * w, V2(x.slope, y.slope));
}

// The next segment of one axis: its index and the one after `k` of
// `count`, cyclically.
fn following(k: u32, count: u32) -> u32 {
    return select(0u, k + 1u, k + 1u < count);
}

// Each axis at a reached corner moves to its next segment: the corner
// after it is that segment's length (and duration) on.
fn next_segments(st: ptr<function, State>, reached: vec2<bool>) {
    let c = &coefficients[held];
    let k = vec2<u32>(following((*st).segment.x, c.segment_count.x), following((*st).segment.y, c.segment_count.y));
    let x = segments[c.segment_first.x + k.x];
    let y = segments[c.segment_first.y + k.y];
    (*st).segment = select((*st).segment, k, reached);
    let length = V2(x.length, y.length);
    (*st).next_corner = select((*st).next_corner, (*st).next_corner + length, reached);
    if CORNER_CLOCK {
        let moved = add_parts((*st).corner_at, (*st).corner_at_lo, V2(x.time, y.time), V2(x.time_lo, y.time_lo));
        (*st).corner_at = select((*st).corner_at, moved.hi, reached);
        (*st).corner_at_lo = select((*st).corner_at_lo, moved.lo, reached);
    }
}

// The segment of axis `first`'s `count` segments that holds cycle phase
// `p`, and the phase of its end (`segment_at`).
struct SegmentAt {
    index: u32,
    corner: Real,
}

fn segment_at(first: u32, count: u32, p: Real) -> SegmentAt {
    let head = segments[first];
    let last = segments[first + count - 1u];
    if p < head.end - head.length {
        return SegmentAt(count - 1u, last.end - Real(1.0));
    }
    for (var k = 0u; k < count; k++) {
        let s = segments[first + k];
        if p < s.end {
            return SegmentAt(k, s.end);
        }
    }
    return SegmentAt(count - 1u, last.end);
}
