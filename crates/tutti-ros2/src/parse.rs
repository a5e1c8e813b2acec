//! `.msg`, `.srv` and `.action` files read as ROS 2's `rosidl_adapter` reads them
//! (`rosidl_adapter/parser.py`, vendored in tests/ros2/rosidl/): the same lines are fields,
//! constants and comments, the same names and values are refused.
//!
//! A line is `TYPE NAME`, `TYPE NAME DEFAULT` or `TYPE NAME=VALUE` (a constant), with anything
//! after a `#` a comment; the comment lines at the top of a file are the file's. A type is a
//! primitive (`bool`, `byte`, `char`, `int8` … `uint64`, `float32`, `float64`, `string`,
//! `wstring`, `string<=N`), or a message, `PKG/Type` or `Type` of the file's own package
//! (ROS 2 has no special case for `Header`: a `.msg` names `std_msgs/Header`), followed by
//! `[N]` (an array of N), `[<=N]` (up to N) or `[]` (any number). A service file is a request
//! and a response separated by a line `---`; an action file a goal, a result and a feedback.
//! `time` and `duration`, which the parser takes for compatibility but rosidl makes no IDL
//! of, are refused here.

use crate::spec::{BaseType, Constant, Field, FieldType, Kind, MessageSpec, Primitive, Shape, TypeName};
use crate::value::Value;

/// A file that is not a valid interface: where, and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{line}: {problem}")]
pub struct ParseError {
    /// The file, as the caller names it (`std_msgs/msg/Header.msg`).
    pub file: String,
    /// 1-based; 0 for the file as a whole.
    pub line: usize,
    pub problem: Problem,
}

/// What is wrong with a line or a file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Problem {
    #[error("`{0}` is not `TYPE NAME`, `TYPE NAME DEFAULT` or `TYPE NAME=VALUE`")]
    Definition(String),
    #[error("invalid type `{ty}`: {why}")]
    Type { ty: String, why: &'static str },
    #[error("type `{0}` has no IDL type in ROS 2 (rosidl_adapter makes none of `time` and `duration`)")]
    Unsupported(String),
    #[error("invalid field name `{0}`: lowercase letters, digits and single underscores, starting with a letter and not ending with an underscore")]
    FieldName(String),
    #[error("invalid constant name `{0}`: uppercase letters, digits and single underscores, starting with a letter and not ending with an underscore")]
    ConstantName(String),
    #[error("invalid message name `{0}`: a capital letter, then letters and digits")]
    MessageName(String),
    #[error("invalid package name `{0}`: lowercase letters, digits and single underscores, starting with a letter")]
    PackageName(String),
    #[error("constant {name} has type `{ty}`; a constant is a primitive or a string")]
    ConstantType { name: String, ty: String },
    #[error("value `{value}` cannot be converted to type `{ty}`: {why}")]
    Value { ty: String, value: String, why: String },
    #[error("field {0} has a nested type, which cannot have a default value")]
    NestedDefault(String),
    #[error("field {0} is defined twice")]
    DuplicateField(String),
    #[error("constant {0} is defined twice")]
    DuplicateConstant(String),
    #[error("a service has one line `---` between its request and its response; found {0}")]
    ServiceSeparators(usize),
    #[error("an action has two lines `---` between its goal, result and feedback; found {0}")]
    ActionSeparators(usize),
}

/// The separator of a service's request and response, and of an action's parts.
const SEPARATOR: &str = "---";

/// One line of a file: its 1-based number and its text.
type Line<'a> = (usize, &'a str);

fn lines(text: &str) -> Vec<Line<'_>> {
    text.lines().enumerate().map(|(i, l)| (i + 1, l)).collect()
}

/// The message `PKG/msg/NAME` of a `.msg` file's text; `file` names it in errors.
pub fn parse_message(file: &str, package: &str, name: &str, text: &str) -> Result<MessageSpec, ParseError> {
    check_names(file, package, name)?;
    Part { file, package }.message(&TypeName::new(package, Kind::Msg, name), &lines(text))
}

