//! What a design command measures (issue 61): a per-instance map the
//! scene produces (`step_x`, `velocity_y`, `backward_ratio_x`, ...), or
//! `abs(...)` and `hypot(a, b)` of such, each with its standard error by
//! the delta method; and the constraints `subject_to` states between them
//! and numbers.

use anyhow::{Result, bail};

use crate::model::AXES;
use crate::sweep::Record;

const AXIS_NAMES: [&str; AXES] = ["x", "y"];

/// A map of `/maps` one instance has a value in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Map {
    /// The step per own drive cycle [m].
    Step(usize),
    /// The mean slider velocity [m/s].
    Velocity(usize),
    /// The backward travel per own drive cycle [m] (`[output] backward`).
    Backward(usize),
    /// backward / (|step| + backward) [1] (`[output] backward`).
    BackwardRatio(usize),
}

impl Map {
    /// Every map, in the order an error lists them.
    const ALL: [fn(usize) -> Map; 4] =
        [Map::Step, Map::Velocity, Map::Backward, Map::BackwardRatio];

    /// The dataset's name under `/maps`.
    pub fn name(self) -> String {
        let (stem, a) = match self {
            Map::Step(a) => ("step", a),
            Map::Velocity(a) => ("velocity", a),
            Map::Backward(a) => ("backward", a),
            Map::BackwardRatio(a) => ("backward_ratio", a),
        };
        format!("{stem}_{}", AXIS_NAMES[a])
    }

    /// Its units.
    pub fn units(self) -> &'static str {
        match self {
            Map::Step(_) | Map::Backward(_) => "m",
            Map::Velocity(_) => "m/s",
            Map::BackwardRatio(_) => "1",
        }
    }

    /// Whether only a scene with `[output] backward = true` has it.
    pub fn needs_backward(self) -> bool {
        matches!(self, Map::Backward(_) | Map::BackwardRatio(_))
    }

    fn from_name(name: &str) -> Option<Map> {
        Map::ALL
            .iter()
            .flat_map(|make| (0..AXES).map(make))
            .find(|m| m.name() == name)
    }

    /// The names of every map, for errors.
    pub fn names() -> Vec<String> {
        Map::ALL
            .iter()
            .flat_map(|make| (0..AXES).map(move |a| make(a).name()))
            .collect()
    }

    /// The value and its standard error in `record`; `frequency` is each
    /// axis' own drive frequency [Hz] (a velocity is the step times it).
    fn value(self, record: &Record, frequency: [f64; AXES]) -> (f64, f64) {
        let b = &record.backward;
        match self {
            Map::Step(a) => (record.step[a], record.step_se[a]),
            Map::Velocity(a) => (record.velocity[a], record.step_se[a] * frequency[a]),
            Map::Backward(a) => (b.travel[a], b.travel_se[a]),
            Map::BackwardRatio(a) => (b.ratio[a], b.ratio_se[a]),
        }
    }
}

/// A quantity: a map, or `abs` and `hypot` of quantities.
#[derive(Clone, Debug, PartialEq)]
pub enum Quantity {
    Map(Map),
    Abs(Box<Quantity>),
    Hypot(Box<Quantity>, Box<Quantity>),
}

/// What a quantity is worth at one instance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Value {
    pub value: f64,
    /// Its standard error (0 where the measurement has none: a window, a
    /// periodic motion).
    pub se: f64,
}

impl Quantity {
    /// Reads `text` (`step_x`, `abs(step_y)`, `hypot(velocity_x,
    /// velocity_y)`); `backward` says whether the scene writes the
    /// backward maps, `what` names the key for errors.
    pub fn parse(text: &str, backward: bool, what: &str) -> Result<Quantity> {
        let mut p = Parser {
            text,
            at: 0,
            what,
            backward,
        };
        let q = p.quantity()?;
        p.skip_space();
        if p.at != text.len() {
            bail!(
                "{what} = \"{text}\": unexpected `{}` after the quantity",
                &text[p.at..]
            );
        }
        Ok(q)
    }

    /// Its value and standard error in `record` (delta method: |q| keeps
    /// q's error; hypot(a, b) = h has error sqrt((a sa)^2 + (b sb)^2) / h,
    /// and sqrt(sa^2 + sb^2) at h = 0, where the derivative is undefined
    /// and that bound is what is known).
    pub fn value(&self, record: &Record, frequency: [f64; AXES]) -> Value {
        match self {
            Quantity::Map(m) => {
                let (value, se) = m.value(record, frequency);
                Value { value, se }
            }
            Quantity::Abs(q) => {
                let v = q.value(record, frequency);
                Value {
                    value: v.value.abs(),
                    se: v.se,
                }
            }
            Quantity::Hypot(a, b) => {
                let (a, b) = (a.value(record, frequency), b.value(record, frequency));
                let h = a.value.hypot(b.value);
                let se = if h > 0.0 {
                    (a.value * a.se).hypot(b.value * b.se) / h
                } else {
                    a.se.hypot(b.se)
                };
                Value { value: h, se }
            }
        }
    }

