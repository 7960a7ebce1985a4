//! Stall-load maps (`[stall]`, docs/model.md section 7): for every instance of
//! a scene, the load along one axis, against its unloaded step's
//! direction, at which that axis' steady step is zero: the largest load
//! the actuator moves at that drive.
//!
//! Each instance's search brackets and bisects on its own (`search`), but
//! the searches advance together in waves: every wave hands the probe of
//! every open search to the backend as one batch (`sweep::run_with_memo`
//! over a wave's probes), so a GPU runs whole waves, and an instance that
//! brackets early stops early. Wave 0 is the scene's ordinary run, whose
//! maps the result file holds as for any scene; its steps start the
//! searches.
//!
//! Split by concern: `search` (one instance's search on plain values, the
//! stall maps' record and its check), [`waves`] (the waves over an
//! integration closure, so tests run them on synthetic steps) and `run` (a
//! stall run into its result file, with checkpoint, resume and shards).

pub mod run;
pub mod search;

use anyhow::Result;

pub use crate::scene::{BRACKET, DEFAULT_TOLERANCE_N};
pub use run::{Outcome, Report};
pub use search::{Search, StallRecord};

/// The integration of one wave: its number (from 1) and its probes as
/// (index into the searches, signed load [N]), to each probe's (step [m
/// per own drive cycle], status).
pub type Integrate<'a> = dyn FnMut(u32, &[(usize, f64)]) -> Result<Vec<(f64, u32)>> + 'a;

/// Runs `searches` to their ends in waves: wave `w` (from 1) asks
/// `integrate(w, probes)` for the (step [m per own drive cycle], status)
/// of every open search's probe at once, probes as (index into
/// `searches`, signed load [N]), and hands each back to its search.
/// Returns the waves run.
pub fn waves(searches: &mut [Search], integrate: &mut Integrate<'_>) -> Result<u32> {
    let mut wave = 0;
    loop {
        let probes: Vec<(usize, f64)> = searches
            .iter()
            .enumerate()
            .filter_map(|(k, s)| s.probe().map(|load| (k, load)))
            .collect();
        if probes.is_empty() {
            return Ok(wave);
        }
        wave += 1;
        let steps = integrate(wave, &probes)?;
        anyhow::ensure!(
            steps.len() == probes.len(),
            "internal: {} steps for {} probes",
            steps.len(),
            probes.len()
        );
        for (&(k, _), &(step, status)) in probes.iter().zip(&steps) {
            searches[k].offer(step, status);
        }
    }
}

/// The room for a load along `axis` [N]: the largest |L_axis| with |L| <
/// f_c beside the load the instance carries on the other axis,
/// sqrt(f_c^2 - L_other^2) (0 where there is none).
pub fn room(inst: &crate::model::Instance, axis: usize) -> f64 {
    let m = &inst.mechanism;
    let other = m.load[1 - axis];
    let fc = m.coulomb_friction;
    (fc * fc - other * other).max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The waves carry every open search at once and drop the finished:
    /// searches that bracket early stop early, and the wave count is the
    /// longest search's.
    #[test]
    fn waves_batch_the_open_searches_and_stop_the_finished() {
        // Stall loads at -0.02, -0.3 and -0.9 N on lines of slope 20 um/N,
        // and one that never stalls.
        let lines = [0.4e-6, 6e-6, 18e-6, -1.0];
        let step = |k: usize, l: f64| {
            if lines[k] < 0.0 {
                (1e-6, 0)
            } else {
                (lines[k] + 20e-6 * l, 0)
            }
        };
        let mut searches: Vec<Search> = (0..lines.len())
            .map(|k| Search::new(step(k, 0.0).0, 0, 1.0, 1e-4))
            .collect();
        let mut batches = Vec::new();
        let waves = waves(&mut searches, &mut |w, probes| {
            batches.push((w, probes.len()));
            Ok(probes.iter().map(|&(k, l)| step(k, l)).collect())
        })
        .unwrap();
        let results: Vec<StallRecord> = searches.iter().map(|s| s.result().unwrap()).collect();
        for (k, want) in [-0.02, -0.3, -0.9].iter().enumerate() {
            assert!((results[k].load - want).abs() <= 1e-4, "{:?}", results[k]);
        }
        assert_eq!(
            results[3].status,
            crate::measurement::status::STATUS_NO_STALL
        );
        assert_eq!(waves, results.iter().map(|r| r.waves).max().unwrap() - 1);
        // Every wave is one batch of the searches still open, fewer and
        // fewer.
        assert_eq!(batches.first(), Some(&(1, 4)));
        assert!(batches.windows(2).all(|p| p[1].1 <= p[0].1), "{batches:?}");
        let probes: usize = batches.iter().map(|b| b.1).sum();
        let waves_each: u32 = results.iter().map(|r| r.waves - 1).sum();
        assert_eq!(probes as u32, waves_each);
    }

    #[test]
    fn the_room_is_what_f_c_leaves_beside_the_other_load() {
        let mut inst = crate::model::Instance::TABLE1;
        assert_eq!(room(&inst, 0), 1.0);
        inst.mechanism.load = [0.0, 0.6];
        assert!((room(&inst, 0) - 0.8).abs() < 1e-15);
        assert_eq!(room(&inst, 1), 1.0);
    }
}
