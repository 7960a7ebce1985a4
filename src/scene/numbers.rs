//! Numbers in a scene: a TOML number's value (integers beyond 64 bits
//! included), a single finite number, and a numeric key's values (a
//! scalar, a list or a range), each checked against the key's rule and
//! bounds.

use std::ops::Range;

use toml::de::{DeTable, DeValue};

use super::error::SceneError;
use super::format::{fmt_num, human_bytes};
use super::keys::{Field, NUMERIC_EXPECTED, RANGE_KEYS};
use super::memory::MAP_MEMORY_BUDGET_BYTES;
use super::parser::{Parser, Value};
use super::values::{MAX_RANGE_STEPS, Values};

impl Parser<'_> {
    /// A number (integer or float, possibly non-finite).
    pub(super) fn number(value: &DeValue<'_>) -> Option<f64> {
        match value {
            DeValue::Integer(i) => integer_value(i.as_str(), i.radix()),
            DeValue::Float(f) => {
                let text = f.as_str();
                text.parse::<f64>().ok().or_else(|| {
                    let lower = text.to_ascii_lowercase();
                    if lower.contains("nan") {
                        Some(f64::NAN)
                    } else if lower.contains("inf") {
                        Some(if lower.starts_with('-') {
                            f64::NEG_INFINITY
                        } else {
                            f64::INFINITY
                        })
                    } else {
                        None
                    }
                })
            }
            _ => None,
        }
    }

    /// A single finite number.
    pub(super) fn finite(&self, path: &str, value: &Value<'_>) -> Result<f64, SceneError> {
        let number = Self::number(value.get_ref())
            .ok_or_else(|| self.wrong_type(path, "expected a number", value))?;
        if !number.is_finite() {
            return Err(self.invalid(
                value.span(),
                format!("{path} = {}: expected a finite number", fmt_num(number)),
            ));
        }
        Ok(number)
    }

    /// The values of a numeric key, each checked against the key's rule.
    pub(super) fn values(
        &self,
        path: &str,
        field: Field,
        value: &Value<'_>,
    ) -> Result<Values, SceneError> {
        let values = match value.get_ref() {
            DeValue::Integer(_) | DeValue::Float(_) => {
                Values::List(vec![Self::number(value.get_ref()).unwrap_or(f64::NAN)])
            }
            DeValue::Array(items) => {
                if items.is_empty() {
                    return Err(self.invalid(
                        value.span(),
                        format!("{path} = []: expected at least one value (an empty list gives no instances)"),
                    ));
                }
                let mut numbers = Vec::with_capacity(items.len());
                for (i, item) in items.iter().enumerate() {
                    match Self::number(item.get_ref()) {
                        Some(number) => numbers.push(number),
                        None => {
                            return Err(self.wrong_type(
                                &format!("{path}[{i}]"),
                                "expected a number",
                                item,
                            ));
                        }
                    }
                }
                Values::List(numbers)
            }
            DeValue::Table(table) => self.range(path, field, value.span(), table)?,
            _ => return Err(self.wrong_type(path, NUMERIC_EXPECTED, value)),
        };
        let rule = field.rule();
        let source = self.source(value.span());
        for (i, number) in values.extremes() {
            let context = match &values {
                Values::List(list) if list.len() == 1 => String::new(),
                Values::List(_) => format!(" (value {} of {source})", i + 1),
                Values::Range { .. } => format!(" (in the range {source})"),
            };
            if !number.is_finite() {
                return Err(self.invalid(
                    value.span(),
                    format!(
                        "{path} = {}: expected a finite number{context}",
                        fmt_num(number)
                    ),
                ));
            }
            if !rule.accepts(number) {
                return Err(self.invalid(
                    value.span(),
                    format!("{path} = {}: {}{context}", fmt_num(number), rule.expected()),
                ));
            }
            if let Some(bounds) = field.bounds()
                && !bounds.contains(number)
            {
                return Err(self.invalid(
                    value.span(),
                    format!(
                        "{path} = {}: {}{context}",
                        fmt_num(number),
                        bounds.expected(field.units())
                    ),
                ));
            }
        }
        Ok(values)
    }

    /// A range table `{ from, to, steps, log }`.
    pub(super) fn range(
        &self,
        path: &str,
        field: Field,
        span: Range<usize>,
        table: &DeTable<'_>,
    ) -> Result<Values, SceneError> {
        let (mut from, mut to, mut steps, mut log) = (None, None, None, false);
        for (key, value) in table.iter() {
            let key_path = format!("{path}.{}", key.get_ref());
            match key.get_ref().as_ref() {
                "from" => from = Some(self.finite(&key_path, value)?),
                "to" => to = Some(self.finite(&key_path, value)?),
                "steps" => steps = Some(self.steps(&key_path, value)?),
                "log" => match value.get_ref() {
                    DeValue::Boolean(b) => log = *b,
                    _ => {
                        return Err(self.wrong_type(
                            &key_path,
                            "expected a boolean (true or false)",
                            value,
                        ));
                    }
                },
                _ => return Err(self.unknown_key(key, path, &RANGE_KEYS)),
            }
        }
        let source = self.source(span.clone());
        let missing = [
            ("from", from.is_none()),
            ("to", to.is_none()),
            ("steps", steps.is_none()),
        ];
        if let Some((name, _)) = missing.iter().find(|(_, missing)| *missing) {
            return Err(self.invalid(
                span,
                format!(
                    "{path} = {source}: a range needs `from`, `to` and `steps`, but `{name}` is missing"
                ),
            ));
        }
        let (from, to, steps) = (from.unwrap_or(0.0), to.unwrap_or(0.0), steps.unwrap_or(1));
        if steps == 1 && from != to {
            return Err(self.invalid(
                span,
                format!(
                    "{path} = {source}: steps = 1 gives the single value from = {}, never \
                     reaching to = {}; expected steps >= 2 when from != to (or to = from for a \
                     single value)",
                    fmt_num(from),
                    fmt_num(to)
                ),
            ));
        }
        let rule = field.rule();
        if log && rule.integer() {
            return Err(self.invalid(
                span,
                format!(
                    "{path} = {source}: an integer key cannot take a log range; give a list of integers"
                ),
            ));
        }
        if log && !(from > 0.0 && to > 0.0) {
            return Err(self.invalid(
                span,
                format!(
                    "{path} = {source}: a log range needs from > 0 and to > 0, found from = {} and to = {}",
                    fmt_num(from),
                    fmt_num(to)
                ),
            ));
        }
        if rule.integer() && steps > 1 {
            let step = (to - from) / (steps - 1) as f64;
            if step.fract() != 0.0 {
                return Err(self.invalid(
                    span,
                    format!(
                        "{path} = {source}: the values do not land on integers (step {}); \
                         choose steps so that (to - from) / (steps - 1) is an integer",
                        fmt_num(step)
                    ),
                ));
            }
        }
        Ok(Values::Range {
            from,
            to,
            steps,
            log,
        })
    }

    /// `steps` of a range: an integer from 1 to [`MAX_RANGE_STEPS`].
    fn steps(&self, path: &str, value: &Value<'_>) -> Result<u64, SceneError> {
        let expected = "expected an integer >= 1";
        let number =
            Self::number(value.get_ref()).ok_or_else(|| self.wrong_type(path, expected, value))?;
        if !(number >= 1.0 && number.fract() == 0.0) {
            return Err(self.invalid(
                value.span(),
                format!("{path} = {}: {expected}", fmt_num(number)),
            ));
        }
        if number > MAX_RANGE_STEPS as f64 {
            return Err(self.invalid(
                value.span(),
                format!(
                    "{path} = {}: too large; expected at most {MAX_RANGE_STEPS} steps (the most \
                     values one grid axis can have within the {} budget of the output maps)",
                    self.source(value.span()),
                    human_bytes(MAP_MEMORY_BUDGET_BYTES as f64)
                ),
            ));
        }
        Ok(number as u64)
    }
}

/// The value of an integer's digits (as `from_str_radix` reads them, with an
/// optional sign): exact up to 2^53, rounded beyond. TOML integers are 64
/// bits, but a scene may hold more digits, and they should read as the huge
/// number they are rather than as something that is not a number.
fn integer_value(digits: &str, radix: u32) -> Option<f64> {
    if let Ok(n) = i128::from_str_radix(digits, radix) {
        return Some(n as f64);
    }
    if radix == 10 {
        // Correctly rounded, where summing digit by digit would not be.
        return digits.parse().ok();
    }
    let (negative, magnitude) = match digits.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, digits.strip_prefix('+').unwrap_or(digits)),
    };
    if magnitude.is_empty() {
        return None;
    }
    let mut value = 0.0f64;
    for c in magnitude.chars() {
        value = value * f64::from(radix) + f64::from(c.to_digit(radix)?);
    }
    Some(if negative { -value } else { value })
}
