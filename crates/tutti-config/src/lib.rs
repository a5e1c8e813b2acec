//! The one reader of tutti's JSON5 files: the gateway's config file (`--config
//! gateway.json5`, docs/gateway.md) and the launch file (`tutti run FILE`, docs/run.md), whose
//! `gateway` key is the config file again.
//!
//! Both are read with serde into types that refuse unknown keys and check every value where
//! it stands, so that each mistake is reported as `FILE:LINE:COLUMN: message` ([`Error`]):
//!
//! * [`load`] and [`from_str`]: a file or a text read into a type. The text's nesting is
//!   checked first, by a scan that recurses nowhere: json5's parser recurses once per level,
//!   and a file nested thousands deep would overflow the stack ([`MAX_NESTING`]). A syntax
//!   error shows its line with a caret under the place.
//! * [`de`]: serde helpers that check a value where it stands (a string parsed, a number in
//!   range, any value passed through a check), so that the check's error gets the value's
//!   line and column.

use std::path::Path;

use serde::Deserialize;

pub mod de;
pub mod sections;

/// The deepest nesting of objects and arrays a file may have.
pub const MAX_NESTING: usize = 32;

/// What kind of file is read, for messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Kind {
    /// What it is called: `gateway config`, `launch file`.
    pub name: &'static str,
    /// How many levels of nesting it needs (said when a file goes deeper than [`MAX_NESTING`]).
    pub levels: usize,
}

/// A file that cannot be read, or a mistake at a place of it. Each names the file, and the
/// line and column (1-based, in characters) where json5 can place the mistake.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The file cannot be read.
    #[error("{file}: cannot read the {kind}: {error}")]
    Read { file: String, kind: &'static str, error: std::io::Error },
    /// Not JSON5: what was expected at the place, and the line it is on.
    #[error("{file}:{line}:{column}: syntax error ({expected}) here:\n  {text}\n  {}", caret(*.column))]
    Syntax { file: String, line: usize, column: usize, expected: String, text: String },
    /// Objects and arrays nested deeper than [`MAX_NESTING`], at the first bracket too deep.
    #[error("{file}:{line}:{column}: nested more than {MAX_NESTING} deep (a {kind} needs {levels} levels)")]
    TooDeep { file: String, line: usize, column: usize, kind: &'static str, levels: usize },
    /// An unknown key, a missing one, a value of the wrong type or one its check refuses,
    /// where it stands (None: a place json5 does not know).
    #[error("{file}{}: {message}", place(*.position))]
    Value { file: String, position: Option<(usize, usize)>, message: String },
}

impl Error {
    /// The file, as it was named.
    pub fn file(&self) -> &str {
        match self {
            Error::Read { file, .. }
            | Error::Syntax { file, .. }
            | Error::TooDeep { file, .. }
            | Error::Value { file, .. } => file,
        }
    }

    /// The line and column of the mistake, where it has one.
    pub fn position(&self) -> Option<(usize, usize)> {
        match self {
            Error::Read { .. } => None,
            Error::Syntax { line, column, .. } | Error::TooDeep { line, column, .. } => Some((*line, *column)),
            Error::Value { position, .. } => *position,
        }
    }
}

fn caret(column: usize) -> String {
    format!("{:>column$}", "^")
}

fn place(position: Option<(usize, usize)>) -> String {
    position.map(|(l, c)| format!(":{l}:{c}")).unwrap_or_default()
}

/// Reads the file at `path` into a `T`; errors name it as `path` is displayed.
pub fn load<T: serde::de::DeserializeOwned>(path: &Path, kind: Kind) -> Result<T, Error> {
    let file = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|error| Error::Read { file: file.clone(), kind: kind.name, error })?;
    from_str(&text, &file, kind)
}

/// Reads `text`, the contents of `file` (named in errors), into a `T`.
pub fn from_str<'a, T: Deserialize<'a>>(text: &'a str, file: &str, kind: Kind) -> Result<T, Error> {
    if let Some((line, column)) = too_deep(text) {
        return Err(Error::TooDeep { file: file.to_string(), line, column, kind: kind.name, levels: kind.levels });
    }
    json5::from_str::<T>(text).map_err(|e| positioned(e, text, file))
}

/// json5's error as ours. A syntax error's message is pest's drawing of the line (` --> 1:8`,
/// the line, an underline); its last line says what was expected, and the drawing is made
/// again here, shorter.
fn positioned(error: json5::Error, text: &str, file: &str) -> Error {
    let json5::Error::Message { msg, location } = error;
    let file = file.to_string();
    let pest = msg.trim_start().starts_with("-->");
    let expected = msg.lines().rev().find_map(|l| l.trim().strip_prefix("= ")).filter(|_| pest);
    match (expected, location) {
        (Some(expected), Some(l)) => Error::Syntax {
            file,
            line: l.line,
            column: l.column,
            expected: expected.to_string(),
            text: text.lines().nth(l.line.saturating_sub(1)).unwrap_or_default().to_string(),
        },
        (Some(expected), None) => Error::Value { file, position: None, message: format!("syntax error: {expected}") },
        (None, location) => Error::Value { file, position: location.map(|l| (l.line, l.column)), message: msg },
    }
}