/// The request and the response (`NAME_Request`, `NAME_Response`) of a `.srv` file.
pub fn parse_service(
    file: &str,
    package: &str,
    name: &str,
    text: &str,
) -> Result<(MessageSpec, MessageSpec), ParseError> {
    check_names(file, package, name)?;
    let all = lines(text);
    let parts = split(&all);
    let [request, response] = parts[..] else {
        return Err(ParseError { file: file.into(), line: 0, problem: Problem::ServiceSeparators(parts.len() - 1) });
    };
    let part = Part { file, package };
    let named = |suffix: &str| TypeName::new(package, Kind::Srv, &format!("{name}{suffix}"));
    Ok((part.message(&named("_Request"), request)?, part.message(&named("_Response"), response)?))
}

/// The goal, the result and the feedback (`NAME_Goal`, `NAME_Result`, `NAME_Feedback`) of an
/// `.action` file.
pub fn parse_action(file: &str, package: &str, name: &str, text: &str) -> Result<[MessageSpec; 3], ParseError> {
    check_names(file, package, name)?;
    let all = lines(text);
    let parts = split(&all);
    let [goal, result, feedback] = parts[..] else {
        return Err(ParseError { file: file.into(), line: 0, problem: Problem::ActionSeparators(parts.len() - 1) });
    };
    let part = Part { file, package };
    let named = |suffix: &str| TypeName::new(package, Kind::Action, &format!("{name}{suffix}"));
    Ok([
        part.message(&named("_Goal"), goal)?,
        part.message(&named("_Result"), result)?,
        part.message(&named("_Feedback"), feedback)?,
    ])
}

fn check_names(file: &str, package: &str, name: &str) -> Result<(), ParseError> {
    let problem = if !valid_package_name(package) {
        Problem::PackageName(package.to_string())
    } else if !valid_message_name(name) {
        Problem::MessageName(name.to_string())
    } else {
        return Ok(());
    };
    Err(ParseError { file: file.to_string(), line: 0, problem })
}

/// The lines between the lines that are exactly `---`.
fn split<'l, 'a>(lines: &'l [Line<'a>]) -> Vec<&'l [Line<'a>]> {
    lines.split(|(_, l)| *l == SEPARATOR).collect()
}

/// One message's lines being read.
#[derive(Debug, Clone, Copy)]
struct Part<'a> {
    file: &'a str,
    package: &'a str,
}

/// A field or a constant being read, which later comment lines may still add to.
#[derive(Debug)]
enum Element {
    Field(Field),
    Constant(Constant),
}

impl Element {
    fn comments(&mut self) -> &mut Vec<String> {
        match self {
            Element::Field(f) => &mut f.comments,
            Element::Constant(c) => &mut c.comments,
        }
    }
}