    /// The quantity as written back (canonical spacing).
    pub fn text(&self) -> String {
        match self {
            Quantity::Map(m) => m.name(),
            Quantity::Abs(q) => format!("abs({})", q.text()),
            Quantity::Hypot(a, b) => format!("hypot({}, {})", a.text(), b.text()),
        }
    }

    /// Its units (hypot's two sides share theirs: the parser checks).
    pub fn units(&self) -> &'static str {
        match self {
            Quantity::Map(m) => m.units(),
            Quantity::Abs(q) | Quantity::Hypot(q, _) => q.units(),
        }
    }
}

/// A recursive-descent reader of quantities.
struct Parser<'t> {
    text: &'t str,
    at: usize,
    what: &'t str,
    backward: bool,
}

impl Parser<'_> {
    fn skip_space(&mut self) {
        while self.text[self.at..].starts_with(' ') {
            self.at += 1;
        }
    }

    fn word(&mut self) -> &str {
        self.skip_space();
        let rest = &self.text[self.at..];
        let len = rest
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(rest.len());
        self.at += len;
        &rest[..len]
    }

    fn expect(&mut self, c: char) -> Result<()> {
        self.skip_space();
        if !self.text[self.at..].starts_with(c) {
            bail!(
                "{} = \"{}\": expected `{c}` at `{}`",
                self.what,
                self.text,
                &self.text[self.at..]
            );
        }
        self.at += 1;
        Ok(())
    }

    fn quantity(&mut self) -> Result<Quantity> {
        let word = self.word().to_owned();
        match word.as_str() {
            "abs" => {
                self.expect('(')?;
                let q = self.quantity()?;
                self.expect(')')?;
                Ok(Quantity::Abs(Box::new(q)))
            }
            "hypot" => {
                self.expect('(')?;
                let a = self.quantity()?;
                self.expect(',')?;
                let b = self.quantity()?;
                self.expect(')')?;
                if a.units() != b.units() {
                    bail!(
                        "{} = \"{}\": hypot of {} [{}] and {} [{}]: both sides need the same units",
                        self.what,
                        self.text,
                        a.text(),
                        a.units(),
                        b.text(),
                        b.units()
                    );
                }
                Ok(Quantity::Hypot(Box::new(a), Box::new(b)))
            }
            name => self.map(name),
        }
    }

    fn map(&self, name: &str) -> Result<Quantity> {
        let Some(map) = Map::from_name(name) else {
            bail!(
                "{} = \"{}\": `{name}` is no quantity the scene produces: expected one of {}, \
                 or abs(...) and hypot(a, b) of them",
                self.what,
                self.text,
                Map::names().join(", ")
            );
        };
        if map.needs_backward() && !self.backward {
            bail!(
                "{} = \"{}\": `{name}` is written only with `[output] backward = true`: add it \
                 to the scene",
                self.what,
                self.text
            );
        }
        Ok(Quantity::Map(map))
    }
}

/// How a constraint compares its sides.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Comparison {
    AtMost,
    AtLeast,
}

/// One side of a constraint.
#[derive(Clone, Debug, PartialEq)]
pub enum Side {
    Quantity(Quantity),
    Number(f64),
}

impl Side {
    fn value(&self, record: &Record, frequency: [f64; AXES]) -> Value {
        match self {
            Side::Quantity(q) => q.value(record, frequency),
            Side::Number(v) => Value { value: *v, se: 0.0 },
        }
    }

    fn text(&self) -> String {
        match self {
            Side::Quantity(q) => q.text(),
            Side::Number(v) => format!("{v:e}"),
        }
    }
}

/// `left <= right` or `left >= right` (`<` and `>` read the same: a
/// measured value is never exactly on a bound).
#[derive(Clone, Debug, PartialEq)]
pub struct Constraint {
    pub left: Side,
    pub comparison: Comparison,
    pub right: Side,
    /// As the scene wrote it.
    pub written: String,
}

