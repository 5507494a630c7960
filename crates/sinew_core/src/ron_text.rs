//! Reading RON files (scenes, import recipes, rig maps) with errors a user
//! can act on: line and column, and for a misspelt field or variant the
//! nearest valid name ("unknown field `iteratons` in `SolverSettings` — did
//! you mean `iterations`?"). Every sinew type read from RON refuses unknown
//! fields (`#[serde(deny_unknown_fields)]`), so a typo is never ignored.

use crate::error::SceneError;
use ron::error::{Error, SpannedError};
use serde::de::DeserializeOwned;
use std::path::Path;

/// Parses RON `text` into a `T`; `file` names the source in errors.
pub(crate) fn parse<T: DeserializeOwned>(text: &str, file: &Path) -> Result<T, SceneError> {
    ron::from_str(text).map_err(|e: SpannedError| SceneError::Syntax {
        file: file.to_path_buf(),
        line: e.span.start.line,
        column: e.span.start.col,
        reason: describe(&e.code),
    })
}

/// The parser's message, with the nearest valid name for an unknown field
/// or variant.
pub(crate) fn describe(error: &Error) -> String {
    match error {
        Error::NoSuchStructField {
            expected,
            found,
            outer,
        } => unknown_name("field", found, outer.as_deref(), expected),
        Error::NoSuchEnumVariant {
            expected,
            found,
            outer,
        } => unknown_name("variant", found, outer.as_deref(), expected),
        Error::IntegerOutOfBounds => {
            "integer out of range for its field (a negative count, or one too large)".into()
        }
        other => other.to_string(),
    }
}

fn unknown_name(kind: &str, found: &str, outer: Option<&str>, expected: &[&str]) -> String {
    let mut text = format!("unknown {kind} `{found}`");
    if let Some(outer) = outer {
        text += &format!(" in `{outer}`");
    }
    match nearest(found, expected) {
        Some(name) => text += &format!(" — did you mean `{name}`?"),
        None if expected.is_empty() => text += &format!(" (no {kind}s are expected here)"),
        None => {
            let list: Vec<String> = expected.iter().map(|e| format!("`{e}`")).collect();
            text += &format!(" (expected one of {})", list.join(", "));
        }
    }
    text
}

/// The expected name closest to `found` by edit distance (case-insensitive),
/// if it is close enough to be a typo: at most a third of the longer name's
/// characters differ (and at least one may).
pub(crate) fn nearest<'a>(found: &str, expected: &[&'a str]) -> Option<&'a str> {
    let found_lower = found.to_lowercase();
    expected
        .iter()
        .map(|name| (edit_distance(&found_lower, &name.to_lowercase()), *name))
        .filter(|(distance, name)| {
            let longer = found.chars().count().max(name.chars().count());
            *distance <= (longer / 3).max(1)
        })
        .min_by_key(|(distance, _)| *distance)
        .map(|(_, name)| name)
}

/// Levenshtein distance counting an adjacent transposition as one edit.
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let width = b.len() + 1;
    let mut rows = vec![0usize; (a.len() + 1) * width];
    for (j, cell) in rows.iter_mut().take(width).enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        rows[i * width] = i;
        for j in 1..=b.len() {
            let substitution = usize::from(a[i - 1] != b[j - 1]);
            let mut best = (rows[(i - 1) * width + j] + 1)
                .min(rows[i * width + j - 1] + 1)
                .min(rows[(i - 1) * width + j - 1] + substitution);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(rows[(i - 2) * width + j - 2] + 1);
            }
            rows[i * width + j] = best;
        }
    }
    rows[a.len() * width + b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typos_find_their_field() {
        let fields = ["iterations", "substeps", "gravity", "dt", "threads"];
        assert_eq!(nearest("iteratons", &fields), Some("iterations"));
        assert_eq!(nearest("itreations", &fields), Some("iterations"));
        assert_eq!(nearest("Gravity", &fields), Some("gravity"));
        assert_eq!(nearest("muscels", &["muscles", "bones"]), Some("muscles"));
        assert_eq!(nearest("colour", &fields), None);
        assert_eq!(nearest("x", &fields), None);
    }

    #[test]
    fn edit_distance_counts_edits() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("ab", "ba"), 1);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("same", "same"), 0);
    }
}
