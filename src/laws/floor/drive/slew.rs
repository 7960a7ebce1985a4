//! The amplifier's slew limit (issue 59): the voltage the stage sees
//! follows the waveform, never faster than `slew_rate` [V/s]. In a cycle's
//! levels that is at most sigma = slew_rate / (|voltage| frequency) levels
//! per cycle. The follower is taken on its periodic orbit, so that every
//! cycle is the same: its corners, computed once per instance in f64,
//! stay piecewise linear (Karnopp's flows stay exact).

use super::Corners;

/// Where the follower stands: cycle phase and level.
#[derive(Clone, Copy, Debug)]
pub(super) struct Point {
    pub(super) u: f64,
    pub(super) y: f64,
}

impl Corners {
    /// The corners of the follower's periodic orbit under a slew limit of
    /// `sigma` levels per cycle (finite, above 0). A limit at or above
    /// every flank's slope gives these corners back, the same bits.
    pub fn slew_limited(&self, sigma: f64) -> Corners {
        assert!(sigma > 0.0 && sigma.is_finite(), "a slew limit above 0");
        if sigma >= self.steepest() {
            return self.clone();
        }
        let start = self.periodic_start(sigma);
        let mut points: Vec<[f64; 2]> = self
            .follow(start, sigma)
            .into_iter()
            .map(|p| [p.u, p.y])
            .collect();
        // The cycle ends where it started (up to rounding): the end's
        // corner is the start's a cycle later.
        points.pop();
        Corners::wrapped(points)
    }

    /// The follower's level at u = 0 on its periodic orbit: the fixed
    /// point of the cycle map, which is monotone and moves no two starts
    /// apart. Two cycles find it where the follower meets the waveform
    /// (from then on the orbit forgets its start); else bisection.
    fn periodic_start(&self, sigma: f64) -> f64 {
        let cycle = |y: f64| self.follow(y, sigma).last().expect("a cycle").y;
        let once = cycle(self.level(0.0));
        let twice = cycle(once);
        if twice == once {
            return once;
        }
        let (mut lo, mut hi) = self
            .points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[1]), hi.max(p[1]))
            });
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if cycle(mid) > mid {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// The follower over one cycle from level `y0` at u = 0: its corners,
    /// from u = 0 to u = 1.
    pub(super) fn follow(&self, y0: f64, sigma: f64) -> Vec<Point> {
        let mut at = Point { u: 0.0, y: y0 };
        let mut out = vec![at];
        for (a, b) in self.cycle_segments() {
            if b[0] == a[0] {
                // A jump: the follower does not; it slews from here.
                continue;
            }
            let slope = (b[1] - a[1]) / (b[0] - a[0]);
            let target = |u: f64| a[1] + slope * (u - a[0]);
            while at.u < b[0] {
                let gap = target(at.u) - at.y;
                let next = if gap == 0.0 && slope.abs() <= sigma {
                    // Tracking: the follower is the waveform to the corner.
                    Point { u: b[0], y: b[1] }
                } else {
                    let dir = if gap == 0.0 {
                        slope.signum()
                    } else {
                        gap.signum()
                    };
                    let closing = dir * sigma - slope;
                    let meet = if gap != 0.0 && closing * gap > 0.0 {
                        at.u + gap / closing
                    } else {
                        f64::INFINITY
                    };
                    if meet < b[0] {
                        Point {
                            u: meet,
                            y: target(meet),
                        }
                    } else {
                        Point {
                            u: b[0],
                            y: at.y + dir * sigma * (b[0] - at.u),
                        }
                    }
                };
                at = next;
                out.push(at);
            }
        }
        out
    }

    /// The segments of the cycle from u = 0 to u = 1: those of
    /// [`Corners::segments`], with the one that crosses u = 0 split there.
    fn cycle_segments(&self) -> Vec<([f64; 2], [f64; 2])> {
        let mut out: Vec<([f64; 2], [f64; 2])> = Vec::new();
        let mut wrap = None;
        for (a, b) in self.segments() {
            if b[0] > 1.0 {
                // From the last corner to the first a cycle later: up to
                // u = 1 here, and from u = 0 to the first corner.
                let at_end = [1.0, self.level_between(a, b, 1.0)];
                out.push((a, at_end));
                wrap = Some(([0.0, at_end[1]], [b[0] - 1.0, b[1]]));
            } else {
                out.push((a, b));
            }
        }
        if self.points[0][0] > 0.0 {
            let first = wrap.expect("the last segment crosses the cycle's end");
            out.insert(0, first);
        }
        out
    }

    /// The level at `u` on the segment from `a` to `b`.
    fn level_between(&self, a: [f64; 2], b: [f64; 2], u: f64) -> f64 {
        a[1] + (b[1] - a[1]) * (u - a[0]) / (b[0] - a[0])
    }
}
