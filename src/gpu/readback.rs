//! Which of a steady batch's accumulators come back to the host.
//!
//! Every steady instance has 1,264 bytes of accumulators in f64 (712 in
//! f32), and reading them back cost an H200 0.6 s of a 1000 x 1000 map
//! whose shader ran 0.1-0.25 s (results/gpu.md, "Where a steady map's GPU
//! time goes"). The reduction of a periodic verdict, which most runs at
//! equal drive frequencies reach, reads only the `Head` the shader writes
//! when an instance finishes (32 bytes in f64). So the host reads every
//! head, and the whole accumulators only of the instances that need them:
//! those that ended otherwise, and those the CPU continues.

/// How a steady batch's accumulators are read back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accumulators {
    /// The heads alone: every instance's reduction reads only its head.
    Heads,
    /// The heads, and the whole accumulators of the instances that need
    /// them, copied on the device into one buffer, a copy per run of
    /// consecutive instances.
    Gather,
    /// Every instance's whole accumulators, in one copy.
    Whole,
}

/// The largest share of a batch whose accumulators are gathered, as a
/// divisor: a sixteenth. Beyond it the batch reads them whole, in one
/// copy, rather than recording up to one copy per instance (their cost on
/// a GPU is not measured).
pub const GATHER_DIVISOR: usize = 16;

/// How to read back the accumulators of a batch of `n` steady instances of
/// which `needed` need theirs whole; `whole` forces [`Accumulators::Whole`]
/// (tests compare the others with it).
pub fn plan(n: usize, needed: usize, whole: bool) -> Accumulators {
    if whole || needed * GATHER_DIVISOR > n {
        Accumulators::Whole
    } else if needed == 0 {
        Accumulators::Heads
    } else {
        Accumulators::Gather
    }
}

/// The runs of consecutive indices in `sorted` (ascending, distinct), as
/// (first, length): one device copy each.
pub fn runs(sorted: &[usize]) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    for &k in sorted {
        match out.last_mut() {
            Some((first, length)) if *first + *length == k => *length += 1,
            _ => out.push((k, 1)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `plan(n, needed, whole)` is `expected`.
    fn check(n: usize, needed: usize, whole: bool, expected: Accumulators) {
        assert_eq!(plan(n, needed, whole), expected, "{n} {needed} {whole}");
    }

    #[test]
    fn heads_alone_where_none_needs_more_then_gathered_up_to_a_sixteenth() {
        check(1000, 0, false, Accumulators::Heads);
        check(1000, 1, false, Accumulators::Gather);
        check(1600, 100, false, Accumulators::Gather);
        check(1600, 101, false, Accumulators::Whole);
        check(10, 1, false, Accumulators::Whole);
        check(1000, 0, true, Accumulators::Whole);
    }

    #[test]
    fn consecutive_indices_make_one_run() {
        assert_eq!(runs(&[]), vec![]);
        assert_eq!(runs(&[4]), vec![(4, 1)]);
        assert_eq!(runs(&[0, 1, 2, 5, 7, 8]), vec![(0, 3), (5, 1), (7, 2)]);
    }
}
