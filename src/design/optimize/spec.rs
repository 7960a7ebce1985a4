//! The `[optimize]` table (docs/design.md): what to maximize or minimize
//! (both: a front), the free keys with their bounds (`[fit]`'s rules) and
//! the constraints.
//!
//! ```toml
//! [optimize]
//! maximize = "step_x"
//! free = { "axis.x.rise" = [0.5, 0.95], "axis.x.fall" = [0.0, 0.05] }
//! subject_to = ["backward_ratio_x <= 0.05", "abs(step_y) <= 1e-9"]
//! budget = 420
//! ```

use anyhow::{Context, Result, bail};

use crate::design::quantity::{Constraint, Quantity};
use crate::scene::free::{Free, blank_table, free_keys};

/// The keys `[optimize]` takes.
const KEYS: [&str; 5] = ["maximize", "minimize", "free", "subject_to", "budget"];

/// Runs per free key when the scene gives no budget: 420 for two keys,
/// the issue's bound for a 41 x 41 grid's best.
pub const RUNS_PER_KEY: usize = 210;

/// The fewest runs a search may be given per free key: a population,
/// a few polls, the neighbourhood and the scans.
pub const MIN_RUNS_PER_KEY: usize = 60;

/// Runs per free key of a front when the scene gives no budget: a front
/// is many optima.
pub const FRONT_RUNS_PER_KEY: usize = 2000;

/// Which way an objective goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sense {
    Maximize,
    Minimize,
}

impl Sense {
    pub fn name(self) -> &'static str {
        match self {
            Sense::Maximize => "maximize",
            Sense::Minimize => "minimize",
        }
    }

    /// The cost a search minimises for value `v`.
    pub fn cost(self, v: f64) -> f64 {
        match self {
            Sense::Maximize => -v,
            Sense::Minimize => v,
        }
    }
}

/// One objective.
#[derive(Clone, Debug, PartialEq)]
pub struct Objective {
    pub sense: Sense,
    pub quantity: Quantity,
}

/// An optimize scene, read and checked against its model's maps.
#[derive(Clone, Debug)]
pub struct OptimizeScene {
    /// The scene's text with `[optimize]` blanked (lines kept).
    pub base_text: String,
    pub free: Vec<Free>,
    /// One objective, or two (maximize first) for a front.
    pub objectives: Vec<Objective>,
    pub constraints: Vec<Constraint>,
    /// Every run the search may make, probes and scans included.
    pub budget: usize,
}

impl OptimizeScene {
    /// The middle of the bounds (geometric on a log scale).
    pub fn middle(&self) -> Vec<f64> {
        crate::scene::free::middle(&self.free)
    }

    /// Whether the scene asks for a front.
    pub fn front(&self) -> bool {
        self.objectives.len() == 2
    }
}

/// Whether a scene's text holds an `[optimize]` table.
pub fn is_optimize_scene(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("optimize"))
}

/// Reads the `[optimize]` table of `text`; `backward` says whether the
/// scene without it writes the backward maps (read with
/// [`backward_of`]).
pub fn read(text: &str) -> Result<OptimizeScene> {
    let table: toml::Table = toml::from_str(text).context("not a valid TOML scene")?;
    let section = table
        .get("optimize")
        .context("no [optimize] table: an optimize scene names its objective and free keys there (docs/design.md)")?
        .as_table()
        .context("`optimize` must be a table ([optimize])")?;
    if let Some(key) = section.keys().find(|k| !KEYS.contains(&k.as_str())) {
        bail!(
            "unknown key `optimize.{key}`: [optimize] takes {} (docs/design.md)",
            KEYS.map(|k| format!("`{k}`")).join(", ")
        );
    }
    let base_text = blank_table(text, "optimize");
    let base: toml::Table = toml::from_str(&base_text).context("the scene without [optimize]")?;
    if base.contains_key("optimize") {
        bail!("write [optimize] as one table (with `free` inside it), not as dotted keys");
    }
    let backward = base
        .get("output")
        .and_then(|o| o.get("backward"))
        .and_then(|b| b.as_bool())
        == Some(true);
    let free = free_keys(section.get("free"), "optimize")?;
    let objectives = objectives(section, backward)?;
    let constraints = match section.get("subject_to") {
        None => Vec::new(),
        Some(v) => {
            let list = v.as_array().context(
                "optimize.subject_to: expected a list of constraints, e.g. [\"backward_ratio_x <= 0.05\"]",
            )?;
            list.iter()
                .map(|c| {
                    let text = c.as_str().with_context(|| {
                        format!("optimize.subject_to: {c} is not a string like \"step_x >= 1e-7\"")
                    })?;
                    Constraint::parse(text, backward)
                })
                .collect::<Result<_>>()?
        }
    };
    let p = free.len();
    let per_key = if objectives.len() == 2 {
        FRONT_RUNS_PER_KEY
    } else {
        RUNS_PER_KEY
    };
    let budget = count(
        section.get("budget"),
        "budget",
        per_key * p,
        MIN_RUNS_PER_KEY * p,
    )?;
    Ok(OptimizeScene {
        base_text,
        free,
        objectives,
        constraints,
        budget,
    })
}

