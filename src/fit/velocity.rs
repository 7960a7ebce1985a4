//! Measured velocities as steps (docs/fit.md): a velocity [m/s] is a step
//! per own drive cycle times the axis' drive frequency (docs/model.md
//! section 4), so each row's velocity is divided by its instance's own
//! frequency on that axis, the scene's ties and `frequency_ratio` applied
//! ([`Scene::from_toml`] builds the instance, as for any candidate).
//!
//! The conversion is made once, before the fit: a free key that moves the
//! frequency of an axis measured as a velocity (`axis.x.frequency`, or
//! `axis.y.frequency_ratio`, or a key axis y copies) is refused.

use anyhow::{Result, bail};

use super::data::Data;
use super::spec::Free;
use crate::model::{AXES, AXIS_NAMES};
use crate::scene::Scene;

/// Where along a free key's bounds the frequencies are compared with
/// those at the middle (fractions of the bounds, in search coordinates).
const PROBES: [f64; 4] = [0.0, 0.25, 0.75, 1.0];

/// Each data row's drive frequency on each axis [Hz], with the free keys
/// at `middle` (the middle of their bounds); an error when some free key
/// moves the frequency of an axis the data measure as a velocity.
/// `scene_at` is the scene of the rows at the free keys' values, or why it
/// has none.
pub fn frequencies(
    data: &Data,
    free: &[Free],
    middle: &[f64],
    scene_at: &dyn Fn(&[f64]) -> std::result::Result<Scene, String>,
) -> Result<Vec<[f64; AXES]>> {
    let axes = data.velocity_axes();
    let scene = match scene_at(middle) {
        Ok(scene) => scene,
        Err(e) => bail!(
            "{}: the rows' instances, to turn velocities into steps: {e}",
            data.path.display(),
        ),
    };
    let base = of(&scene);
    for (k, free) in free.iter().enumerate() {
        let [lo, hi] = free.coordinate_bounds();
        for t in PROBES {
            let mut values = middle.to_vec();
            values[k] = free.value(lo + t * (hi - lo));
            let Ok(scene) = scene_at(&values) else {
                continue;
            };
            let moved = of(&scene);
            for &axis in &axes {
                let changed = base
                    .iter()
                    .zip(&moved)
                    .any(|(a, b)| (a[axis] - b[axis]).abs() > 1e-12 * a[axis].abs());
                if changed {
                    let column = data.value[axis].as_ref().map_or("", |m| &m.name);
                    let a = AXIS_NAMES[axis];
                    bail!(
                        "`{}` is free in [fit] and moves axis {a}'s drive frequency, which turns \
                         {column} of {} into a step per cycle (step = velocity / frequency): a \
                         velocity needs frequencies the fit does not move; give the steps \
                         (step_{a}_um, ...) or fix `{}`",
                        free.key,
                        data.path.display(),
                        free.key
                    );
                }
            }
        }
    }
    Ok(base)
}

/// Each instance's drive frequency on each axis.
fn of(scene: &Scene) -> Vec<[f64; AXES]> {
    (0..scene.instance_count())
        .map(|i| {
            let inst = scene.instance(i);
            std::array::from_fn(|a| inst.axes[a].frequency)
        })
        .collect()
}
