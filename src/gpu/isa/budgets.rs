//! The register budgets of issue 57, the one home of the figures `pidm
//! info --shader` reports against and `tests/it/registers.rs` holds.
//! A budget reads ACO's allocated VGPRs, spilled VGPRs and scratch of the
//! pipelines whose names start with its prefix, on both families.

use super::Statistics;

/// What a budget bounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    /// No spilled VGPRs and no scratch: the lane lives in registers.
    NoSpills,
    /// No spilled VGPRs (scratch may hold what the program itself puts
    /// there).
    NoSpilledVgprs,
    /// At most this many allocated VGPRs (more waves per SIMD).
    Vgprs(u64),
    /// At most this many spilled VGPRs: a ceiling at the figures of
    /// 309d7b2, so that no change spills more while the lane does not fit.
    SpilledAtMost(u64),
}

/// One budget.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    /// Pipelines whose names start with it.
    pub prefix: &'static str,
    pub limit: Limit,
    /// Whether the tests fail where it is broken; a budget not held is a
    /// target, reported beside the figures.
    pub held: bool,
}

impl Budget {
    /// Whether `s` keeps this budget.
    pub fn kept(&self, s: &Statistics) -> bool {
        match self.limit {
            Limit::NoSpills => s.spilled_vgprs == 0 && s.scratch == 0,
            Limit::NoSpilledVgprs => s.spilled_vgprs == 0,
            Limit::Vgprs(most) => s.vgprs <= most,
            Limit::SpilledAtMost(most) => s.spilled_vgprs <= most,
        }
    }

    /// "f64-hardware: no spills", for reports.
    pub fn describe(&self) -> String {
        let what = match self.limit {
            Limit::NoSpills => "0 spilled VGPRs, 0 scratch".to_string(),
            Limit::NoSpilledVgprs => "0 spilled VGPRs".to_string(),
            Limit::Vgprs(most) => format!("at most {most} VGPRs"),
            Limit::SpilledAtMost(most) => format!("at most {most} spilled VGPRs"),
        };
        let kind = if self.held { "held" } else { "target" };
        format!("{}*: {what} ({kind})", self.prefix)
    }
}

/// The most VGPRs any f64 Karnopp variant spilled at 309d7b2 (steady +
/// phase + load, navi31 and navi21); lowered as the lane shrinks.
pub const F64_SPILL_CEILING: u64 = 499;

/// LuGre's hardware pipeline's spilled VGPRs at 309d7b2.
pub const LUGRE_SPILL_CEILING: u64 = 271;

/// Issue 57's budgets. The f64 ones are targets until the lanes fit (see
/// results/registers.md for where they stand).
pub const BUDGETS: [Budget; 7] = [
    Budget {
        prefix: "f32-hardware",
        limit: Limit::NoSpilledVgprs,
        held: true,
    },
    Budget {
        prefix: "f64-hardware",
        limit: Limit::SpilledAtMost(F64_SPILL_CEILING),
        held: true,
    },
    Budget {
        prefix: super::LUGRE_NAME,
        limit: Limit::SpilledAtMost(LUGRE_SPILL_CEILING),
        held: true,
    },
    Budget {
        prefix: "f64-hardware",
        limit: Limit::NoSpills,
        held: false,
    },
    // Held since the lane reads its model, stages and W from device
    // memory where used (237 VGPRs asked on navi31, none spilled).
    Budget {
        prefix: super::LUGRE_NAME,
        limit: Limit::NoSpills,
        held: true,
    },
    Budget {
        prefix: "f64-hardware",
        limit: Limit::Vgprs(192),
        held: false,
    },
    Budget {
        prefix: "f32-hardware",
        limit: Limit::Vgprs(120),
        held: false,
    },
];

/// Each budget's verdict on every pipeline it reads: (budget, statistics,
/// kept).
pub fn verdicts(stats: &[Statistics]) -> Vec<(Budget, &Statistics, bool)> {
    let mut out = Vec::new();
    for b in BUDGETS {
        for s in stats.iter().filter(|s| s.pipeline.starts_with(b.prefix)) {
            out.push((b, s, b.kept(s)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::isa::Family;

    fn stats(pipeline: &str, vgprs: u64, spilled: u64, scratch: u64) -> Statistics {
        Statistics {
            pipeline: pipeline.to_string(),
            family: Family::Navi31,
            vgprs,
            vgprs_asked: None,
            spilled_vgprs: spilled,
            spilled_sgprs: 0,
            scratch,
            subgroups_per_simd: 4,
            instructions: None,
            all: Default::default(),
        }
    }

    /// Whether `limit` keeps a pipeline of these figures.
    fn check(limit: Limit, (vgprs, spilled, scratch): (u64, u64, u64), kept: bool) {
        let b = Budget {
            prefix: "f64-hardware",
            limit,
            held: true,
        };
        let s = stats("f64-hardware-window", vgprs, spilled, scratch);
        assert_eq!(b.kept(&s), kept, "{limit:?} on {vgprs} {spilled} {scratch}");
    }

    #[test]
    fn budgets_read_the_figures_they_name() {
        check(Limit::NoSpills, (256, 0, 0), true);
        check(Limit::NoSpills, (256, 0, 1024), false);
        check(Limit::NoSpills, (256, 1, 0), false);
        check(Limit::NoSpilledVgprs, (256, 0, 1024), true);
        check(Limit::NoSpilledVgprs, (240, 3, 0), false);
        check(Limit::Vgprs(192), (192, 0, 0), true);
        check(Limit::Vgprs(192), (216, 0, 0), false);
        check(Limit::SpilledAtMost(499), (256, 499, 33536), true);
        check(Limit::SpilledAtMost(499), (256, 500, 33536), false);
    }

    #[test]
    fn a_budget_reads_only_the_pipelines_of_its_prefix() {
        let all = [
            stats("f64-hardware-window", 256, 461, 33024),
            stats("f32-hardware-window", 240, 0, 0),
            // LuGre's lane since it reads its model, stages and W where
            // used (309d7b2's: 256 VGPRs, 271 spilled, 69,376 B).
            stats(crate::gpu::isa::LUGRE_NAME, 252, 0, 0),
        ];
        let v = verdicts(&all);
        // Each budget reads the one pipeline of its prefix.
        assert_eq!(v.len(), BUDGETS.len());
        for (b, s, kept) in v {
            assert!(s.pipeline.starts_with(b.prefix));
            assert_eq!(kept, b.kept(s));
            // Every budget held today is kept by today's figures.
            assert!(!b.held || kept, "{}", b.describe());
        }
    }
}
