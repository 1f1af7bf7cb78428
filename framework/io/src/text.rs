//! Helpers shared by the text readers: reading a file as text and pulling typed, whitespace-separated
//! tokens off one line, with errors that name the file, the line and the field that was expected.

use std::path::Path;
use std::str::{FromStr, SplitWhitespace};

use crate::error::{IoError, read_file};

/// Reads `path` as text. Bytes that are not valid UTF-8 are replaced (they can only appear in comments
/// or in tokens that then fail to parse as numbers, which is reported with the line number).
pub(crate) fn read_text(path: &Path) -> Result<String, IoError> {
    let bytes = read_file(path)?;
    Ok(match String::from_utf8(bytes) {
        Ok(text) => text,
        Err(error) => String::from_utf8_lossy(error.as_bytes()).into_owned(),
    })
}

/// Iterates over the lines of `text` as `(1-based line number, line without its end-of-line)`.
pub(crate) fn numbered_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().map(|(index, line)| (index + 1, line))
}

/// The whitespace-separated tokens of one line, consumed in order with typed accessors.
pub(crate) struct Tokens<'a> {
    path: &'a Path,
    line: usize,
    tokens: SplitWhitespace<'a>,
    taken: usize,
}

impl<'a> Tokens<'a> {
    /// Tokens of `text`, which is line `line` of `path`.
    pub(crate) fn new(path: &'a Path, line: usize, text: &'a str) -> Self {
        Self {
            path,
            line,
            tokens: text.split_whitespace(),
            taken: 0,
        }
    }

    /// The 1-based line number these tokens come from.
    pub(crate) fn line(&self) -> usize {
        self.line
    }

    /// An error at this line.
    pub(crate) fn error(&self, message: impl Into<String>) -> IoError {
        IoError::at_line(self.path, self.line, message)
    }

    /// The next token, or an error saying that `what` was expected.
    pub(crate) fn next_str(&mut self, what: &str) -> Result<&'a str, IoError> {
        match self.tokens.next() {
            Some(token) => {
                self.taken += 1;
                Ok(token)
            }
            None => Err(self.error(format!(
                "expected {what} as field {}, found end of line",
                self.taken + 1
            ))),
        }
    }

    /// The next token parsed as `T` (any `FromStr` type), naming `what` in the error.
    pub(crate) fn next_parsed<T: FromStr>(&mut self, what: &str) -> Result<T, IoError> {
        let token = self.next_str(what)?;
        token.parse::<T>().map_err(|_| {
            self.error(format!(
                "field {} ({what}): cannot parse \"{token}\" as a number",
                self.taken
            ))
        })
    }

    /// The next token as a finite `f64`; NaN and infinities are errors.
    pub(crate) fn next_f64(&mut self, what: &str) -> Result<f64, IoError> {
        let value: f64 = self.next_parsed(what)?;
        if value.is_finite() {
            Ok(value)
        } else {
            Err(self.error(format!("field {} ({what}) is not finite: {value}", self.taken)))
        }
    }

    /// The next `N` tokens as finite `f64`s.
    pub(crate) fn next_f64s<const N: usize>(&mut self, what: &str) -> Result<[f64; N], IoError> {
        let mut values = [0.0; N];
        for value in &mut values {
            *value = self.next_f64(what)?;
        }
        Ok(values)
    }

    /// The next token as a non-negative integer id.
    pub(crate) fn next_u64(&mut self, what: &str) -> Result<u64, IoError> {
        self.next_parsed(what)
    }

    /// Errors when tokens are left on the line (a `#` starts a trailing comment and is allowed).
    pub(crate) fn finish(&mut self) -> Result<(), IoError> {
        match self.tokens.next() {
            None => Ok(()),
            Some(token) if token.starts_with('#') => Ok(()),
            Some(token) => Err(self.error(format!(
                "unexpected extra field {} \"{token}\" (expected {} fields)",
                self.taken + 1,
                self.taken
            ))),
        }
    }
}

/// Formats `value` so that parsing the text gives back exactly the same `f64` (shortest round-trip form).
pub(crate) fn fmt_f64(value: f64) -> String {
    format!("{value}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_report_field_and_line() {
        let path = Path::new("t.txt");
        let mut tokens = Tokens::new(path, 4, "1.5 abc");
        assert_eq!(tokens.next_f64("x").ok(), Some(1.5));
        let err = tokens
            .next_f64("y")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert_eq!(
            err,
            "t.txt: line 4: field 2 (y): cannot parse \"abc\" as a number"
        );
        let mut tokens = Tokens::new(path, 2, "nan");
        assert!(tokens.next_f64("x").is_err());
        let mut tokens = Tokens::new(path, 3, "1 2 # comment");
        assert!(tokens.next_f64s::<2>("v").is_ok());
        assert!(tokens.finish().is_ok());
    }
}