impl Part<'_> {
    fn error(&self, line: usize, problem: Problem) -> ParseError {
        ParseError { file: self.file.to_string(), line, problem }
    }

    /// `parse_message_string`.
    fn message(&self, name: &TypeName, lines: &[Line<'_>]) -> Result<MessageSpec, ParseError> {
        let lines: Vec<(usize, String)> = lines.iter().map(|(n, l)| (*n, l.replace('\t', " "))).collect();
        // The file's comments: its first lines that start with `#`.
        let top = lines.iter().take_while(|(_, l)| l.starts_with('#')).count();
        let file_comments = lines[..top].iter().map(|(_, l)| l.trim_start_matches('#').to_string()).collect();
        let mut elements: Vec<Element> = Vec::new();
        let mut pending: Vec<String> = Vec::new();
        for (n, line) in &lines[top..] {
            let mut line = line.trim_end();
            if line.is_empty() {
                continue;
            }
            if let Some(at) = line.find('#') {
                let comment = line[at..].trim_start_matches('#').to_string();
                line = &line[..at];
                if !line.is_empty() && line.trim().is_empty() {
                    // An indented comment belongs to the element before it.
                    if let Some(last) = elements.last_mut() {
                        last.comments().push(comment);
                    }
                    continue;
                }
                pending.push(comment);
                line = line.trim_end();
                if line.is_empty() {
                    continue;
                }
            }
            let mut element = self.element(*n, line)?;
            element.comments().append(&mut pending);
            elements.push(element);
        }
        let (mut fields, mut constants) = (Vec::new(), Vec::new());
        for e in elements {
            match e {
                Element::Field(f) => fields.push(f),
                Element::Constant(c) => constants.push(c),
            }
        }
        self.no_duplicates(&fields, &constants, &lines)?;
        let mut spec = MessageSpec::new(name.clone(), fields, constants);
        spec.comments = file_comments;
        Ok(spec)
    }

    fn no_duplicates(
        &self,
        fields: &[Field],
        constants: &[Constant],
        lines: &[(usize, String)],
    ) -> Result<(), ParseError> {
        let last_line = lines.last().map_or(0, |(n, _)| *n);
        for (i, f) in fields.iter().enumerate() {
            if fields[..i].iter().any(|g| g.name == f.name) {
                return Err(self.error(last_line, Problem::DuplicateField(f.name.clone())));
            }
        }
        for (i, c) in constants.iter().enumerate() {
            if constants[..i].iter().any(|d| d.name == c.name) {
                return Err(self.error(last_line, Problem::DuplicateConstant(c.name.clone())));
            }
        }
        Ok(())
    }

    /// One line without its comment: a field or a constant.
    fn element(&self, n: usize, line: &str) -> Result<Element, ParseError> {
        let (type_string, rest) = line.split_once(' ').unwrap_or((line, ""));
        let rest = rest.trim_start();
        if rest.is_empty() {
            return Err(self.error(n, Problem::Definition(line.to_string())));
        }
        if let Some((name, value)) = rest.split_once('=') {
            let (name, value) = (name.trim_end(), value.trim_start());
            return self.constant(type_string, name, value).map(Element::Constant).map_err(|p| self.error(n, p));
        }
        let (name, default) = rest.split_once(' ').unwrap_or((rest, ""));
        let default = default.trim_start();
        self.field(type_string, name, (!default.is_empty()).then_some(default))
            .map(Element::Field)
            .map_err(|p| self.error(n, p))
    }

    fn constant(&self, type_string: &str, name: &str, value: &str) -> Result<Constant, Problem> {
        let ty = match type_string {
            "string" => BaseType::String { bound: None },
            "wstring" => BaseType::WString { bound: None },
            "time" | "duration" => return Err(Problem::Unsupported(type_string.to_string())),
            t => match Primitive::from_msg_name(t) {
                Some(p) => BaseType::Primitive(p),
                None => return Err(Problem::ConstantType { name: name.to_string(), ty: t.to_string() }),
            },
        };
        if !valid_constant_name(name) {
            return Err(Problem::ConstantName(name.to_string()));
        }
        let value = primitive_value(&ty, value)?;
        Ok(Constant { name: name.to_string(), ty, value, comments: Vec::new() })
    }

    fn field(&self, type_string: &str, name: &str, default: Option<&str>) -> Result<Field, Problem> {
        let ty = field_type(type_string, self.package)?;
        if !valid_field_name(name) {
            return Err(Problem::FieldName(name.to_string()));
        }
        let default = default.map(|d| value(&ty, d, name)).transpose()?;
        Ok(Field { name: name.to_string(), ty, default, comments: Vec::new() })
    }
}

fn type_error(ty: &str, why: &'static str) -> Problem {
    Problem::Type { ty: ty.to_string(), why }
}

/// A field's type (`Type.__init__`): the shape, then the base type.
pub(crate) fn field_type(type_string: &str, package: &str) -> Result<FieldType, Problem> {
    let (base, shape) = match type_string.strip_suffix(']') {
        None => (type_string, Shape::Single),
        Some(open) => {
            let at = open.rfind('[').ok_or_else(|| type_error(type_string, "it ends with `]` but has no `[`"))?;
            let size = &open[at + 1..];
            let shape = if size.is_empty() {
                Shape::Unbounded
            } else {
                let (bounded, digits) = match size.strip_prefix("<=") {
                    Some(d) => (true, d),
                    None => (false, size),
                };
                let n = py_int(digits).and_then(|n| u64::try_from(n).ok()).filter(|&n| n > 0).ok_or_else(|| {
                    type_error(type_string, "an array's size is a whole number above 0, after `<=` for a bound")
                })?;
                if bounded {
                    Shape::Bounded(n)
                } else {
                    Shape::Array(n)
                }
            };
            (&open[..at], shape)
        }
    };
    Ok(FieldType { base: base_type(base, package)?, shape })
}

