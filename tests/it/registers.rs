//! Issue 57's register budgets: ACO (Mesa 25's RADV on a null navi31 and
//! navi21, `pidm::gpu::isa`) compiles every pipeline a hardware batch
//! creates, and each budget `gpu::isa::BUDGETS` holds must be kept. Under
//! `CI=true` a missing RADV fails the test (`.ci/radv.sh` unpacks it);
//! elsewhere it says so and passes.

use pidm::gpu::isa::{self, Family, Statistics};
use std::path::Path;

/// Every batch pipeline's statistics on every family, or `None` (said on
/// stderr) where the newer RADV is not unpacked outside CI.
fn statistics() -> Option<Vec<Statistics>> {
    if !isa::radv_available() {
        assert!(
            std::env::var_os("CI").is_none(),
            "no Mesa 25 RADV in {}: .ci/radv.sh unpacks it",
            isa::radv_dir().display()
        );
        eprintln!(
            "registers: no RADV in {}, not measured",
            isa::radv_dir().display()
        );
        return None;
    }
    let pipelines = isa::batch_pipelines().unwrap();
    let exe = Path::new(env!("CARGO_BIN_EXE_pidm"));
    let mut stats = Vec::new();
    for family in Family::ALL {
        stats.extend(isa::measure(exe, family, &pipelines).unwrap());
    }
    Some(stats)
}

#[test]
fn every_batch_pipeline_keeps_the_budgets_held() {
    let Some(stats) = statistics() else { return };
    eprint!("{}", isa::table(&stats));
    // 28 Karnopp variants (the waveform part doubles them; f64 adds 4
    // with the backward travel) and LuGre's three (a sawtooth's, a
    // waveform's and a backward one's), on both families.
    assert_eq!(stats.len(), 2 * 31);
    for s in &stats {
        // Sanity: the figures are a compiled program's.
        assert!(s.vgprs > 0 && s.instructions.unwrap_or(1) > 0, "{s:?}");
    }
    let broken: Vec<String> = isa::verdicts(&stats)
        .into_iter()
        .filter(|(b, _, kept)| b.held && !kept)
        .map(|(b, s, _)| {
            format!(
                "{} on {}: {} VGPRs, {} spilled, {} B scratch against {}",
                s.pipeline,
                s.family.as_str(),
                s.vgprs,
                s.spilled_vgprs,
                s.scratch,
                b.describe()
            )
        })
        .collect();
    assert!(broken.is_empty(), "budgets broken:\n{}", broken.join("\n"));
}
