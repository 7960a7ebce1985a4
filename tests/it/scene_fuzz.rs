//! Property test of the scene parser: random texts, token soups and mutated
//! shipped scenes (`sweeps/*.toml`) are either refused with an error or
//! accepted as a scene whose instances are finite; never a panic.
//!
//! Each property runs [`CASES`] cases, a fraction of a second in release.
//! `PROPTEST_CASES` runs more, and `PROPTEST_RNG_SEED` replays a seed.

use std::path::PathBuf;
use std::sync::OnceLock;

use proptest::prelude::*;
use proptest::test_runner::Config;

use pidm::model::Instance;
use pidm::scene::Scene;

/// Cases per property: enough to reach every mutation kind on every
/// shipped scene many times, while the whole file runs in well under a
/// second in release.
const CASES: u32 = 256;

/// Values swapped in for a number or for a whole value: extremes of f64 and
/// of TOML integers, non-finite and signed zeros, other types, empty and
/// nested arrays and tables, and ranges at the edges of what is accepted.
const EXTREMES: &[&str] = &[
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "5e-324",
    "1e-320",
    "-0",
    "-0.0",
    "+0.0",
    "0",
    "1",
    "2",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999999999999999999999999",
    "0x7fffffffffffffff",
    "0o777",
    "0b101",
    "214748365",
    "4294967295",
    "4294967296",
    "[]",
    "[[]]",
    "[1, [2, [3]]]",
    "[nan, 1e308]",
    "{}",
    "{ a = { b = { c = 1 } } }",
    "{ from = 0, to = 1e308, steps = 3 }",
    "{ from = 0, to = 10, steps = 1 }",
    "{ from = -1, to = 1, steps = 3, log = true }",
    "{ from = 1e-300, to = 1e300, steps = 5, log = true }",
    "{ from = 0, to = 1, steps = 9223372036854775807 }",
    "{ from = 0, to = 1, steps = -1 }",
    "\"text\"",
    "\"\"",
    "\"../../escaped\"",
    "true",
    "1979-05-27T07:32:00Z",
];

/// Pieces of scene text for the token soup: table headers, keys, values and
/// punctuation, so that random sequences often parse as TOML.
const TOKENS: &[&str] = &[
    "\n",
    " ",
    "=",
    ",",
    ".",
    "[",
    "]",
    "{",
    "}",
    "\"",
    "#",
    "[axis.x]\n",
    "[axis.y]\n",
    "[mechanism]\n",
    "[simulation]\n",
    "[output]\n",
    "[[points]]\n",
    "name",
    "label",
    "voltage",
    "frequency",
    "duty",
    "phase",
    "stiffness",
    "stage_mass",
    "resonance_hz",
    "quality_factor",
    "damping",
    "slider_mass",
    "velocity_band",
    "cycles",
    "settle",
    "tolerance",
    "measure",
    "\"window\"",
    "\"steady\"",
    "step_tolerance",
    "max_cycles",
    "baselines",
    "trajectories",
    "trajectory_samples_per_cycle",
    "axis.x.voltage",
    "from",
    "to",
    "steps",
    "log",
    "true",
    "\"a\"",
    "0",
    "1",
    "3",
    "-0",
    "1e308",
    "nan",
    "1e-9",
    "100.0",
];

/// The shipped scenes' texts.
fn shipped() -> &'static [String] {
    static TEXTS: OnceLock<Vec<String>> = OnceLock::new();
    TEXTS.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("sweeps");
        let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|entry| entry.unwrap().path())
            .filter(|path| path.extension().is_some_and(|e| e == "toml"))
            .collect();
        paths.sort();
        assert!(!paths.is_empty(), "no scenes in {}", dir.display());
        paths
            .iter()
            .map(|path| std::fs::read_to_string(path).unwrap())
            .collect()
    })
}

