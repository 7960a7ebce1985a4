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
        }
    }

    /// "f64-hardware: no spills", for reports.
    pub fn describe(&self) -> String {
        let what = match self.limit {
            Limit::NoSpills => "0 spilled VGPRs, 0 scratch".to_string(),
            Limit::NoSpilledVgprs => "0 spilled VGPRs".to_string(),
            Limit::Vgprs(most) => format!("at most {most} VGPRs"),
        };
        let kind = if self.held { "held" } else { "target" };
        format!("{}*: {what} ({kind})", self.prefix)
    }
}

/// Issue 57's budgets. Karnopp's f64 lane and LuGre's fit since they
/// hold their state and a step's values in device memory, read where used
/// (results/registers.md): at 309d7b2 they spilled 457-499 and 271 VGPRs.
/// The VGPR ceilings are stretch targets.
pub const BUDGETS: [Budget; 5] = [
    Budget {
        prefix: "f32-hardware",
        limit: Limit::NoSpilledVgprs,
        held: true,
    },
    Budget {
        prefix: "f64-hardware",
        limit: Limit::NoSpills,
        held: true,
    },
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
    }

    #[test]
    fn a_budget_reads_only_the_pipelines_of_its_prefix() {
        let all = [
            // Karnopp's f64 lane since it holds its state and a step's
            // values in device memory (309d7b2's: 256 VGPRs, 461 spilled,
            // 33,024 B).
            stats("f64-hardware-window", 256, 0, 0),
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
