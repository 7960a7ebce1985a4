//! The `[sensitivity]` table (docs/design.md): the base sample size, the
//! quantities to analyse and a distribution per input key.
//!
//! ```toml
//! [sensitivity]
//! samples = 256
//! outputs = ["step_x", "backward_ratio_x"]
//! [sensitivity.inputs]
//! "mechanism.static_friction" = { uniform = [1.08, 1.32] }
//! "axis.x.stiffness" = { normal = { mean = 1.4e5, sd = 7e3 } }
//! "mechanism.slider_mass" = { lognormal = { median = 5e-3, factor = 1.05 } }
//! ```

use anyhow::{Context, Result, bail};

use crate::design::quantity::Quantity;
use crate::scene::KeyRange;
use crate::scene::free::{blank_table, flatten};
use crate::search::distributions::Distribution;

/// The fewest and most base samples: Saltelli's estimators need two rows,
/// and 2^20 rows of k + 2 runs each is already millions of runs.
pub const SAMPLES: [usize; 2] = [2, 1 << 20];

/// The keys `[sensitivity]` takes.
const KEYS: [&str; 3] = ["samples", "outputs", "inputs"];

/// One input: a key and how it varies across units.
#[derive(Clone, Debug, PartialEq)]
pub struct Input {
    pub key: String,
    pub distribution: Distribution,
    /// The key's valid values, which the distribution is truncated to.
    pub range: KeyRange,
}

impl Input {
    /// The share of the distribution its truncation cuts off.
    pub fn cut(&self) -> f64 {
        self.distribution.cut((self.range.low, self.range.high))
    }

    /// The key's value at unit-cube coordinate `u`.
    pub fn value(&self, u: f64) -> f64 {
        self.distribution
            .value(u, (self.range.low, self.range.high))
    }

    /// The distribution as the scene wrote it, for the reports.
    pub fn describe(&self) -> serde_json::Value {
        match self.distribution {
            Distribution::Uniform { low, high } => serde_json::json!({"uniform": [low, high]}),
            Distribution::Normal { mean, sd } => {
                serde_json::json!({"normal": {"mean": mean, "sd": sd}})
            }
            Distribution::LogNormal { median, factor } => {
                serde_json::json!({"lognormal": {"median": median, "factor": factor}})
            }
        }
    }
}

/// A sensitivity scene split in two.
#[derive(Clone, Debug)]
pub struct SensitivityScene {
    /// The scene's text with `[sensitivity]` blanked (lines kept).
    pub base_text: String,
    pub samples: usize,
    /// The outputs as written, read against the scene's maps by
    /// [`SensitivityScene::outputs`].
    pub outputs: Vec<String>,
    pub inputs: Vec<Input>,
}

impl SensitivityScene {
    /// The outputs as quantities; `backward` says whether the scene writes
    /// the backward maps.
    pub fn outputs(&self, backward: bool) -> Result<Vec<Quantity>> {
        self.outputs
            .iter()
            .map(|o| Quantity::parse(o, backward, "sensitivity.outputs"))
            .collect()
    }

    /// The inputs' middle values (each distribution's median), which the
    /// scene must accept.
    pub fn middle(&self) -> Vec<f64> {
        self.inputs.iter().map(|i| i.value(0.5)).collect()
    }
}

/// Whether a scene's text holds a `[sensitivity]` table.
pub fn is_sensitivity_scene(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("sensitivity"))
}

/// Reads the `[sensitivity]` table of `text`.
pub fn read(text: &str) -> Result<SensitivityScene> {
    let table: toml::Table = toml::from_str(text).context("not a valid TOML scene")?;
    let Some(section) = table.get("sensitivity") else {
        bail!(
            "no [sensitivity] table: a sensitivity scene names its inputs and outputs there (docs/design.md)"
        );
    };
    let section = section
        .as_table()
        .context("`sensitivity` must be a table ([sensitivity])")?;
    if let Some(key) = section.keys().find(|k| !KEYS.contains(&k.as_str())) {
        bail!(
            "unknown key `sensitivity.{key}`: [sensitivity] takes `samples`, `outputs` and \
             `inputs` (docs/design.md)"
        );
    }
    let base_text = blank_table(text, "sensitivity");
    if toml::from_str::<toml::Table>(&base_text)
        .context("the scene without [sensitivity]")?
        .contains_key("sensitivity")
    {
        bail!("write [sensitivity] as one table (with `inputs` inside it), not as dotted keys");
    }
    Ok(SensitivityScene {
        base_text,
        samples: samples(section.get("samples"))?,
        outputs: outputs(section.get("outputs"))?,
        inputs: inputs(section.get("inputs"))?,
    })
}

