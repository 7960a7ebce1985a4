//! How a fit weighs its measurements: by the data's standard errors where
//! the file gives them, else by one scale per axis estimated from the
//! residuals. No weight depends on the candidate: the model's own standard
//! error stays out of the weights (the measurement's tolerance holds it
//! under a tenth of the data's, `super::solve`, and the fit reports it).

use super::data::Data;
use super::problem::RowModel;
use crate::model::AXES;

/// The weights of a fit's measurements.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Weights {
    /// Whether each axis' standard errors come from the data.
    pub known: [bool; AXES],
    /// Each axis' scale where it is estimated [m per own drive cycle].
    pub scale: [f64; AXES],
}

impl Weights {
    /// The data's standard errors where given; elsewhere a first scale, the
    /// axis' root-mean-square step (so both axes weigh alike until the
    /// residuals say more).
    pub fn initial(data: &Data) -> Weights {
        let scale = std::array::from_fn(|a| {
            let steps: Vec<f64> = data.rows.iter().filter_map(|r| r.step[a]).collect();
            let rms = (steps.iter().map(|s| s * s).sum::<f64>() / steps.len().max(1) as f64).sqrt();
            if rms > 0.0 { rms } else { 1e-9 }
        });
        Weights {
            known: data.has_se,
            scale,
        }
    }

    /// Whether some axis' scale is estimated.
    pub fn estimated(&self) -> bool {
        self.known.iter().any(|k| !k)
    }

    /// Whether every axis `data` measures has the data's standard errors.
    pub fn all_given(&self, data: &Data) -> bool {
        (0..AXES).all(|a| self.known[a] || data.measured_on(a) == 0)
    }

    /// The data's standard error of a row's step on `axis` [m], without the
    /// model's.
    pub fn data_se(&self, row_se: Option<f64>, axis: usize) -> f64 {
        match (self.known[axis], row_se) {
            (true, Some(se)) => se,
            _ => self.scale[axis],
        }
    }

    /// The weighted residuals, row by row and axis by axis where measured.
    pub fn residuals(&self, data: &Data, models: &[RowModel]) -> Vec<f64> {
        let mut out = Vec::with_capacity(data.measurements());
        for (row, model) in data.rows.iter().zip(models) {
            for axis in 0..AXES {
                if let Some(step) = row.step[axis] {
                    let sigma = self.data_se(row.se[axis], axis);
                    out.push((model.step[axis] - step) / sigma);
                }
            }
        }
        out
    }

    /// The scales re-estimated from the unweighted residuals of `models`
    /// with `free` parameters (each axis' share of the degrees of freedom);
    /// known axes keep theirs.
    pub fn reestimated(&self, data: &Data, models: &[RowModel], free: usize) -> Weights {
        let n = data.measurements() as f64;
        let scale = std::array::from_fn(|a| {
            if self.known[a] {
                return self.scale[a];
            }
            let (mut sum, mut count) = (0.0, 0.0);
            for (row, model) in data.rows.iter().zip(models) {
                if let Some(step) = row.step[a] {
                    sum += (model.step[a] - step).powi(2);
                    count += 1.0;
                }
            }
            if count == 0.0 {
                return self.scale[a];
            }
            let dof = (count - free as f64 * count / n).max(1.0);
            // A perfect fit (noise-free data) still needs a finite weight:
            // the integrator's own error, 1e-4 um (docs/model.md section 4).
            (sum / dof).sqrt().max(1e-10)
        });
        Weights { scale, ..*self }
    }

    /// The smallest standard error of the data [m]: the fit's measurement
    /// tolerance is sized against it.
    pub fn smallest_se(&self, data: &Data) -> f64 {
        let mut smallest = f64::INFINITY;
        for row in &data.rows {
            for axis in 0..AXES {
                if row.step[axis].is_some() {
                    smallest = smallest.min(self.data_se(row.se[axis], axis));
                }
            }
        }
        smallest
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// Weights of `csv` against a model that is the data plus `offset`.
    fn check(csv: &str, offset: f64, expect_residuals: &[f64], expect_scale: [f64; 2]) {
        let data = Data::parse(csv, Path::new("d.csv")).unwrap();
        let models: Vec<RowModel> = data
            .rows
            .iter()
            .map(|r| RowModel {
                step: r.step.map(|s| s.unwrap_or(0.0) + offset),
                se: [0.0; 2],
            })
            .collect();
        let weights = Weights::initial(&data).reestimated(&data, &models, 1);
        let r = weights.residuals(&data, &models);
        assert_eq!(r.len(), expect_residuals.len());
        for (got, want) in r.iter().zip(expect_residuals) {
            assert!((got - want).abs() < 1e-9, "{r:?}");
        }
        for (got, want) in weights.scale.iter().zip(expect_scale) {
            assert!(
                (got - want).abs() < 1e-15 + 1e-9 * want,
                "{:?}",
                weights.scale
            );
        }
    }

    #[test]
    fn known_errors_weigh_each_value_and_unknown_ones_one_scale_per_axis() {
        // Known SEs: residual = offset / se.
        check(
            "step_x,step_x_se\n1e-6,1e-8\n2e-6,2e-8\n",
            1e-8,
            &[1.0, 0.5],
            [1.5811388300841898e-6, 1e-9],
        );
        // Unknown: two values, one free key, so one degree of freedom; the
        // scale is sqrt(2 * offset^2 / 1) and each residual 1 / sqrt(2).
        let s = 2f64.sqrt();
        check(
            "step_x\n1e-6\n2e-6\n",
            1e-8,
            &[1.0 / s, 1.0 / s],
            [s * 1e-8, 1e-9],
        );
    }
}
