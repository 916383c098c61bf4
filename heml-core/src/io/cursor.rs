//! A byte cursor over a whole input file that knows its line number, shared by the
//! text readers so that every parse error can name the file and the line.
//!
//! Formats differ in how much layout they impose: Gmsh elements are one per line,
//! whereas VTK legacy and Medit are free-format token streams (numbers may wrap
//! anywhere). The cursor therefore offers both tokens and lines over the same
//! position, and raw byte slices for the binary blocks of legacy VTK.

use std::path::Path;
use std::str::FromStr;

use crate::error::{HemlError, Result};

/// Position-tracking reader over the bytes of one file.
#[derive(Clone)]
pub(crate) struct Cursor<'a> {
    file: &'a Path,
    data: &'a [u8],
    pos: usize,
    line: usize,
    comment: Option<u8>,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `data`; `comment` starts a comment running to the end
    /// of the line (e.g. `#` in TetGen and Medit files).
    pub fn new(file: &'a Path, data: &'a [u8], comment: Option<u8>) -> Self {
        Cursor {
            file,
            data,
            pos: 0,
            line: 1,
            comment,
        }
    }

    /// The file being read (for error messages).
    pub fn file(&self) -> &'a Path {
        self.file
    }

    /// 1-based line of the current position.
    pub fn line(&self) -> usize {
        self.line
    }

    /// Bytes not yet consumed.
    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// Byte offset of the current position from the start of the file (named in
    /// errors about binary data, where a line number says little).
    pub fn offset(&self) -> usize {
        self.pos
    }

    /// Moves just past the next occurrence of `needle` (and the rest of its line);
    /// `false`, with the cursor unmoved, when there is none. Skips sections whose
    /// content may be binary, which the line readers would refuse as invalid text.
    pub fn skip_past(&mut self, needle: &[u8]) -> bool {
        let rest = &self.data[self.pos..];
        let Some(at) = rest.windows(needle.len().max(1)).position(|w| w == needle) else {
            return false;
        };
        self.line += rest[..at + needle.len()].iter().filter(|&&b| b == b'\n').count();
        self.pos += at + needle.len();
        self.skip_rest_of_line();
        true
    }

    /// A parse error at `line`.
    pub fn err_at(&self, line: usize, msg: impl Into<String>) -> HemlError {
        HemlError::Parse {
            file: self.file.to_path_buf(),
            line,
            msg: msg.into(),
        }
    }

    /// A parse error at the current line.
    pub fn err(&self, msg: impl Into<String>) -> HemlError {
        self.err_at(self.line, msg)
    }

    /// The error for running out of input while reading `what`.
    pub fn eof(&self, what: &str) -> HemlError {
        self.err(format!("unexpected end of file while reading {what} (file truncated?)"))
    }

    fn skip_space_and_comments(&mut self) {
        while let Some(&b) = self.data.get(self.pos) {
            if b == b'\n' {
                self.line += 1;
                self.pos += 1;
            } else if b.is_ascii_whitespace() {
                self.pos += 1;
            } else if Some(b) == self.comment {
                while let Some(&c) = self.data.get(self.pos) {
                    if c == b'\n' {
                        break;
                    }
                    self.pos += 1;
                }
            } else {
                break;
            }
        }
    }

    /// Skips whitespace and comments; returns the line where the next token starts.
    pub fn line_of_next_token(&mut self) -> usize {
        self.skip_space_and_comments();
        self.line
    }

    /// The next whitespace-separated token and its line, or `None` at end of file.
    pub fn token(&mut self) -> Result<Option<(&'a str, usize)>> {
        self.skip_space_and_comments();
        let start = self.pos;
        while let Some(&b) = self.data.get(self.pos) {
            if b.is_ascii_whitespace() || Some(b) == self.comment {
                break;
            }
            self.pos += 1;
        }
        if start == self.pos {
            return Ok(None);
        }
        let tok = std::str::from_utf8(&self.data[start..self.pos])
            .map_err(|_| self.err("invalid UTF-8 in a text field (binary data in a text file?)"))?;
        Ok(Some((tok, self.line)))
    }

    /// The next token; running out of input is an error naming `what`.
    pub fn expect_token(&mut self, what: &str) -> Result<(&'a str, usize)> {
        self.token()?.ok_or_else(|| self.eof(what))
    }

    /// The first token of record `k` (0-based) of `n` announced at line `header`:
    /// running out of input names how many records were found.
    pub fn record_start(&mut self, k: usize, n: usize, what: &str, header: usize) -> Result<(&'a str, usize)> {
        self.token()?.ok_or_else(|| {
            self.err(format!(
                "unexpected end of file: the header (line {header}) announces {n} {what}, the file ends \
                 after {k} (file truncated?)"
            ))
        })
    }

    /// Record `k` of `n` announced at line `header` must start with a `T`: a word
    /// there (the next section's keyword) means the section holds fewer records
    /// than its count, which the error says.
    pub fn record_number<T: FromStr>(&mut self, k: usize, n: usize, what: &str, header: usize) -> Result<(T, usize)> {
        let (tok, line) = self.record_start(k, n, what, header)?;
        match tok.parse::<T>() {
            Ok(v) => Ok((v, line)),
            Err(_) if tok.starts_with(|ch: char| ch.is_ascii_alphabetic() || ch == '$') => Err(self.err_at(
                line,
                format!(
                    "expected a number in the {what}, found '{}': the header (line {header}) announces \
                     {n} {what}, only {k} given",
                    shorten(tok)
                ),
            )),
            Err(_) => Err(self.err_at(
                line,
                format!("expected a number in the {what}, found '{}'", shorten(tok)),
            )),
        }
    }

    /// Fails if anything but whitespace and comments follows the `n` records of
    /// `what` announced at line `header`: a record beyond the count would otherwise
    /// be silently dropped (part of the body missing from the simulation).
    pub fn expect_no_more_records(&mut self, n: usize, what: &str, header: usize) -> Result<()> {
        match self.token()? {
            None => Ok(()),
            Some((tok, line)) => Err(self.err_at(
                line,
                format!(
                    "found '{}' after the {n} {what} announced by the header (line {header}): \
                     the header count is wrong or the file has extra records",
                    shorten(tok)
                ),
            )),
        }
    }

    /// The next token parsed as `T`.
    pub fn parse<T: FromStr>(&mut self, what: &str) -> Result<T> {
        let (tok, line) = self.expect_token(what)?;
        parse_at(self.file, line, tok, what)
    }

    /// The next non-blank line (comments stripped, trimmed) and its number, or `None`
    /// at end of file. If the cursor stands inside a line, the rest of that line
    /// counts as a line when it is not blank.
    pub fn next_line(&mut self) -> Result<Option<(&'a str, usize)>> {
        loop {
            if self.pos >= self.data.len() {
                return Ok(None);
            }
            let start = self.pos;
            let line = self.line;
            let end = self.data[start..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(self.data.len(), |p| start + p);
            self.pos = end;
            if end < self.data.len() {
                self.pos += 1;
                self.line += 1;
            }
            let mut raw = &self.data[start..end];
            if let Some(c) = self.comment {
                if let Some(p) = raw.iter().position(|&b| b == c) {
                    raw = &raw[..p];
                }
            }
            let text = std::str::from_utf8(raw)
                .map_err(|_| self.err_at(line, "invalid UTF-8 in a text line (binary data in a text file?)"))?
                .trim();
            if !text.is_empty() {
                return Ok(Some((text, line)));
            }
        }
    }

    /// The next non-blank line; running out of input is an error naming `what`.
    pub fn expect_line(&mut self, what: &str) -> Result<(&'a str, usize)> {
        self.next_line()?.ok_or_else(|| self.eof(what))
    }

    /// The rest of the current line, blank or not (trimmed, comments kept), or `None`
    /// at end of file. Used where blank lines matter (a VTK title may be empty).
    pub fn raw_line(&mut self) -> Result<Option<(&'a str, usize)>> {
        if self.pos >= self.data.len() {
            return Ok(None);
        }
        let (start, line) = (self.pos, self.line);
        self.skip_rest_of_line();
        let raw = &self.data[start..self.pos];
        let text = std::str::from_utf8(raw)
            .map_err(|_| self.err_at(line, "invalid UTF-8 in a text line (binary data in a text file?)"))?;
        Ok(Some((text.trim(), line)))
    }

    /// Whether the next token (after whitespace) is `word`, without consuming anything.
    pub fn peek_is(&self, word: &str) -> bool {
        let mut p = self.pos;
        while self.data.get(p).is_some_and(|b| b.is_ascii_whitespace()) {
            p += 1;
        }
        let w = word.as_bytes();
        self.data.get(p..p + w.len()).is_some_and(|s| s.eq_ignore_ascii_case(w))
            && !matches!(self.data.get(p + w.len()), Some(b) if !b.is_ascii_whitespace())
    }

    /// Moves just past the end of the current line (used before binary blocks, which
    /// start right after the newline of their keyword line).
    pub fn skip_rest_of_line(&mut self) {
        while let Some(&b) = self.data.get(self.pos) {
            self.pos += 1;
            if b == b'\n' {
                self.line += 1;
                return;
            }
        }
    }

    /// The next `n` raw bytes.
    pub fn bytes(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if n > self.remaining() {
            return Err(self.eof(what));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.line += s.iter().filter(|&&b| b == b'\n').count();
        self.pos += n;
        Ok(s)
    }
}

/// Parses one token, naming the file, line and field on failure.
pub(crate) fn parse_at<T: FromStr>(file: &Path, line: usize, tok: &str, what: &str) -> Result<T> {
    tok.parse::<T>().map_err(|_| HemlError::Parse {
        file: file.to_path_buf(),
        line,
        msg: format!("expected {what}, found '{}'", shorten(tok)),
    })
}

/// A token cut to a printable length for error messages.
pub(crate) fn shorten(tok: &str) -> String {
    if tok.chars().count() > 40 {
        format!("{}…", tok.chars().take(40).collect::<String>())
    } else {
        tok.to_string()
    }
}

/// A capacity hint that cannot be abused by a lying count in a header: never more
/// items than the input's remaining bytes could hold when each item takes at least
/// `min_bytes_per_item` bytes of input (e.g. 2 for an ASCII number and its
/// separator, 8 for a binary double). A header announcing 10¹⁸ nodes in a 1 kB file
/// thus reserves at most ~1 kB worth of items; the vector still grows as records
/// are really read.
pub(crate) fn capacity(count: usize, remaining_bytes: usize, min_bytes_per_item: usize) -> usize {
    count.min(remaining_bytes / min_bytes_per_item.max(1))
}

/// 1-based line of byte `offset` in `data`.
pub(crate) fn line_of(data: &[u8], offset: usize) -> usize {
    1 + data[..offset.min(data.len())].iter().filter(|&&b| b == b'\n').count()
}

/// Line numbers of byte offsets that arrive (mostly) in increasing order, as the
/// tags of an XML file do: each look-up counts newlines from the previous offset
/// only, so numbering every tag of a file costs one pass over it instead of one
/// pass per tag (a 500 kB `.vtu` with 100k tags took ~10 s when each tag's line was
/// counted from byte 0). An offset before the previous one restarts from the
/// beginning (correct, only slower; parsers do not do it in their main loop).
pub(crate) struct LineCounter<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
    /// Bytes examined so far, for tests that check the work is linear.
    scanned: usize,
}