fn base_type(s: &str, package: &str) -> Result<BaseType, Problem> {
    if let Some(p) = Primitive::from_msg_name(s) {
        return Ok(BaseType::Primitive(p));
    }
    match s {
        "string" => return Ok(BaseType::String { bound: None }),
        "wstring" => return Ok(BaseType::WString { bound: None }),
        "time" | "duration" => return Err(Problem::Unsupported(s.to_string())),
        _ => {}
    }
    for (prefix, wide) in [("string<=", false), ("wstring<=", true)] {
        if let Some(bound) = s.strip_prefix(prefix) {
            let bound = py_int(bound)
                .and_then(|n| u64::try_from(n).ok())
                .filter(|&n| n > 0)
                .map(Some)
                .ok_or_else(|| type_error(s, "a string's bound is a whole number above 0"))?;
            return Ok(if wide { BaseType::WString { bound } } else { BaseType::String { bound } });
        }
    }
    let (pkg, name) = match s.split('/').collect::<Vec<_>>()[..] {
        [pkg, name] => (pkg, name),
        [name] => (package, name),
        _ => return Err(type_error(s, "a message type is `PKG/Type` or `Type`")),
    };
    if !valid_package_name(pkg) {
        return Err(Problem::PackageName(pkg.to_string()));
    }
    if !valid_message_name(name) {
        return Err(Problem::MessageName(name.to_string()));
    }
    Ok(BaseType::Nested(TypeName::new(pkg, Kind::Msg, name)))
}

/// A default value (`parse_value_string`): a primitive's, or an array's in `[…]`.
fn value(ty: &FieldType, text: &str, field: &str) -> Result<Value, Problem> {
    if matches!(ty.base, BaseType::Nested(_)) {
        return Err(Problem::NestedDefault(field.to_string()));
    }
    if ty.shape == Shape::Single {
        return primitive_value(&ty.base, text);
    }
    let bad = |why: String| Problem::Value { ty: type_text(ty), value: text.to_string(), why };
    let inner = text
        .strip_prefix('[')
        .and_then(|t| t.strip_suffix(']'))
        .ok_or_else(|| bad("an array's value starts with `[` and ends with `]`".into()))?;
    let elements: Vec<String> = match ty.base {
        BaseType::String { .. } | BaseType::WString { .. } => string_elements(inner).map_err(|w| bad(w.into()))?,
        _ if inner.is_empty() => Vec::new(),
        _ => inner.split(',').map(str::to_string).collect(),
    };
    match ty.shape {
        Shape::Array(n) if elements.len() as u64 != n => {
            return Err(bad(format!("the array has exactly {n} elements, not {}", elements.len())));
        }
        Shape::Bounded(n) if elements.len() as u64 > n => {
            return Err(bad(format!("the array has at most {n} elements, not {}", elements.len())));
        }
        _ => {}
    }
    elements
        .iter()
        .enumerate()
        .map(|(i, e)| primitive_value(&ty.base, e.trim()).map_err(|p| bad(format!("element {i}: {p}"))))
        .collect::<Result<Vec<_>, _>>()
        .map(Value::Array)
}

/// The elements of a string array's value (`parse_string_array_value_string`): quoted or
/// bare, separated by commas.
fn string_elements(mut s: &str) -> Result<Vec<String>, &'static str> {
    let mut out = Vec::new();
    loop {
        s = s.trim_start_matches(' ');
        if s.is_empty() {
            return Ok(out);
        }
        if s.starts_with(',') {
            return Err("an element is missing before a `,`");
        }
        let quote = s.chars().next().filter(|c| *c == '"' || *c == '\'');
        if let Some(q) = quote {
            let end = closing_quote(s, q).ok_or("a string is not closed by its quote")?;
            out.push(s[1..end].replace(&format!("\\{q}"), &q.to_string()));
            s = &s[end + 1..];
        } else {
            let end = s.find(',').unwrap_or(s.len());
            out.push(s[..end].to_string());
            s = &s[end..];
        }
        s = s.trim_start_matches(' ');
        s = s.strip_prefix(',').unwrap_or(s);
    }
}

/// Where the quote `q` that opens `s` is closed: the next `q` not after a backslash.
fn closing_quote(s: &str, q: char) -> Option<usize> {
    let bytes = s.as_bytes();
    (1..bytes.len()).find(|&i| bytes[i] == q as u8 && bytes[i - 1] != b'\\')
}