fn samples(value: Option<&toml::Value>) -> Result<usize> {
    let value = value.context(
        "[sensitivity] has no `samples`: the base sample size N (the study runs N (k + 2) \
         instances for k inputs)",
    )?;
    match value.as_integer() {
        Some(n) if (SAMPLES[0] as i64..=SAMPLES[1] as i64).contains(&n) => Ok(n as usize),
        _ => bail!(
            "sensitivity.samples = {value}: expected an integer from {} to {} (2^20)",
            SAMPLES[0],
            SAMPLES[1]
        ),
    }
}

fn outputs(value: Option<&toml::Value>) -> Result<Vec<String>> {
    let expected =
        "expected a list of quantities, e.g. outputs = [\"step_x\", \"backward_ratio_x\"]";
    let list = value
        .with_context(|| format!("[sensitivity] has no `outputs`: {expected}"))?
        .as_array()
        .with_context(|| format!("sensitivity.outputs: {expected}"))?;
    if list.is_empty() {
        bail!("sensitivity.outputs is empty: {expected}");
    }
    let mut out: Vec<String> = Vec::new();
    for v in list {
        let Some(s) = v.as_str() else {
            bail!("sensitivity.outputs: {v} is not a string: {expected}");
        };
        if out.iter().any(|o| o == s) {
            bail!("sensitivity.outputs lists \"{s}\" twice");
        }
        out.push(s.to_owned());
    }
    Ok(out)
}

const DISTRIBUTIONS: [&str; 3] = ["uniform", "normal", "lognormal"];

fn inputs(value: Option<&toml::Value>) -> Result<Vec<Input>> {
    let table = value
        .context(
            "[sensitivity] has no `inputs`: a distribution per key, e.g. \
             inputs = { \"mechanism.static_friction\" = { uniform = [1.08, 1.32] } }",
        )?
        .as_table()
        .context("`sensitivity.inputs` must be a table of keys and distributions")?;
    // A distribution's table names one (or holds a value that is no table,
    // `beta = [1, 3]`): a table of tables is a nesting of keys.
    let leaf = |t: &toml::Table| {
        t.iter()
            .any(|(k, v)| DISTRIBUTIONS.contains(&k.as_str()) || !v.is_table())
    };
    let inputs: Vec<Input> = flatten(table, "", &leaf)
        .into_iter()
        .map(|(key, value)| input(&key, value))
        .collect::<Result<_>>()?;
    if inputs.is_empty() {
        bail!("`sensitivity.inputs` is empty: give at least one key a distribution");
    }
    Ok(inputs)
}