impl<'a> LineCounter<'a> {
    /// A counter at the start of `data` (line 1).
    pub fn new(data: &'a [u8]) -> Self {
        LineCounter {
            data,
            pos: 0,
            line: 1,
            scanned: 0,
        }
    }

    /// 1-based line of byte `offset` (clamped to the data).
    pub fn line_at(&mut self, offset: usize) -> usize {
        let offset = offset.min(self.data.len());
        if offset < self.pos {
            self.pos = 0;
            self.line = 1;
        }
        let chunk = &self.data[self.pos..offset];
        self.line += chunk.iter().filter(|&&b| b == b'\n').count();
        self.scanned += chunk.len();
        self.pos = offset;
        self.line
    }

    /// Bytes examined by all look-ups so far.
    pub fn scanned(&self) -> usize {
        self.scanned
    }
}

/// Reads three coordinates of node `node` and refuses non-finite ones (`nan`,
/// `inf`, or a number such as `1e400` that overflows `f64`) with the node and the
/// line: such a node would turn every tet around it into NaN volumes downstream.
pub(crate) fn finite_point(c: &mut Cursor<'_>, node: impl std::fmt::Display) -> Result<crate::Vec3> {
    point(c, node, None)
}

/// [`finite_point`] for formats with one node per line (`tag x y z`, the tag at
/// `line`): the three coordinates must be on that line, and nothing after them.
/// Read as a free token stream, a line short of a coordinate would take the next
/// line's tag as its z and shift every later node, and the error would surface
/// lines further on (as a duplicate tag, say) instead of at the short line.
pub(crate) fn finite_point_on_line(
    c: &mut Cursor<'_>,
    node: impl std::fmt::Display,
    line: usize,
) -> Result<crate::Vec3> {
    point_on_line(c, node, line, NodeLine::TAGGED)
}