/// A primitive's or a string's value (`parse_primitive_value_string`).
pub(crate) fn primitive_value(base: &BaseType, text: &str) -> Result<Value, Problem> {
    let bad = |why: &str| Problem::Value { ty: base_text(base), value: text.to_string(), why: why.to_string() };
    match base {
        BaseType::Primitive(Primitive::Bool) => match text.to_lowercase().as_str() {
            "true" | "1" => Ok(Value::Bool(true)),
            "false" | "0" => Ok(Value::Bool(false)),
            _ => Err(bad("must be either `true` / `1` or `false` / `0`")),
        },
        BaseType::Primitive(p) if p.is_float() => py_float(text)
            .map(Value::Float)
            .ok_or_else(|| bad("must be a floating point number using `.` as the separator")),
        BaseType::Primitive(p) => {
            let (lo, hi) = p.int_range().unwrap_or((0, 0));
            let n = py_int(text)
                .filter(|n| (lo..=hi).contains(n))
                .ok_or_else(|| bad(&format!("must be a valid integer value >= {lo} and <= {hi}")))?;
            Ok(if p.is_signed() { Value::Int(n as i64) } else { Value::UInt(n as u64) })
        }
        BaseType::String { bound } | BaseType::WString { bound } => {
            let mut s = text.to_string();
            for q in ['"', '\''] {
                if s.len() >= 2 && s.starts_with(q) && s.ends_with(q) {
                    let inner = &s[1..s.len() - 1];
                    if closing_quote(&format!("{q}{inner}"), q).is_some() || inner.starts_with(q) {
                        return Err(bad("inner quotes of a string are escaped with a backslash"));
                    }
                    s = inner.replace(&format!("\\{q}"), &q.to_string());
                    break;
                }
            }
            if bound.is_some_and(|b| s.chars().count() as u64 > b) {
                return Err(bad("the string is longer than its bound"));
            }
            Ok(Value::String(s))
        }
        BaseType::Nested(_) => Err(bad("a nested type has no value")),
    }
}

/// An integer as Python's `int(s)`, then `int(s, 0)` (with a `0x`, `0o` or `0b` prefix), read it.
fn py_int(s: &str) -> Option<i128> {
    let s = s.trim();
    let (negative, body) = match s.as_bytes().first() {
        Some(b'-') => (true, &s[1..]),
        Some(b'+') => (false, &s[1..]),
        _ => (false, s),
    };
    let lower = body.to_ascii_lowercase();
    let (radix, digits) = match lower.get(..2) {
        Some("0x") => (16, &lower[2..]),
        Some("0o") => (8, &lower[2..]),
        Some("0b") => (2, &lower[2..]),
        _ => (10, lower.as_str()),
    };
    let digits = digits.strip_prefix('_').filter(|_| radix != 10).unwrap_or(digits);
    if digits.is_empty()
        || digits.starts_with('_')
        || digits.ends_with('_')
        || digits.contains("__")
        || !digits.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
    {
        return None;
    }
    let n = i128::from_str_radix(&digits.replace('_', ""), radix).ok()?;
    Some(if negative { -n } else { n })
}

/// A float as Python's `float(s)` reads it.
fn py_float(s: &str) -> Option<f64> {
    let s = s.trim();
    if s.starts_with('_') || s.ends_with('_') || s.contains("__") {
        return None;
    }
    let lower = s.replace('_', "").to_ascii_lowercase();
    lower.parse().ok()
}

/// A field's type as a `.msg` writes it.
fn type_text(ty: &FieldType) -> String {
    let base = base_text(&ty.base);
    match ty.shape {
        Shape::Single => base,
        Shape::Array(n) => format!("{base}[{n}]"),
        Shape::Bounded(n) => format!("{base}[<={n}]"),
        Shape::Unbounded => format!("{base}[]"),
    }
}

fn base_text(base: &BaseType) -> String {
    match base {
        BaseType::Primitive(p) => p.msg_name().to_string(),
        BaseType::String { bound: None } => "string".into(),
        BaseType::String { bound: Some(b) } => format!("string<={b}"),
        BaseType::WString { bound: None } => "wstring".into(),
        BaseType::WString { bound: Some(b) } => format!("wstring<={b}"),
        BaseType::Nested(n) => format!("{}/{}", n.package, n.name),
    }
}

/// `^(?!.*__)(?!.*_$)[a-z][a-z0-9_]*$`, or with `upper` the same in capitals.
fn snake(name: &str, upper: bool) -> bool {
    let mut chars = name.chars();
    let first_ok = chars.next().is_some_and(|c| if upper { c.is_ascii_uppercase() } else { c.is_ascii_lowercase() });
    let rest_ok = chars
        .all(|c| c == '_' || c.is_ascii_digit() || if upper { c.is_ascii_uppercase() } else { c.is_ascii_lowercase() });
    first_ok && rest_ok && !name.contains("__") && !name.ends_with('_')
}

