//! The mirror tests' tooling, for every law's shader: the functions a WGSL
//! or Rust text defines, and the check that a WGSL file and its Rust file
//! define the same ones (vello's rule: every stage has a same-named CPU
//! mirror).

/// Function names defined in a source text (`fn name(` at any
/// indentation), leaving out a Rust file's test module, its traits, its
/// trait impls and its macros (the floor's `Gauge` and `Slider` and a
/// law's accessors for them, which in WGSL are struct members read by
/// name).
pub(crate) fn defined_functions(text: &str) -> Vec<String> {
    let text = text.split("#[cfg(test)]").next().unwrap_or(text);
    let mut names = Vec::new();
    let mut in_trait = false;
    for line in text.lines() {
        let is_trait = line.starts_with("pub trait ")
            || line.starts_with("trait ")
            || line.starts_with("macro_rules! ")
            || (line.starts_with("impl") && line.contains(" for "));
        let is_trait = is_trait && !line.trim_end().ends_with("{}");
        in_trait = (in_trait || is_trait) && line != "}";
        if in_trait {
            continue;
        }
        let line = line.trim_start();
        let rest = ["pub(crate) fn ", "pub(super) fn ", "pub fn ", "fn "]
            .iter()
            .find_map(|prefix| line.strip_prefix(prefix));
        if let Some(rest) = rest {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            names.push(name);
        }
    }
    names
}

/// A WGSL file's functions (`wgsl`) each in its Rust mirror (`cpu`) or
/// listed as shader-only, and each Rust function among `found` (the
/// file's, with those the shader defines elsewhere for it) or listed as
/// CPU-only: both laws' mirror tests.
pub(crate) fn assert_mirrors(
    wgsl_name: &str,
    wgsl: &[String],
    found: &[String],
    cpu: &[String],
    (shader_only, cpu_only): (&[&str], &[&str]),
) {
    for f in wgsl {
        assert!(
            cpu.contains(f) || shader_only.contains(&f.as_str()),
            "{wgsl_name} defines {f}, its Rust mirror does not"
        );
    }
    for f in cpu {
        assert!(
            found.contains(f) || cpu_only.contains(&f.as_str()),
            "the Rust mirror of {wgsl_name} defines {f}, the shader does not"
        );
    }
}