/// What a node's line holds, for [`finite_point_on_line`] and
/// [`coordinates_line`]: the layout named in errors and the parametric
/// coordinates that follow x y z.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NodeLine {
    /// The line's layout as errors name it, e.g. `tag x y z`.
    pub layout: &'static str,
    /// Numbers after the three coordinates (Gmsh 4.1's parametric u, v, w).
    pub extra: usize,
}

impl NodeLine {
    /// `tag x y z` (Gmsh 1 and 2).
    const TAGGED: NodeLine = NodeLine {
        layout: "tag x y z",
        extra: 0,
    };
}

/// A node's coordinates on a line of their own (Gmsh 4.1's node blocks: the tags
/// first, then one `x y z` line per node, `x y z u [v [w]]` in parametric blocks):
/// the line starting at the next token holds exactly the coordinates `what` says,
/// else the error is at that line. Returns the point, finite, and the line.
pub(crate) fn coordinates_line(
    c: &mut Cursor<'_>,
    node: impl std::fmt::Display,
    what: NodeLine,
) -> Result<(crate::Vec3, usize)> {
    let line = c.line_of_next_token();
    Ok((point_on_line(c, node, line, what)?, line))
}

/// The point of `node` read from `line`, which must hold exactly what `what` says:
/// the three coordinates (finite), its extra numbers, nothing after them.
fn point_on_line(c: &mut Cursor<'_>, node: impl std::fmt::Display, line: usize, what: NodeLine) -> Result<crate::Vec3> {
    let p = point(c, &node, Some((line, what)))?;
    for k in 0..what.extra {
        if c.line_of_next_token() != line {
            return Err(c.err_at(
                line,
                format!(
                    "node {node}: the line ends after 3 + {k} of its 3 + {} numbers; a node line of this block is '{}'",
                    what.extra, what.layout
                ),
            ));
        }
        c.parse::<f64>("a parametric coordinate")?;
    }
    expect_line_end(c, &node, line, what)?;
    Ok(p)
}

