//! Asset ids: the only user-chosen text that reaches a file name or an object key.

use crate::ApiError;
use std::fmt;

/// A validated asset id: `[a-z0-9][a-z0-9._-]{0,63}`.
///
/// The alphabet has no `/` or `\`, and the first character cannot be `.`, so an id can neither
/// leave the store's folder or prefix nor name a hidden file (the local store keeps its
/// temporary files under dot-names, out of every id's reach).
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct AssetId(String);

impl AssetId {
    /// Longest id, in bytes (ASCII, so also characters).
    pub const MAX_LEN: usize = 64;

    /// Checks `s` and takes it; [`ApiError::InvalidId`] (400) otherwise, quoting at most a short prefix.
    pub fn parse(s: &str) -> Result<AssetId, ApiError> {
        if Self::is_valid(s) { Ok(AssetId(s.to_string())) } else { Err(ApiError::InvalidId(truncate_for_message(s))) }
    }

    /// Whether `s` is a valid id: 1 to [`AssetId::MAX_LEN`] bytes of `a-z 0-9 . _ -`, the first a letter or digit.
    pub fn is_valid(s: &str) -> bool {
        let b = s.as_bytes();
        let first_ok = b.first().is_some_and(|c| c.is_ascii_lowercase() || c.is_ascii_digit());
        first_ok
            && b.len() <= Self::MAX_LEN
            && b.iter().all(|&c| c.is_ascii_lowercase() || c.is_ascii_digit() || matches!(c, b'.' | b'_' | b'-'))
    }

    /// The id as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// The object name of this asset's container in a store: `<id>.pmc`.
    pub fn file_name(&self) -> String {
        format!("{}.pmc", self.0)
    }

    /// The id of a store object name, if it is `<valid id>.pmc`.
    pub fn from_file_name(name: &str) -> Option<AssetId> {
        let stem = name.strip_suffix(".pmc")?;
        Self::is_valid(stem).then(|| AssetId(stem.to_string()))
    }
}

impl fmt::Display for AssetId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Echoing a rejected id helps the client see what arrived; a huge one would bloat the answer.
fn truncate_for_message(s: &str) -> String {
    const KEEP: usize = 80;
    match s.char_indices().nth(KEEP) {
        Some((i, _)) => format!("{}...", &s[..i]),
        None => s.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_the_documented_alphabet_only() {
        for ok in ["a", "0", "horse-gallop", "cat_01.v2", &"x".repeat(64)] {
            assert!(AssetId::is_valid(ok), "{ok}");
        }
        for bad in ["", ".hidden", "-a", "_a", "A", "a/b", "..", "../etc", "a\\b", "a b", "é", "a%2f", &"x".repeat(65), "a\0"] {
            assert!(!AssetId::is_valid(bad), "{bad:?}");
        }
    }

    #[test]
    fn file_names_round_trip_and_reject_others() {
        let id = AssetId::parse("tube").unwrap();
        assert_eq!(AssetId::from_file_name(&id.file_name()), Some(id));
        assert_eq!(AssetId::from_file_name("Tube.pmc"), None);
        assert_eq!(AssetId::from_file_name(".tmp-1.pmc"), None);
        assert_eq!(AssetId::from_file_name("tube.obj"), None);
    }

    #[test]
    fn long_rejected_ids_are_shortened_in_messages() {
        let msg = AssetId::parse(&"Z".repeat(500)).unwrap_err().to_string();
        assert!(msg.len() < 300, "{msg}");
    }
}