impl Constraint {
    /// Reads one entry of `subject_to`.
    pub fn parse(text: &str, backward: bool) -> Result<Constraint> {
        let what = "optimize.subject_to";
        let (at, op) = ["<=", ">=", "<", ">"]
            .iter()
            .find_map(|op| text.find(op).map(|at| (at, *op)))
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "{what}: \"{text}\" compares nothing: expected `A <= B` or `A >= B`, each \
                     side a quantity or a number"
                )
            })?;
        let side = |s: &str| -> Result<Side> {
            let s = s.trim();
            match s.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(Side::Number(v)),
                Ok(v) => bail!("{what}: \"{text}\": {v} is not a finite number"),
                Err(_) => Ok(Side::Quantity(Quantity::parse(s, backward, what)?)),
            }
        };
        let (left, right) = (side(&text[..at])?, side(&text[at + op.len()..])?);
        if let (Side::Number(_), Side::Number(_)) = (&left, &right) {
            bail!("{what}: \"{text}\" compares two numbers: one side must be a quantity");
        }
        Ok(Constraint {
            left,
            comparison: if op.starts_with('<') {
                Comparison::AtMost
            } else {
                Comparison::AtLeast
            },
            right,
            written: text.trim().to_owned(),
        })
    }

    /// The constraint's slack in `record` (how far it is kept: below 0
    /// where it is broken) and the slack's standard error (the sides'
    /// errors taken as independent).
    pub fn slack(&self, record: &Record, frequency: [f64; AXES]) -> Value {
        let (l, r) = (
            self.left.value(record, frequency),
            self.right.value(record, frequency),
        );
        let value = match self.comparison {
            Comparison::AtMost => r.value - l.value,
            Comparison::AtLeast => l.value - r.value,
        };
        Value {
            value,
            se: l.se.hypot(r.se),
        }
    }

    /// The quantities the constraint reads.
    pub fn quantities(&self) -> impl Iterator<Item = &Quantity> {
        [&self.left, &self.right]
            .into_iter()
            .filter_map(|s| match s {
                Side::Quantity(q) => Some(q),
                Side::Number(_) => None,
            })
    }

    /// As read (canonical spacing).
    pub fn text(&self) -> String {
        let op = match self.comparison {
            Comparison::AtMost => "<=",
            Comparison::AtLeast => ">=",
        };
        format!("{} {op} {}", self.left.text(), self.right.text())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record() -> Record {
        let mut r = Record {
            step: [3e-7, -4e-7],
            step_se: [3e-9, 4e-9],
            velocity: [3e-6, -4e-6],
            ..Record::default()
        };
        r.backward.ratio = [0.02, 0.5];
        r.backward.ratio_se = [0.001, 0.01];
        r
    }

    fn check(text: &str, expected: Result<(f64, f64), &str>) {
        let got = Quantity::parse(text, true, "maximize")
            .map(|q| q.value(&record(), [10.0, 10.0]))
            .map(|v| (v.value, v.se));
        match (got, expected) {
            (Ok(got), Ok(want)) => {
                assert!(
                    (got.0 - want.0).abs() <= 1e-12 * want.0.abs().max(1e-300),
                    "{text}"
                );
                assert!(
                    (got.1 - want.1).abs() <= 1e-12 * want.1.abs().max(1e-300),
                    "{text}"
                );
            }
            (Err(e), Err(part)) => assert!(e.to_string().contains(part), "{e}"),
            (got, want) => panic!("{text}: got {got:?}, expected {want:?}"),
        }
    }

    #[test]
    fn quantities_read_and_carry_their_errors() {
        check("step_x", Ok((3e-7, 3e-9)));
        check("abs(step_y)", Ok((4e-7, 4e-9)));
        check("velocity_y", Ok((-4e-6, 4e-8)));
        // h = 5e-7, se = sqrt((3e-7 3e-9)^2 + (4e-7 4e-9)^2) / 5e-7
        // = sqrt(337) 2e-10.
        check(
            " hypot( step_x , step_y ) ",
            Ok((5e-7, 337f64.sqrt() * 2e-10)),
        );
        check("backward_ratio_x", Ok((0.02, 0.001)));
        check("step_z", Err("`step_z` is no quantity"));
        check("hypot(step_x, velocity_x)", Err("same units"));
        check("abs(step_x", Err("expected `)`"));
        check("step_x step_y", Err("unexpected `step_y`"));
        let e = Quantity::parse("backward_x", false, "minimize").unwrap_err();
        assert!(e.to_string().contains("[output] backward = true"), "{e}");
    }

    #[test]
    fn constraints_give_their_slack() {
        let c = Constraint::parse("backward_ratio_x <= 0.05", true).unwrap();
        let s = c.slack(&record(), [10.0, 10.0]);
        assert!((s.value - 0.03).abs() < 1e-15 && s.se == 0.001);
        let c = Constraint::parse("1e-9 >= abs(step_y)", true).unwrap();
        assert!(c.slack(&record(), [10.0; 2]).value < 0.0);
        let c = Constraint::parse("step_x > step_y", true).unwrap();
        assert!((c.slack(&record(), [10.0; 2]).value - 7e-7).abs() < 1e-20);
        for (bad, part) in [
            ("step_x", "compares nothing"),
            ("1 <= 2", "two numbers"),
            ("stepx <= 1", "`stepx` is no quantity"),
        ] {
            let e = Constraint::parse(bad, true).unwrap_err();
            assert!(e.to_string().contains(part), "{e}");
        }
    }
}