/// An error at `line` if the next token is on it: the node's line holds more than
/// `what` says (a look-ahead on a copy of the cursor).
fn expect_line_end(c: &Cursor<'_>, node: impl std::fmt::Display, line: usize, what: NodeLine) -> Result<()> {
    if let Some((tok, l)) = c.clone().token()? {
        if l == line {
            let after = if what.extra == 0 {
                "the 3 coordinates"
            } else {
                "the node's numbers"
            };
            return Err(c.err_at(
                line,
                format!(
                    "node {node}: '{}' follows {after}; a node line is '{}'",
                    shorten(tok),
                    what.layout
                ),
            ));
        }
    }
    Ok(())
}

fn point(c: &mut Cursor<'_>, node: impl std::fmt::Display, line: Option<(usize, NodeLine)>) -> Result<crate::Vec3> {
    let mut p = [0.0; 3];
    for (k, v) in p.iter_mut().enumerate() {
        let axis = ["x", "y", "z"][k];
        if let Some((line, what)) = line {
            if c.line_of_next_token() != line {
                return Err(c.err_at(
                    line,
                    format!(
                        "node {node}: the line ends after {k} of the 3 coordinates; a node line is '{}'",
                        what.layout
                    ),
                ));
            }
        }
        let (tok, line) = c.expect_token(&format!("the {axis} coordinate of node {node}"))?;
        let x: f64 = parse_at(c.file(), line, tok, &format!("the {axis} coordinate of node {node}"))?;
        if !x.is_finite() {
            return Err(c.err_at(
                line,
                format!(
                    "node {node}: {axis} coordinate '{}' is not a finite number",
                    shorten(tok)
                ),
            ));
        }
        *v = x;
    }
    Ok(crate::Vec3::new(p[0], p[1], p[2]))
}