/// The line and column (1-based, in characters) of the first `{` or `[` that opens a level
/// deeper than [`MAX_NESTING`], if there is one. Strings and comments are skipped as JSON5
/// writes them; what is not JSON5 is left to the parser.
fn too_deep(text: &str) -> Option<(usize, usize)> {
    #[derive(Clone, Copy, PartialEq)]
    enum In {
        Code,
        Str(char),
        Escape(char),
        LineComment,
        BlockComment,
    }
    let (mut state, mut depth, mut line, mut col) = (In::Code, 0usize, 1usize, 0usize);
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '\n' {
            (line, col) = (line + 1, 0);
        } else {
            col += 1;
        }
        state = match (state, c) {
            (In::Code, '"' | '\'') => In::Str(c),
            (In::Code, '/') if chars.peek() == Some(&'/') => In::LineComment,
            (In::Code, '/') if chars.peek() == Some(&'*') => {
                chars.next();
                col += 1;
                In::BlockComment
            }
            (In::Code, '{' | '[') => {
                depth += 1;
                if depth > MAX_NESTING {
                    return Some((line, col));
                }
                In::Code
            }
            (In::Code, '}' | ']') => {
                depth = depth.saturating_sub(1);
                In::Code
            }
            (In::Str(q), '\\') => In::Escape(q),
            (In::Str(q), c) if c == q => In::Code,
            (In::Escape(q), _) => In::Str(q),
            (In::LineComment, '\n') => In::Code,
            (In::BlockComment, '*') if chars.peek() == Some(&'/') => {
                chars.next();
                col += 1;
                In::Code
            }
            (s, _) => s,
        };
    }
    None
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    const KIND: Kind = Kind { name: "test file", levels: 2 };

    fn read(text: &str) -> Result<BTreeMap<String, serde::de::IgnoredAny>, Error> {
        from_str(text, "t.json5", KIND)
    }

    #[test]
    fn nesting_deeper_than_the_limit_is_refused_where_it_goes_too_deep() {
        for (open, close) in [("[", "]"), ("{a:", "}")] {
            let text = format!("{{ k:\n {}{} }}", open.repeat(100_000), close.repeat(100_000));
            let e = read(&text).unwrap_err();
            let col = 2 + (MAX_NESTING - 1) * open.len();
            assert_eq!(e.position(), Some((2, col)));
            assert_eq!(
                e.to_string(),
                format!("t.json5:2:{col}: nested more than {MAX_NESTING} deep (a test file needs 2 levels)")
            );
        }
        // Brackets in strings and comments do not count; the limit itself is parsed.
        let quoted = format!(
            "{{ k: \"{}\", // {}\n /* {} */ q: '{}' }}",
            "[".repeat(99),
            "{".repeat(99),
            "[".repeat(99),
            "\\'[".repeat(99)
        );
        assert_eq!(read(&quoted).unwrap().len(), 2);
        let at_limit = format!("{{ k: {}{} }}", "[".repeat(MAX_NESTING - 1), "]".repeat(MAX_NESTING - 1));
        read(&at_limit).unwrap();
    }

    #[test]
    fn a_syntax_error_shows_its_line_with_a_caret() {
        let e = read("{ a: 1,\n  b: 2 ] }").unwrap_err();
        let Error::Syntax { line: 2, column, .. } = e else { panic!("{e:?}") };
        let text = e.to_string();
        assert!(text.starts_with(&format!("t.json5:2:{column}: syntax error (expected ")), "{text}");
        assert!(text.ends_with(&format!(") here:\n    b: 2 ] }}\n  {:>column$}", "^")), "{text}");
    }

    #[test]
    fn a_type_error_names_the_value_where_it_stands_and_a_missing_file_is_named() {
        #[derive(Debug, Deserialize)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct Keys {
            s: String,
        }
        let e = from_str::<Keys>("{\n  s: 1 }", "t.json5", KIND).unwrap_err();
        assert_eq!(e.position(), Some((2, 6)));
        assert_eq!(e.to_string(), "t.json5:2:6: invalid type: integer `1`, expected a string");
        let e = from_str::<Keys>("{ m: 1 }", "t.json5", KIND).unwrap_err();
        assert!(e.to_string().starts_with("t.json5:1:3: unknown field `m`"), "{e}");
        let e = load::<Keys>(Path::new("/nonexistent/t.json5"), KIND).unwrap_err();
        assert!(e.to_string().starts_with("/nonexistent/t.json5: cannot read the test file: "), "{e}");
        assert_eq!((e.file(), e.position()), ("/nonexistent/t.json5", None));
    }
}
