//! The free keys of a search over a scene (`[fit] free`, `[optimize]
//! free`): dotted instance keys with bounds, checked against the key's
//! range, and searched on a log scale where the bounds span a factor of
//! [`LOG_RATIO`]; and the scene's text without the search's table.

use anyhow::{Context, Result, bail};

/// Bounds whose ratio reaches this (both positive) are searched on a log
/// scale: a stiffness known to a factor of 100 is as likely 1e4 as 1e5.
pub const LOG_RATIO: f64 = 100.0;

/// One free key of a search.
#[derive(Clone, Debug, PartialEq)]
pub struct Free {
    /// The dotted scene key, e.g. "mechanism.static_friction".
    pub key: String,
    /// Its bounds, in the key's own units, `lo < hi`.
    pub bounds: [f64; 2],
    /// Searched on a log scale (see [`LOG_RATIO`]).
    pub log: bool,
    /// The key's units ("N", "N/V", ...).
    pub units: &'static str,
}

impl Free {
    /// The key's value at search coordinate `u` (its logarithm on a log
    /// scale).
    pub fn value(&self, u: f64) -> f64 {
        if self.log { u.exp() } else { u }
    }

    /// The search coordinate of `value`.
    pub fn coordinate(&self, value: f64) -> f64 {
        if self.log { value.ln() } else { value }
    }

    /// The key as `pidm check --json` and the reports give it.
    pub fn describe(&self) -> serde_json::Value {
        let scale = if self.log { "log" } else { "linear" };
        serde_json::json!({"key": self.key, "bounds": self.bounds, "units": self.units, "scale": scale})
    }

    /// The bounds in search coordinates.
    pub fn coordinate_bounds(&self) -> [f64; 2] {
        self.bounds.map(|b| self.coordinate(b))
    }
}

/// The middle of each key's bounds (geometric on a log scale).
pub fn middle(free: &[Free]) -> Vec<f64> {
    free.iter()
        .map(|f| {
            let [lo, hi] = f.coordinate_bounds();
            f.value(0.5 * (lo + hi))
        })
        .collect()
}

/// `SECTION.free`: each key with its bounds, in file order.
pub fn free_keys(value: Option<&toml::Value>, section: &str) -> Result<Vec<Free>> {
    let table = value
        .with_context(|| format!("[{section}] has no `free`: the keys to search with their bounds, e.g. free = {{ \"mechanism.static_friction\" = [0.5, 3.0] }}"))?
        .as_table()
        .with_context(|| format!("`{section}.free` must be a table of keys and bounds"))?;
    if table.is_empty() {
        bail!("`{section}.free` is empty: name at least one key");
    }
    let mut free = Vec::new();
    for (key, bounds) in flatten(table, "", &|_| false) {
        free.push(free_key(&key, bounds, section)?);
    }
    Ok(free)
}

/// The keys of a table as dotted paths: a table of keys may be written
/// with quoted dotted keys or as nested tables. A table `leaf` accepts is
/// a value, not a nesting.
pub fn flatten<'a>(
    table: &'a toml::Table,
    prefix: &str,
    leaf: &dyn Fn(&toml::Table) -> bool,
) -> Vec<(String, &'a toml::Value)> {
    let mut out = Vec::new();
    for (key, value) in table {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match value.as_table() {
            Some(inner) if !leaf(inner) => out.extend(flatten(inner, &path, leaf)),
            _ => out.push((path, value)),
        }
    }
    out
}

/// One free key, checked: a real-valued instance key with ordered bounds
/// inside its range.
fn free_key(key: &str, bounds: &toml::Value, section: &str) -> Result<Free> {
    let range = super::instance_key_range(key)
        .map_err(|why| anyhow::anyhow!("{section}.free: `{key}` cannot be searched: {why}"))?;
    let units = range.units;
    if key.starts_with("simulation.") {
        bail!(
            "{section}.free: `{key}` is a setting of the measurement, not a parameter of the model"
        );
    }
    let pair: Option<Vec<f64>> = bounds.as_array().and_then(|a| {
        a.iter()
            .map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
            .collect()
    });
    let [lo, hi] = pair.as_deref().unwrap_or(&[]) else {
        bail!("{section}.free.\"{key}\" = {bounds}: expected two bounds [lower, upper] in {units}");
    };
    let (lo, hi) = (*lo, *hi);
    if !(lo.is_finite() && hi.is_finite()) || lo >= hi {
        bail!(
            "{section}.free.\"{key}\" = [{lo}, {hi}]: expected finite bounds with lower < upper \
             (in {units})"
        );
    }
    if let Some(b) = [lo, hi].into_iter().find(|b| !range.accepts(*b)) {
        bail!(
            "{section}.free.\"{key}\" = [{lo}, {hi}]: the bound {b} is outside the key's range: \
             expected {}",
            range.expected()
        );
    }
    Ok(Free {
        key: key.to_owned(),
        bounds: [lo, hi],
        log: lo > 0.0 && hi / lo >= LOG_RATIO,
        units,
    })
}

/// `text` with every line of its `[TABLE]` table (and any `[TABLE.*]`
/// table) turned blank, so that line numbers stay those of the file.
pub fn blank_table(text: &str, table: &str) -> String {
    let mut inside = false;
    let mut out = String::with_capacity(text.len());
    for line in text.split_inclusive('\n') {
        let trimmed = line.trim_start();
        if trimmed.starts_with('[') {
            let header = trimmed.trim_start_matches('[').trim_start();
            inside = !trimmed.starts_with("[[")
                && header.strip_prefix(table).is_some_and(|rest| {
                    let rest = rest.trim_start();
                    rest.starts_with(']') || rest.starts_with('.')
                });
        }
        if inside {
            out.push_str(if line.ends_with('\n') { "\n" } else { "" });
        } else {
            out.push_str(line);
        }
    }
    out
}

/// A scene error's message without its location (a candidate's scene text
/// is generated, so its lines mean nothing to the user).
pub fn bare_message(e: &super::SceneError) -> String {
    match e {
        super::SceneError::Invalid { message, .. } => message.clone(),
        other => other.to_string(),
    }
}

/// `simulation.replicas = 1` in a steady scene unless the scene sets it
/// (a window has no replicas): how many replicas `auto` runs depends on
/// the idle workers, hence on the batch's size, and a search evaluates one
/// candidate in batches of many sizes; its value must see the candidate,
/// not the batch (ARCHITECTURE.md's determinism).
pub fn pin_replicas(table: &mut toml::Table) {
    let window = table
        .get("simulation")
        .and_then(|s| s.get("measure"))
        .and_then(|m| m.as_str())
        == Some("window");
    if window {
        return;
    }
    let simulation = table
        .entry("simulation")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    if let Some(simulation) = simulation.as_table_mut() {
        simulation
            .entry("replicas")
            .or_insert(toml::Value::Integer(1));
    }
}

/// Sets a dotted key in a TOML table, making the tables on its way.
pub fn set_key(table: &mut toml::Table, key: &str, value: f64) {
    let mut parts: Vec<&str> = key.split('.').collect();
    let last = parts.pop().expect("a key has a name");
    let mut here = table;
    for part in parts {
        let entry = here
            .entry(part)
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        here = entry.as_table_mut().expect("scene keys nest in tables");
    }
    here.insert(last.into(), toml::Value::Float(value));
}
