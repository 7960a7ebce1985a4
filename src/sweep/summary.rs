//! [`Summary`], the totals over a sweep and over the parts of one run.

use super::Record;
use crate::laws::status::STATUS_OK;
use crate::measurement::keeps_values;
use crate::model::AXES;
use crate::model::motion::Motion;

/// Totals over a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    pub instances: u64,
    /// Instances per status code (index = code; the last entry gathers
    /// unknown codes).
    pub status_counts: [u64; 8],
    /// Instances whose motion was found periodic (a steady measurement).
    pub periodic: u64,
    /// Instances per kind of motion (index = `Motion::code`).
    pub motion: [u64; Motion::ALL.len()],
    /// Instances whose values are merged from replicas
    /// (`crate::replicas`), and the replicas they merged.
    pub merged: u64,
    pub replicas: u64,
    /// Largest standard error of a step among instances that keep values
    /// [m per own drive cycle].
    pub largest_se: f64,
    /// Scene periods integrated over all main instances, and the most of
    /// one instance.
    pub periods: u64,
    pub max_periods: u32,
    /// Integrator steps over all main instances.
    pub steps: u64,
    /// Integrations run, baselines included, each distinct one once.
    pub integrations: u64,
    /// Wall time spent integrating (in the backend) [s].
    pub integration_s: f64,
    /// Integrations an f32 or GPU backend ran on the CPU in f64 instead.
    pub on_cpu: u64,
    /// Of those, f32 runs that stopped at a band graze.
    pub grazes: u64,
    /// f32 window runs among the heaviest of their batch, checked
    /// (`laws::floor::check`); those that carry the f64 reference's value are
    /// counted in `on_cpu` too.
    pub checked: u64,
    /// Of the checked, those that carry the f64 reference's value.
    pub checked_on_cpu: u64,
    /// Simulated time over all integrated instances, baselines included [s].
    pub simulated_s: f64,
    pub extreme_step: [f64; 2],
    /// Per axis, the instance with the most backward step and the one with
    /// the most forward step among those with status 0: (step [m per own
    /// drive cycle], flat index); the index is `u64::MAX` while none is.
    pub best: [[(f64, u64); 2]; AXES],
}

impl Default for Summary {
    fn default() -> Summary {
        Summary {
            instances: 0,
            status_counts: [0; 8],
            periodic: 0,
            motion: [0; Motion::ALL.len()],
            merged: 0,
            replicas: 0,
            largest_se: 0.0,
            periods: 0,
            max_periods: 0,
            steps: 0,
            integrations: 0,
            integration_s: 0.0,
            on_cpu: 0,
            grazes: 0,
            checked: 0,
            checked_on_cpu: 0,
            simulated_s: 0.0,
            extreme_step: [f64::INFINITY, f64::NEG_INFINITY],
            best: [[(f64::INFINITY, u64::MAX), (f64::NEG_INFINITY, u64::MAX)]; AXES],
        }
    }
}

impl Summary {
    /// Adds the totals of another part of the same run.
    pub fn merge(&mut self, other: &Summary) {
        self.instances += other.instances;
        for (a, b) in self.status_counts.iter_mut().zip(other.status_counts) {
            *a += b;
        }
        self.steps += other.steps;
        self.periodic += other.periodic;
        for (a, b) in self.motion.iter_mut().zip(other.motion) {
            *a += b;
        }
        self.merged += other.merged;
        self.replicas += other.replicas;
        self.largest_se = self.largest_se.max(other.largest_se);
        self.periods += other.periods;
        self.max_periods = self.max_periods.max(other.max_periods);
        self.integrations += other.integrations;
        self.integration_s += other.integration_s;
        self.on_cpu += other.on_cpu;
        self.grazes += other.grazes;
        self.checked += other.checked;
        self.checked_on_cpu += other.checked_on_cpu;
        self.simulated_s += other.simulated_s;
        self.extreme_step[0] = self.extreme_step[0].min(other.extreme_step[0]);
        self.extreme_step[1] = self.extreme_step[1].max(other.extreme_step[1]);
        for axis in 0..AXES {
            let [low, high] = other.best[axis];
            self.offer(axis, low.0, low.1);
            self.offer(axis, high.0, high.1);
        }
    }

    /// Takes a step of instance `index` on `axis` as the most backward or
    /// forward one when it is (the lower index wins a tie, whatever the
    /// order instances come in).
    fn offer(&mut self, axis: usize, step: f64, index: u64) {
        if index == u64::MAX || !step.is_finite() {
            return;
        }
        let [low, high] = &mut self.best[axis];
        if step < low.0 || (step == low.0 && index < low.1) {
            *low = (step, index);
        }
        if step > high.0 || (step == high.0 && index < high.1) {
            *high = (step, index);
        }
    }

    /// Counts one finished instance, flat index `index` (its simulated time is added apart,
    /// because baselines add to it too).
    pub fn add(&mut self, rec: &Record, index: u64) {
        self.instances += 1;
        self.status_counts[(rec.status as usize).min(7)] += 1;
        self.steps += rec.steps as u64;
        self.periodic += (rec.period_lag > 0) as u64;
        self.motion[rec.motion.code() as usize] += 1;
        if rec.replicas > 1 {
            self.merged += 1;
            self.replicas += rec.replicas as u64;
        }
        if keeps_values(rec.status) {
            self.largest_se = self.largest_se.max(rec.step_se[0]).max(rec.step_se[1]);
        }
        self.periods += rec.periods as u64;
        self.max_periods = self.max_periods.max(rec.periods);
        if rec.status == STATUS_OK {
            for axis in 0..AXES {
                self.extreme_step[0] = self.extreme_step[0].min(rec.step[axis]);
                self.extreme_step[1] = self.extreme_step[1].max(rec.step[axis]);
                self.offer(axis, rec.step[axis], index);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_counts_every_kind_of_motion() {
        let mut a = Summary::default();
        for (k, motion) in [Motion::Periodic, Motion::Irregular, Motion::Periodic]
            .into_iter()
            .enumerate()
        {
            let rec = Record {
                motion,
                ..Record::default()
            };
            a.add(&rec, k as u64);
        }
        let mut b = Summary::default();
        b.add(&Record::default(), 3);
        b.merge(&a);
        assert_eq!(a.motion, [0, 2, 0, 1, 0]);
        assert_eq!(b.motion, [1, 2, 0, 1, 0]);
    }
}
