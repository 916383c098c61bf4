//! TOML errors turned into HEML errors with a line number and a "did you mean",
//! and line look-ups for semantic errors.

use std::path::Path;

use crate::error::HemlError;
use crate::registry::closest;

/// A TOML/serde error as [`HemlError::Parse`]: the file, the 1-based line of the
/// offending key or value, the message and, for an unknown key or value, the
/// closest expected one.
pub(crate) fn toml_error(origin: &Path, text: &str, e: &toml::de::Error) -> HemlError {
    let line = e.span().map_or(0, |s| line_of(text, s.start));
    let mut msg = e.message().trim().replace('\n', " ");
    // toml says "duplicate key" (or table) without the name; its span covers it
    if msg.starts_with("duplicate") && !msg.contains('`') {
        if let Some(name) = e
            .span()
            .and_then(|s| text.get(s))
            .map(str::trim)
            .filter(|n| !n.is_empty())
        {
            msg = format!("{msg} `{name}`");
        }
    }
    // a wrong value ("invalid type: string \"1.0\", expected f64") names its key
    if let Some(key) = e.span().and_then(|s| key_before(text, s.start)) {
        if !msg.contains(&format!("`{key}`")) {
            msg = format!("`{key}`: {msg}");
        }
    }
    if let Some(s) = suggestion(&msg) {
        msg.push_str(&format!("; did you mean `{s}`?"));
    }
    HemlError::Parse {
        file: origin.to_path_buf(),
        line,
        msg,
    }
}

/// For "unknown field `x`, expected one of `a`, `b`" (and "unknown variant"), the
/// expected name closest to `x`.
pub(crate) fn suggestion(msg: &str) -> Option<String> {
    let rest = ["unknown field `", "unknown variant `"]
        .iter()
        .find_map(|p| msg.split_once(p).map(|(_, r)| r))?;
    let (word, rest) = rest.split_once('`')?;
    let (_, expected) = rest.split_once("expected")?;
    let names: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
    closest(word, &names).map(str::to_string)
}

/// The key of the value starting at byte `pos` (`key = value`, also inside an inline
/// table), when the text before it reads like one.
pub(crate) fn key_before(text: &str, pos: usize) -> Option<&str> {
    let before = text.get(..pos)?.trim_end();
    let before = before.strip_suffix('=')?.trim_end();
    // (past the whole character: a multi-byte one, e.g. the U+FFFD that replaces an
    // invalid byte, made `i + 1` cut it and the slice panic — found by fuzzing)
    let start = before
        .char_indices()
        .rev()
        .find(|&(_, c)| !(c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.'))
        .map_or(0, |(i, c)| i + c.len_utf8());
    let key = &before[start..];
    (!key.is_empty()).then_some(key)
}

/// 1-based line of byte offset `pos`.
pub(crate) fn line_of(text: &str, pos: usize) -> usize {
    let pos = pos.min(text.len());
    text.as_bytes()[..pos].iter().filter(|&&b| b == b'\n').count() + 1
}

/// Line of the `index`-th (0-based) `[[table]]` header, when written as a header.
#[cfg(test)]
pub(crate) fn entry_line(text: &str, table: &str, index: usize) -> Option<usize> {
    entry_lines(text).get(table).and_then(|lines| lines.get(index).copied())
}

/// The 1-based lines of every `[[table]]` header of `text`, by table name (in one
/// pass over the text).
pub(crate) fn entry_lines(text: &str) -> std::collections::HashMap<String, Vec<usize>> {
    let mut lines: std::collections::HashMap<String, Vec<usize>> = std::collections::HashMap::new();
    for (i, l) in text.lines().enumerate() {
        let l = l.trim_start();
        let Some(rest) = l.strip_prefix("[[") else { continue };
        let Some(end) = rest.find("]]") else { continue };
        lines.entry(rest[..end].trim().to_string()).or_default().push(i + 1);
    }
    lines
}

/// Line of the `[table]` header.
pub(crate) fn table_line(text: &str, table: &str) -> Option<usize> {
    let header = format!("[{table}]");
    text.lines()
        .position(|l| l.trim_start().starts_with(&header))
        .map(|i| i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The key before a value, also after a multi-byte character (which used to
    /// panic: the key started inside the character).
    #[test]
    fn key_before_stops_at_whole_characters() {
        assert_eq!(key_before("a = 1", 4), Some("a"));
        // the fuzzer's input: an invalid byte read as U+FFFD (3 bytes) before a key
        let text = "{ E = 3,\u{fffd}x-= 1";
        assert_eq!(key_before(text, text.find("= 1").unwrap() + 1), Some("x-"));
        assert_eq!(key_before("é= 1", 3), None);
        assert_eq!(key_before("ék = 1", 5), Some("k"));
        assert_eq!(key_before("x é k = 1", 8), Some("k"));
    }

    #[test]
    fn suggests_the_closest_expected_name() {
        let m = "unknown field `densty`, expected one of `law`, `params`, `density`, `tag`, `prony`";
        assert_eq!(suggestion(m).as_deref(), Some("density"));
        let m = "unknown variant `smoth`, expected one of `step`, `linear`, `smooth`";
        assert_eq!(suggestion(m).as_deref(), Some("smooth"));
        assert_eq!(suggestion("unknown field `zzzzzzzz`, expected `law`"), None);
        assert_eq!(suggestion("invalid type: string"), None);
        assert_eq!(line_of("a\nb\nc", 2), 2);
        assert_eq!(entry_line("x\n[[fix]]\n\n [[fix]]\n", "fix", 1), Some(4));
        let t = "params = { E = \"1.0\", nu = 0.45 }";
        assert_eq!(key_before(t, t.find('"').unwrap()), Some("E"));
        assert_eq!(key_before("dt = x", 5), Some("dt"));
        assert_eq!(key_before("[1, 2]", 1), None);
    }

    #[test]
    fn names_the_duplicate_key_and_its_line() {
        let text = "[solver]\nduration = 0.05\nduration = 0.1\n";
        let e = toml::from_str::<toml::Table>(text).unwrap_err();
        let msg = toml_error(Path::new("s.toml"), text, &e).to_string();
        assert!(msg.starts_with("s.toml:3: duplicate key `duration`"), "{msg}");
    }
}
