//! The checks every section of the configuration shares: a number or a count within its range,
//! one of a set of named choices; each error names the file and the field.

use std::path::Path;

use crate::spec::SpecError;

/// A number within `range`, or an error naming the field and the range.
pub(super) fn within(
    path: &Path,
    field: &str,
    v: Option<f64>,
    range: (f64, f64),
    unit: &str,
) -> Result<Option<f64>, SpecError> {
    match v {
        Some(x) if !(x.is_finite() && x >= range.0 && x <= range.1) => Err(SpecError::invalid(
            path,
            field,
            format!("{x}: give a value from {} to {} {unit}", range.0, range.1),
        )),
        _ => Ok(v),
    }
}

/// The value of the named choice, the first when none is given, or an error naming the field
/// and every choice.
pub(super) fn one_of<T: Copy>(
    path: &Path,
    field: &str,
    v: Option<&str>,
    choices: &[(&str, T)],
) -> Result<T, SpecError> {
    let Some(name) = v else { return Ok(choices[0].1) };
    choices
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(_, t)| t)
        .ok_or_else(|| {
            let quoted: Vec<String> = choices.iter().map(|(n, _)| format!("{n:?}")).collect();
            let (last, rest) = quoted.split_last().expect("choices");
            let list = if rest.is_empty() {
                last.clone()
            } else {
                format!("{} or {last}", rest.join(", "))
            };
            SpecError::invalid(path, field, format!("{name:?}: give {list}"))
        })
}

/// A count within `range`, or an error naming the field and the range.
pub(super) fn count_within(
    path: &Path,
    field: &str,
    v: Option<usize>,
    range: (usize, usize),
) -> Result<Option<usize>, SpecError> {
    match v {
        Some(n) if !(range.0..=range.1).contains(&n) => Err(SpecError::invalid(
            path,
            field,
            format!("{n}: give a count from {} to {}", range.0, range.1),
        )),
        _ => Ok(v),
    }
}
