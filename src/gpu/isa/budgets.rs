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
    Budget {
        prefix: super::LUGRE_NAME,
        limit: Limit::NoSpills,
        held: false,
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
