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
/// elements than the input has bytes left.
pub(crate) fn capacity(count: usize, remaining_bytes: usize) -> usize {
    count.min(remaining_bytes)
}

/// 1-based line of byte `offset` in `data`.
pub(crate) fn line_of(data: &[u8], offset: usize) -> usize {
    1 + data[..offset.min(data.len())].iter().filter(|&&b| b == b'\n').count()
}
