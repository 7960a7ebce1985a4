//! The `[fit]` table of a fit scene (docs/fit.md): the data file and the
//! free keys with their bounds, read from the scene's text, and the scene
//! without it, which every candidate of the fit starts from.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

pub use crate::scene::free::{Free, LOG_RATIO};
use crate::scene::free::{blank_table, free_keys};

/// Which standard errors a fit reports (`fit.errors`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Errors {
    /// The data's standard errors are taken as given (SciPy's
    /// `absolute_sigma=True`): the default.
    #[default]
    Given,
    /// Scaled by sqrt(reduced chi2) (lmfit's `scale_covar`): for data whose
    /// standard errors are known only up to a common factor.
    Scaled,
}

impl Errors {
    /// The value of `fit.errors`.
    pub fn name(self) -> &'static str {
        match self {
            Errors::Given => "given",
            Errors::Scaled => "scaled",
        }
    }
}

/// A fit scene split in two: its `[fit]` table and the scene without it.
#[derive(Clone, Debug)]
pub struct FitScene {
    /// The scene's text with the `[fit]` table blanked (lines kept, so a
    /// scene error still names the line of the file).
    pub base_text: String,
    /// The data file, resolved against the scene file's folder (empty when
    /// `[fit]` names none: `pidm fit --data` must).
    pub data: PathBuf,
    /// The free keys, in file order.
    pub free: Vec<Free>,
    /// Which standard errors are reported.
    pub errors: Errors,
}

/// Whether a scene's text holds a `[fit]` table (the way `pidm check`
/// tells a fit scene).
pub fn is_fit_scene(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("fit"))
}

/// Reads the `[fit]` table of `text`, the scene at `path`.
pub fn read(text: &str, path: &Path) -> Result<FitScene> {
    let table: toml::Table = toml::from_str(text)
        .with_context(|| format!("{}: not a valid TOML scene", path.display()))?;
    let Some(fit) = table.get("fit") else {
        bail!(
            "{}: no [fit] table: a fit scene names its data and free keys there (docs/fit.md)",
            path.display()
        );
    };
    let fit = fit.as_table().context("`fit` must be a table ([fit])")?;
    for key in fit.keys() {
        if !["data", "free", "errors"].contains(&key.as_str()) {
            bail!("unknown key `fit.{key}`: [fit] takes `data`, `free` and `errors` (docs/fit.md)");
        }
    }
    let data = match fit.get("data") {
        Some(data) => data
            .as_str()
            .context("`fit.data` must be a string: the CSV file's path, relative to the scene")?,
        None => "",
    };
    let folder = path.parent().unwrap_or(Path::new("."));
    let free = free_keys(fit.get("free"), "fit")?;
    let base_text = blank_table(text, "fit");
    let rest: toml::Table = toml::from_str(&base_text).context("the scene without [fit]")?;
    if rest.contains_key("fit") {
        bail!("write the fit as one [fit] table (with `free` inside it), not as dotted keys");
    }
    Ok(FitScene {
        base_text,
        data: if data.is_empty() {
            PathBuf::new()
        } else {
            folder.join(data)
        },
        free,
        errors: errors(fit.get("errors"))?,
    })
}

/// `fit.errors`: "given" (the default) or "scaled".
fn errors(value: Option<&toml::Value>) -> Result<Errors> {
    let Some(value) = value else {
        return Ok(Errors::Given);
    };
    let expected = "expected \"given\" (the data's standard errors as they are, the default) or \
                    \"scaled\" (scaled by sqrt(reduced chi2))";
    match value.as_str() {
        Some("given") => Ok(Errors::Given),
        Some("scaled") => Ok(Errors::Scaled),
        _ => bail!("fit.errors = {value}: {expected}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Expected<'a> = Result<Vec<(&'a str, [f64; 2], bool)>, &'a str>;

    fn check(text: &str, expected: Expected) {
        let got = read(text, Path::new("/s/scene.toml"));
        match (got, expected) {
            (Ok(fit), Ok(free)) => {
                let got: Vec<_> = fit
                    .free
                    .iter()
                    .map(|f| (f.key.as_str(), f.bounds, f.log))
                    .collect();
                assert_eq!(got, free);
                assert_eq!(fit.data, Path::new("/s/steps.csv"));
                assert!(!fit.base_text.contains("fit"), "{}", fit.base_text);
                assert_eq!(fit.base_text.lines().count(), text.lines().count());
            }
            (Err(e), Err(part)) => assert!(format!("{e:#}").contains(part), "{e:#}"),
            (got, expected) => panic!("got {got:?}, expected {expected:?}"),
        }
    }

    #[test]
    fn reads_free_keys_and_refuses_bad_ones() {
        let fit = |free: &str| {
            format!(
                "[mechanism]\nslider_mass = 5e-3\n[fit]\ndata = \"steps.csv\"\nfree = {{ {free} }}\n[axis.x]\ngain = -0.6\n"
            )
        };
        check(
            &fit("\"mechanism.static_friction\" = [0.5, 3.0], \"axis.x.gain\" = [-1.0, -0.2]"),
            Ok(vec![
                ("mechanism.static_friction", [0.5, 3.0], false),
                ("axis.x.gain", [-1.0, -0.2], false),
            ]),
        );
        check(
            &fit("\"mechanism.bristle_stiffness\" = [1e4, 1e7]"),
            Ok(vec![("mechanism.bristle_stiffness", [1e4, 1e7], true)]),
        );
        check(
            &fit("mechanism = { coulomb_friction = [1, 2] }"),
            Ok(vec![("mechanism.coulomb_friction", [1.0, 2.0], false)]),
        );
        check(
            &fit("\"mechanism.static_friction\" = [3.0, 0.5]"),
            Err("lower < upper"),
        );
        check(
            &fit("\"mechanism.static_frictoin\" = [0.5, 3.0]"),
            Err("`mechanism.static_frictoin` cannot be searched"),
        );
        check(&fit("\"simulation.cycles\" = [1, 3]"), Err("integer"));
        check(
            &fit("\"simulation.tolerance\" = [1e-9, 1e-6]"),
            Err("whole scene"),
        );
        check(
            &fit("\"mechanism.friction\" = [1, 3]"),
            Err("no numeric scene key"),
        );
        check(&fit("\"axis.x.gain\" = -0.5"), Err("two bounds"));
        check(
            "[fit]\ndata = \"steps.csv\"\nseed = 3\n",
            Err("unknown key `fit.seed`"),
        );
    }
}