/// `maximize`, `minimize` or both.
fn objectives(section: &toml::Table, backward: bool) -> Result<Vec<Objective>> {
    let mut out = Vec::new();
    for sense in [Sense::Maximize, Sense::Minimize] {
        if let Some(v) = section.get(sense.name()) {
            let text = v.as_str().with_context(|| {
                format!(
                    "optimize.{} = {v}: expected one quantity as a string, e.g. \"step_x\"",
                    sense.name()
                )
            })?;
            let quantity = Quantity::parse(text, backward, &format!("optimize.{}", sense.name()))?;
            out.push(Objective { sense, quantity });
        }
    }
    if let [a, b] = &out[..]
        && a.quantity == b.quantity
    {
        bail!(
            "optimize: maximize and minimize name the same quantity, {}: a front needs two \
             quantities that trade against each other",
            a.quantity.text()
        );
    }
    if out.is_empty() {
        bail!(
            "[optimize] has no objective: give `maximize = \"QUANTITY\"` or `minimize`, or both \
             for a front"
        );
    }
    Ok(out)
}

/// A count key, at least `least`, with its default.
fn count(value: Option<&toml::Value>, key: &str, default: usize, least: usize) -> Result<usize> {
    let Some(value) = value else {
        return Ok(default);
    };
    match value.as_integer() {
        Some(n) if n >= least as i64 && n <= 1 << 24 => Ok(n as usize),
        _ => bail!(
            "optimize.{key} = {value}: expected an integer from {least} to {}",
            1 << 24
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(body: &str, expected: Result<(usize, usize, usize), &str>) {
        let text =
            format!("[axis.y]\nvoltage = 0\n[output]\nbackward = true\n[optimize]\n{body}\n");
        match (read(&text), expected) {
            (Ok(o), Ok((p, objectives, budget))) => {
                assert_eq!(
                    (o.free.len(), o.objectives.len(), o.budget),
                    (p, objectives, budget)
                );
                assert_eq!(o.base_text.lines().count(), text.lines().count());
            }
            (Err(e), Err(part)) => assert!(format!("{e:#}").contains(part), "{e:#}"),
            (got, want) => panic!("got {got:?}, expected {want:?}"),
        }
    }

    #[test]
    fn reads_objectives_and_refuses_bad_ones() {
        let free = "free = { \"axis.x.voltage\" = [50, 150], \"axis.x.frequency\" = [5, 40] }";
        check(
            &format!("maximize = \"velocity_x\"\n{free}"),
            Ok((2, 1, 420)),
        );
        check(
            &format!(
                "maximize = \"step_x\"\nminimize = \"backward_ratio_x\"\n{free}\nbudget = 300"
            ),
            Ok((2, 2, 300)),
        );
        check(
            &format!("maximize = \"step_q\"\n{free}"),
            Err("`step_q` is no quantity"),
        );
        check(free, Err("no objective"));
        check(
            &format!("maximize = \"step_x\"\n{free}\nsubject_to = [\"stepx <= 1\"]"),
            Err("`stepx` is no quantity"),
        );
        check(
            "maximize = \"step_x\"\nfree = { \"axis.x.duty\" = [0.5, 1.5] }",
            Err("outside the key's range"),
        );
        check(
            &format!("maximize = \"step_x\"\n{free}\nbudget = 10"),
            Err("from 120"),
        );
        check(
            &format!("maximize = \"step_x\"\n{free}\nseed = 1"),
            Err("unknown key `optimize.seed`"),
        );
    }
}