fn valid_package_name(name: &str) -> bool {
    snake(name, false)
}

fn valid_field_name(name: &str) -> bool {
    snake(name, false)
}

/// `^[A-Z]([A-Z0-9_]?[A-Z0-9]+)*$`: capitals, digits and single underscores, not last.
fn valid_constant_name(name: &str) -> bool {
    snake(name, true)
}

/// `^[A-Z][A-Za-z0-9]*$` once the suffixes of the implicit types are taken off.
fn valid_message_name(name: &str) -> bool {
    let mut name = name.strip_prefix("Sample_").unwrap_or(name);
    for suffix in ["_Request", "_Response", "_Goal", "_Result", "_Feedback"] {
        name = name.strip_suffix(suffix).unwrap_or(name);
    }
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c.is_ascii_uppercase()) && chars.all(|c| c.is_ascii_alphanumeric())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(text: &str) -> Result<MessageSpec, ParseError> {
        parse_message("p/msg/M.msg", "p", "M", text)
    }

    fn problem(text: &str) -> Problem {
        msg(text).unwrap_err().problem
    }

    #[test]
    fn every_kind_of_field_with_its_defaults_and_comments() {
        let m = msg("# top\n# more\n\n\
                     int8 A = -3 # a constant\n\
                     string S=\"a#b\"\n\
                     bool flag true  # flag\n  # and more\n\
                     char c 0x41\n\
                     float32[3] v [1, 2.5, -3e2]\n\
                     string<=5[<=2] names [\"a,b\", 'c\\'d']\n\
                     Other o\n\
                     pkg/Name[] many\n\
                     uint64 big 18446744073709551615\n")
        .unwrap();
        assert_eq!(m.comments, [" top", " more"]);
        assert_eq!(m.constant("A"), Some(&Value::Int(-3)));
        assert_eq!(m.constants[0].comments, [" a constant"]);
        // A `#` ends the line even inside quotes, as rosidl reads it: the value is `"a`.
        assert_eq!(m.constant("S"), Some(&Value::String("\"a".into())));
        let f = |n: &str| m.field(n).unwrap();
        assert_eq!(f("flag").default, Some(Value::Bool(true)));
        assert_eq!(f("flag").comments, [" flag", " and more"]);
        assert_eq!(f("c").ty.base, BaseType::Primitive(Primitive::Char));
        assert_eq!(f("c").default, Some(Value::UInt(65)));
        assert_eq!(f("v").ty.shape, Shape::Array(3));
        assert_eq!(
            f("v").default,
            Some(Value::Array(vec![Value::Float(1.0), Value::Float(2.5), Value::Float(-300.0)]))
        );
        assert_eq!(f("names").ty, FieldType { base: BaseType::String { bound: Some(5) }, shape: Shape::Bounded(2) });
        assert_eq!(f("names").default, Some(Value::Array(vec!["a,b".into(), "c'd".into()])));
        assert_eq!(f("o").ty, FieldType::nested(TypeName::new("p", Kind::Msg, "Other")));
        assert_eq!(
            f("many").ty,
            FieldType { base: BaseType::Nested(TypeName::new("pkg", Kind::Msg, "Name")), shape: Shape::Unbounded }
        );
        assert_eq!(f("big").default, Some(Value::UInt(u64::MAX)));
        assert_eq!(m.fields.len(), 7);
    }

    #[test]
    fn an_empty_message_gets_rosidls_one_field() {
        let m = msg("# nothing\n\nuint8 X=1\n").unwrap();
        assert!(m.is_empty());
        assert_eq!(m.fields[0].name, "structure_needs_at_least_one_member");
        assert_eq!(m.constant("X"), Some(&Value::UInt(1)));
    }

    #[test]
    fn errors_name_the_file_the_line_and_the_problem() {
        let e = msg("int32 a\nfloat64 b 1.5.2\n").unwrap_err();
        assert_eq!(e.line, 2);
        assert!(e.to_string().starts_with("p/msg/M.msg:2: value `1.5.2` cannot be converted to type `float64`"), "{e}");
        assert_eq!(problem("int32"), Problem::Definition("int32".into()));
        assert_eq!(problem("int32 Bad"), Problem::FieldName("Bad".into()));
        assert_eq!(problem("int32 a__b"), Problem::FieldName("a__b".into()));
        assert_eq!(problem("int32 bad_=1"), Problem::ConstantName("bad_".into()));
        assert!(matches!(problem("int32[0] a"), Problem::Type { .. }));
        assert!(matches!(problem("int32[x] a"), Problem::Type { .. }));
        assert!(matches!(problem("string<=0 a"), Problem::Type { .. }));
        assert!(matches!(problem("a/b/C x"), Problem::Type { .. }));
        assert_eq!(problem("lower x"), Problem::MessageName("lower".into()));
        assert_eq!(problem("Bad_Pkg/X x"), Problem::PackageName("Bad_Pkg".into()));
        assert_eq!(problem("time t"), Problem::Unsupported("time".into()));
        assert_eq!(problem("int32[] X=1"), Problem::ConstantType { name: "X".into(), ty: "int32[]".into() });
        assert!(matches!(problem("uint8 a 256"), Problem::Value { .. }));
        assert!(matches!(problem("int8 a -129"), Problem::Value { .. }));
        assert!(matches!(problem("bool a yes"), Problem::Value { .. }));
        assert!(matches!(problem("int8[2] a [1]"), Problem::Value { .. }));
        assert!(matches!(problem("int8[<=1] a [1, 2]"), Problem::Value { .. }));
        assert!(matches!(problem("int8[] a 1"), Problem::Value { .. }));
        assert!(matches!(problem("string<=2 a abc"), Problem::Value { .. }));
        assert!(matches!(problem("string a \"x\"y\""), Problem::Value { .. }));
        assert_eq!(problem("Other o 1"), Problem::NestedDefault("o".into()));
        assert_eq!(problem("int8 a\nint8 a"), Problem::DuplicateField("a".into()));
        assert_eq!(problem("int8 A=1\nint8 A=2"), Problem::DuplicateConstant("A".into()));
        let e = parse_message("f", "p", "lower", "int8 a").unwrap_err();
        assert_eq!((e.line, e.problem), (0, Problem::MessageName("lower".into())));
    }

    #[test]
    fn numbers_as_python_reads_them() {
        assert_eq!(py_int(" 1_000 "), Some(1000));
        assert_eq!(py_int("-0x1F"), Some(-31));
        assert_eq!(py_int("0b101"), Some(5));
        assert_eq!(py_int("0o17"), Some(15));
        assert_eq!(py_int("010"), Some(10));
        for bad in ["", "1__0", "_1", "1_", "0x", "1.0", "--1"] {
            assert_eq!(py_int(bad), None, "{bad}");
        }
        assert_eq!(py_float("1_0.5"), Some(10.5));
        assert_eq!(py_float("-Inf"), Some(f64::NEG_INFINITY));
        assert!(py_float("nan").is_some_and(f64::is_nan));
        assert_eq!(py_float("1e-3"), Some(0.001));
        assert_eq!(py_float("1,5"), None);
    }

    #[test]
    fn services_and_actions_split_at_their_separators() {
        let (rq, rs) = parse_service("s.srv", "p", "S", "# req\nint8 a\n---\n# resp\nbool ok\n").unwrap();
        assert_eq!((rq.name.to_string(), rs.name.to_string()), ("p/srv/S_Request".into(), "p/srv/S_Response".into()));
        assert_eq!(rs.comments, [" resp"]);
        let (rq, _) = parse_service("s.srv", "p", "S", "---\n").unwrap();
        assert!(rq.is_empty());
        let e = parse_service("s.srv", "p", "S", "int8 a\n").unwrap_err();
        assert_eq!(e.problem, Problem::ServiceSeparators(0));
        let e = parse_service("s.srv", "p", "S", "---\nint8 a\n---\nbad line\n").unwrap_err();
        assert_eq!(e.problem, Problem::ServiceSeparators(2));
        let e = parse_action("a.action", "p", "A", "int8 g\n---\nint8 r\n---\nint8 x\nint8 y z\n").unwrap_err();
        assert_eq!(e.line, 6, "{e}");
        let [g, r, f] = parse_action("a.action", "p", "A", "int8 g\n---\nint8 r\n---\nint8 f\n").unwrap();
        assert_eq!([g.name.name, r.name.name, f.name.name], ["A_Goal", "A_Result", "A_Feedback"]);
        assert_eq!(parse_action("a.action", "p", "A", "---\n").unwrap_err().problem, Problem::ActionSeparators(1));
    }
}