/// One input, checked: an instance key with a distribution whose range
/// meets the key's.
fn input(key: &str, value: &toml::Value) -> Result<Input> {
    let at = format!("sensitivity.inputs.\"{key}\"");
    let range = crate::scene::instance_key_range(key)
        .map_err(|why| anyhow::anyhow!("{at}: `{key}` cannot take a distribution: {why}"))?;
    if key.starts_with("simulation.") {
        bail!("{at}: `{key}` is a setting of the measurement, not a parameter of the model");
    }
    let expected = "expected one of uniform = [low, high], normal = { mean, sd } or \
                    lognormal = { median, factor }";
    let table = value
        .as_table()
        .filter(|t| t.len() == 1)
        .with_context(|| format!("{at} = {value}: {expected}"))?;
    let (name, params) = table.iter().next().expect("one entry");
    let number = |v: Option<&toml::Value>| -> Option<f64> {
        v.and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
    };
    let field = |name: &str| number(params.get(name));
    let distribution = match name.as_str() {
        "uniform" => match params.as_array().map(|a| a.as_slice()) {
            Some([lo, hi]) => match (number(Some(lo)), number(Some(hi))) {
                (Some(low), Some(high)) => Distribution::Uniform { low, high },
                _ => bail!(
                    "{at}: uniform = {params}: expected [low, high] in {}",
                    range.units
                ),
            },
            _ => bail!(
                "{at}: uniform = {params}: expected [low, high] in {}",
                range.units
            ),
        },
        "normal" => match (
            field("mean"),
            field("sd"),
            params.as_table().map(|t| t.len()),
        ) {
            (Some(mean), Some(sd), Some(2)) => Distribution::Normal { mean, sd },
            _ => bail!(
                "{at}: normal = {params}: expected {{ mean, sd }} in {}",
                range.units
            ),
        },
        "lognormal" => match (
            field("median"),
            field("factor"),
            params.as_table().map(|t| t.len()),
        ) {
            (Some(median), Some(factor), Some(2)) => Distribution::LogNormal { median, factor },
            _ => bail!(
                "{at}: lognormal = {params}: expected {{ median, factor }} (the median in {}, \
                 the factor the geometric SD, above 1)",
                range.units
            ),
        },
        other => bail!("{at}: `{other}` is no distribution: {expected}"),
    };
    distribution.check().with_context(|| at.clone())?;
    let input = Input {
        key: key.to_owned(),
        distribution,
        range,
    };
    if let Distribution::Uniform { low, high } = distribution
        && let Some(b) = [low, high].into_iter().find(|b| !range.accepts(*b))
    {
        bail!(
            "{at}: uniform = [{low}, {high}]: {b} is outside the key's range: expected {}",
            range.expected()
        );
    }
    if input.cut() >= 1.0 - 1e-12 {
        bail!(
            "{at}: the distribution lies outside the key's range ({}): nothing is left to \
             sample once truncated",
            range.expected()
        );
    }
    Ok(input)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(inputs: &str, extra: &str, expected: Result<usize, &str>) {
        let text = format!(
            "[sensitivity]\nsamples = 8\noutputs = [\"step_x\"]\n{extra}\ninputs = {{ {inputs} }}\n[axis.y]\nvoltage = 0\n"
        );
        match (read(&text), expected) {
            (Ok(s), Ok(k)) => {
                assert_eq!(s.inputs.len(), k);
                assert!(!s.base_text.contains("sensitivity"));
                assert_eq!(s.base_text.lines().count(), text.lines().count());
            }
            (Err(e), Err(part)) => assert!(format!("{e:#}").contains(part), "{e:#}"),
            (got, want) => panic!("got {got:?}, expected {want:?}"),
        }
    }

    #[test]
    fn reads_inputs_and_refuses_bad_ones() {
        check(
            "\"mechanism.static_friction\" = { uniform = [1.0, 1.4] }, \
             \"axis.x.duty\" = { normal = { mean = 0.95, sd = 0.01 } }, \
             mechanism = { slider_mass = { lognormal = { median = 5e-3, factor = 1.1 } } }",
            "",
            Ok(3),
        );
        check(
            "\"axis.x.duty\" = { uniform = [0.5, 1.2] }",
            "",
            Err("outside the key's range"),
        );
        check(
            "\"simulation.cycles\" = { uniform = [1, 3] }",
            "",
            Err("cannot take a distribution"),
        );
        check(
            "\"mechanism.friction\" = { uniform = [1, 3] }",
            "",
            Err("cannot take a distribution"),
        );
        check(
            "\"axis.x.gain\" = { beta = [1, 3] }",
            "",
            Err("`beta` is no distribution"),
        );
        check(
            "\"axis.x.gain\" = { normal = { mean = 1 } }",
            "",
            Err("expected { mean, sd }"),
        );
        check(
            "\"axis.x.gain\" = { normal = { mean = 1, sd = -1 } }",
            "",
            Err("sd above 0"),
        );
        check(
            "\"axis.x.gain\" = { uniform = [1, 1] }",
            "",
            Err("low < high"),
        );
        check("", "", Err("is empty"));
        check(
            "\"axis.x.gain\" = { uniform = [1, 2] }",
            "seed = 3",
            Err("unknown key `sensitivity.seed`"),
        );
        let bad = |samples: &str| {
            read(&format!("[sensitivity]\nsamples = {samples}\noutputs = [\"step_x\"]\ninputs = {{ \"axis.x.gain\" = {{ uniform = [-1, -0.5] }} }}\n"))
                .unwrap_err()
                .to_string()
        };
        assert!(bad("1").contains("from 2 to 1048576"));
        assert!(bad("1048577").contains("from 2 to 1048576"));
        assert!(bad("2.5").contains("expected an integer"));
    }
}