/// One edit of a scene text. Each position is taken modulo the number of
/// places it can be (bytes, numbers or `=` signs).
#[derive(Clone, Debug)]
enum Mutation {
    /// Deletes up to `len` bytes at a position.
    Delete(usize, usize),
    /// Repeats up to `len` bytes at a position in place.
    Duplicate(usize, usize),
    /// Replaces the byte at a position.
    Replace(usize, u8),
    /// Inserts a piece of scene text at a position.
    Insert(usize, &'static str),
    /// Replaces one number-like token with an extreme value.
    Number(usize, &'static str),
    /// Replaces what follows one `=` on its line with an extreme value.
    Value(usize, &'static str),
}

/// Any mutation.
fn mutation() -> impl Strategy<Value = Mutation> {
    let extreme = || proptest::sample::select(EXTREMES);
    prop_oneof![
        (any::<usize>(), 1..64usize).prop_map(|(at, len)| Mutation::Delete(at, len)),
        (any::<usize>(), 1..64usize).prop_map(|(at, len)| Mutation::Duplicate(at, len)),
        (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Mutation::Replace(at, byte)),
        (any::<usize>(), proptest::sample::select(TOKENS))
            .prop_map(|(at, token)| Mutation::Insert(at, token)),
        (any::<usize>(), extreme()).prop_map(|(at, value)| Mutation::Number(at, value)),
        (any::<usize>(), extreme()).prop_map(|(at, value)| Mutation::Value(at, value)),
    ]
}

/// Applies a mutation to a scene's bytes.
fn apply(bytes: &mut Vec<u8>, mutation: &Mutation) {
    let len = bytes.len();
    match *mutation {
        Mutation::Delete(at, n) if len > 0 => {
            let start = at % len;
            bytes.drain(start..(start + n).min(len));
        }
        Mutation::Duplicate(at, n) if len > 0 => {
            let start = at % len;
            let piece = bytes[start..(start + n).min(len)].to_vec();
            bytes.splice(start..start, piece);
        }
        Mutation::Replace(at, byte) if len > 0 => bytes[at % len] = byte,
        Mutation::Insert(at, text) => {
            let start = at % (len + 1);
            bytes.splice(start..start, text.bytes());
        }
        Mutation::Number(at, value) => {
            let numbers = number_tokens(bytes);
            if !numbers.is_empty() {
                let (start, end) = numbers[at % numbers.len()];
                bytes.splice(start..end, value.bytes());
            }
        }
        Mutation::Value(at, value) => {
            let equals: Vec<usize> = (0..len).filter(|&i| bytes[i] == b'=').collect();
            if !equals.is_empty() {
                let start = equals[at % equals.len()] + 1;
                let end = bytes[start..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(len, |i| start + i);
                let replacement = format!(" {value}");
                bytes.splice(start..end, replacement.bytes());
            }
        }
        _ => {}
    }
}

/// The byte ranges of number-like tokens: a digit, sign or dot run that
/// starts with a digit or a sign followed by a digit.
fn number_tokens(bytes: &[u8]) -> Vec<(usize, usize)> {
    let part = |b: u8| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'-' | b'+' | b'_');
    let mut tokens = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = (i == 0 || !part(bytes[i - 1]))
            && (bytes[i].is_ascii_digit()
                || (matches!(bytes[i], b'-' | b'+')
                    && bytes.get(i + 1).is_some_and(u8::is_ascii_digit)));
        if starts {
            let end = (i + 1..bytes.len())
                .find(|&j| !part(bytes[j]))
                .unwrap_or(bytes.len());
            tokens.push((i, end));
            i = end;
        } else {
            i += 1;
        }
    }
    tokens
}

/// Every parameter of an instance, for the finiteness check.
fn parameters(instance: &Instance) -> Vec<f64> {
    let mut values: Vec<f64> = instance
        .mechanism
        .parameters()
        .iter()
        .map(|&(_, v)| v)
        .collect();
    for axis in &instance.axes {
        values.extend(axis.parameters().iter().map(|&(_, v)| v));
    }
    values
}

/// Parses `text`: an error must have a message; an accepted scene must give
/// finite instances at both ends and describe itself. A panic anywhere
/// fails the property.
fn parse_never_panics(text: &str) -> Result<(), TestCaseError> {
    match Scene::from_toml(text, Some("fuzz")) {
        Err(error) => prop_assert!(!error.to_string().is_empty()),
        Ok(scene) => {
            let count = scene.instance_count();
            prop_assert!(count >= 1);
            for index in [0, count - 1] {
                let instance = scene.instance(index);
                for value in parameters(&instance) {
                    prop_assert!(value.is_finite(), "instance {index}: {instance:?}");
                }
                prop_assert!(instance.settle < instance.cycles);
            }
            prop_assert!(!scene.describe().is_empty());
        }
    }
    Ok(())
}

/// The runner's configuration: [`CASES`] cases (or `PROPTEST_CASES`), and
/// no regression files written into the source tree.
fn config() -> Config {
    Config {
        cases: CASES,
        failure_persistence: None,
        ..Config::default()
    }
}

proptest! {
    #![proptest_config(config())]

    /// Shipped scenes with a few random edits each.
    #[test]
    fn mutated_shipped_scenes_never_panic(
        which in any::<usize>(),
        mutations in proptest::collection::vec(mutation(), 1..6),
    ) {
        let texts = shipped();
        let mut bytes = texts[which % texts.len()].clone().into_bytes();
        for mutation in &mutations {
            apply(&mut bytes, mutation);
        }
        parse_never_panics(&String::from_utf8_lossy(&bytes))?;
    }

    /// Random sequences of scene tokens.
    #[test]
    fn token_soup_never_panics(
        tokens in proptest::collection::vec(proptest::sample::select(TOKENS), 0..80),
    ) {
        parse_never_panics(&tokens.concat())?;
    }

    /// Random text.
    #[test]
    fn random_text_never_panics(chars in proptest::collection::vec(any::<char>(), 0..200)) {
        parse_never_panics(&chars.into_iter().collect::<String>())?;
    }
}

/// The mutations do reach the parser's checks: each kind of edit applied to
/// a shipped scene gives the text expected, so a property that passes has
/// really parsed edited scenes.
#[test]
fn mutations_edit_as_intended() {
    let first = 0;
    let cases: Vec<(&str, Mutation, &str)> = vec![
        ("a = 1", Mutation::Delete(first, 2), "= 1"),
        ("ab", Mutation::Duplicate(first, 1), "aab"),
        ("ab", Mutation::Replace(first, b'x'), "xb"),
        ("ab", Mutation::Insert(first, "[["), "[[ab"),
        (
            "x = [1, -2.5e3]",
            Mutation::Number(first, "nan"),
            "x = [nan, -2.5e3]",
        ),
        (
            "x = 1 # c\ny = 2",
            Mutation::Value(first, "{}"),
            "x = {}\ny = 2",
        ),
    ];
    for (text, mutation, expected) in cases {
        let mut bytes = text.as_bytes().to_vec();
        apply(&mut bytes, &mutation);
        assert_eq!(String::from_utf8(bytes).unwrap(), expected, "{mutation:?}");
    }
    assert_eq!(
        number_tokens(b"a1 = 10, b = -2.5e3, c = x9"),
        [(5, 7), (13, 19)]
    );
}
