//! Step one of reading a DDF: XML text to a tree of raw elements that keep their source
//! positions. Nothing here knows what a domain or an item is; `validate` does.
//!
//! The tree is built with quick-xml's event reader rather than its serde deserializer:
//! serde would drop the line and column of each element, report only the first error and
//! silently accept or reject unknown elements depending on struct attributes. See
//! `docs/ddf.md`.

use std::borrow::Cow;
use std::cell::Cell;

use quick_xml::events::Event;
use quick_xml::Reader;

use super::Pos;

/// Deepest XML element nesting accepted. A valid DDF needs 3 + 17 levels at most (orchestra,
/// domain, set, 16 nested buses and a leaf item, plus its `<type>`); anything past this is
/// refused before it can exhaust memory or stack.
pub const MAX_XML_DEPTH: usize = 40;

/// One XML element with its position (the `<` of its start tag). Names, attribute values
/// and text borrow from the source where they can: a large DDF has tens of thousands of
/// elements, and allocating each piece dominated the parse time.
#[derive(Debug, Clone, PartialEq)]
pub struct RawElement<'a> {
    pub name: Cow<'a, str>,
    pub pos: Pos,
    pub attrs: Vec<RawAttr<'a>>,
    pub children: Vec<RawElement<'a>>,
    /// Concatenated character data directly inside this element.
    pub text: Cow<'a, str>,
    /// Position of the first non-whitespace character data, if any.
    pub text_pos: Option<Pos>,
}

/// One attribute; its position is the one of the element that carries it.
#[derive(Debug, Clone, PartialEq)]
pub struct RawAttr<'a> {
    pub name: Cow<'a, str>,
    pub value: Cow<'a, str>,
}

impl<'a> RawElement<'a> {
    fn new(name: Cow<'a, str>, pos: Pos) -> Self {
        RawElement { name, pos, attrs: Vec::new(), children: Vec::new(), text: Cow::Borrowed(""), text_pos: None }
    }

    /// The trimmed text content.
    pub fn text(&self) -> &str {
        self.text.trim()
    }

    /// The value of attribute `name`, if present.
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs.iter().find(|a| a.name == name).map(|a| &*a.value)
    }
}

/// Maps byte offsets to 1-based line and column (columns count characters).
///
/// The parser asks for positions in increasing order, so the index keeps a cursor and only
/// scans the bytes between the previous offset and the new one: linear in the file size
/// even for a DDF written on one line. An offset before the cursor rescans from the start.
#[derive(Debug)]
pub struct LineIndex<'a> {
    src: &'a str,
    cursor: Cell<Cursor>,
}

#[derive(Debug, Clone, Copy)]
struct Cursor {
    offset: usize,
    /// 1-based line of `offset`.
    line: u32,
    /// Characters between the start of the line and `offset`.
    col: u32,
}

const START: Cursor = Cursor { offset: 0, line: 1, col: 0 };

impl<'a> LineIndex<'a> {
    pub fn new(src: &'a str) -> Self {
        LineIndex { src, cursor: Cell::new(START) }
    }

    pub fn pos(&self, offset: usize) -> Pos {
        let offset = offset.min(self.src.len());
        let mut c = self.cursor.get();
        if offset < c.offset {
            c = START;
        }
        let chunk = &self.src.as_bytes()[c.offset..offset];
        // Characters are counted as bytes that do not continue a UTF-8 sequence, which also
        // works for an offset inside a character.
        let chars = |b: &[u8]| b.iter().filter(|&&x| x & 0xC0 != 0x80).count() as u32;
        match chunk.iter().rposition(|&x| x == b'\n') {
            Some(last) => {
                c.line += chunk.iter().filter(|&&x| x == b'\n').count() as u32;
                c.col = chars(&chunk[last + 1..]);
            }
            None => c.col += chars(chunk),
        }
        c.offset = offset;
        self.cursor.set(c);
        Pos { line: c.line, col: c.col + 1 }
    }
}

/// A fatal syntax error: where and what.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntaxError {
    pub pos: Pos,
    pub message: String,
}

fn err(pos: Pos, message: impl Into<String>) -> SyntaxError {
    SyntaxError { pos, message: message.into() }
}

/// Parses XML text into its root element.
pub fn parse(src: &str) -> Result<RawElement<'_>, SyntaxError> {
    let index = LineIndex::new(src);
    if src.trim().is_empty() {
        return Err(err(Pos { line: 1, col: 1 }, "the file is empty: expected an <orchestra> document"));
    }
    let mut reader = Reader::from_str(src);
    {
        let config = reader.config_mut();
        config.check_end_names = true;
        config.expand_empty_elements = false;
    }
    // Open elements; the bottom one becomes the root when it closes.
    let mut stack: Vec<RawElement> = Vec::new();
    let mut root: Option<RawElement> = None;
    loop {
        let before = reader.buffer_position() as usize;
        let event = match reader.read_event() {
            Ok(e) => e,
            Err(e) => {
                let at = index.pos(reader.error_position() as usize);
                return Err(err(at, format!("malformed XML: {}", printable(&e.to_string(), 200))));
            }
        };
        // Positions are computed only where needed: they cost more than the XML reading.
        let here = || index.pos(before);
        match event {
            Event::Start(start) | Event::Empty(start) if root.is_some() && stack.is_empty() => {
                let _ = start;
                return Err(err(here(), "content after the root element: a DDF has one <orchestra> root"));
            }
            Event::Start(ref start) | Event::Empty(ref start) => {
                let here = here();
                if stack.len() >= MAX_XML_DEPTH {
                    return Err(err(here, format!("XML elements nested deeper than {MAX_XML_DEPTH} levels")));
                }
                let mut element = RawElement::new(borrow(src, start.name().as_ref()), here);
                for attr in start.attributes() {
                    let attr = attr
                        .map_err(|e| err(here, format!("malformed attribute: {}", printable(&e.to_string(), 200))))?;
                    let value = attr.normalized_value(quick_xml::XmlVersion::Implicit1_0).map_err(|e| {
                        err(here, format!("malformed attribute value: {}", printable(&e.to_string(), 200)))
                    })?;
                    element.attrs.push(RawAttr { name: borrow(src, attr.key.as_ref()), value: borrow(src, &value) });
                }
                if matches!(event, Event::Empty(_)) {
                    close(element, &mut stack, &mut root);
                } else {
                    stack.push(element);
                }
            }
            Event::End(_) => {
                // check_end_names guarantees a matching open element.
                if let Some(element) = stack.pop() {
                    close(element, &mut stack, &mut root);
                }
            }
            Event::Text(text) => {
                let content = text.xml_content(quick_xml::XmlVersion::Implicit1_0);
                add_text(&mut stack, content, &index, before)?;
            }
            Event::CData(data) => {
                let content = data.xml_content(quick_xml::XmlVersion::Implicit1_0);
                add_text(&mut stack, content, &index, before)?;
            }
            Event::GeneralRef(reference) => {
                let resolved = match reference.resolve_char_ref() {
                    Ok(Some(c)) => c.to_string(),
                    Ok(None) => match quick_xml::escape::resolve_predefined_entity(&reference) {
                        Some(s) => s.to_string(),
                        None => return Err(err(here(), format!("unknown entity '&{};'", printable(&reference, 40)))),
                    },
                    Err(e) => {
                        return Err(err(
                            here(),
                            format!("malformed character reference: {}", printable(&e.to_string(), 200)),
                        ))
                    }
                };
                add_text(&mut stack, Cow::Owned(resolved), &index, before)?;
            }
            Event::DocType(_) => {
                return Err(err(here(), "DOCTYPE declarations are not supported in a DDF"));
            }
            Event::Decl(_) if src.get(..before).is_some_and(|s| !s.trim().is_empty()) => {
                return Err(err(here(), "the XML declaration <?xml …?> must come first in the file"));
            }
            Event::Decl(_) | Event::PI(_) | Event::Comment(_) => {}
            Event::Eof => break,
        }
    }
    if let Some(open) = stack.last() {
        let at = index.pos(src.len());
        return Err(err(
            at,
            format!(
                "unexpected end of file: <{}> opened at line {}, column {} is not closed",
                open.name, open.pos.line, open.pos.col
            ),
        ));
    }
    root.ok_or_else(|| err(Pos { line: 1, col: 1 }, "no XML element found: expected an <orchestra> document"))
}

/// `text` made fit for a one-line diagnostic: control characters (newlines included)
/// escaped, cut to `max` characters with an ellipsis. Library error messages and
/// user-written names or values can contain anything.
pub fn printable(text: &str, max: usize) -> String {
    let mut out = String::with_capacity(text.len().min(max * 2));
    for (i, c) in text.chars().enumerate() {
        if i == max {
            out.push('…');
            break;
        }
        if c.is_control() {
            out.extend(c.escape_debug());
        } else {
            out.push(c);
        }
    }
    out
}

/// `part` as a slice of `src` when it is one, else a copy. quick-xml hands out pieces of the
/// input, but with the lifetime of the event rather than of the input; this recovers the
/// longer borrow by position (safe code: a slice of `src` at the same address is the same
/// bytes).
fn borrow<'a>(src: &'a str, part: &str) -> Cow<'a, str> {
    let start = (part.as_ptr() as usize).wrapping_sub(src.as_ptr() as usize);
    match src.get(start..start.wrapping_add(part.len())) {
        Some(s) if s.as_ptr() == part.as_ptr() => Cow::Borrowed(s),
        _ => Cow::Owned(part.to_owned()),
    }
}

fn close<'a>(element: RawElement<'a>, stack: &mut [RawElement<'a>], root: &mut Option<RawElement<'a>>) {
    match stack.last_mut() {
        Some(parent) => parent.children.push(element),
        None => *root = Some(element),
    }
}

fn add_text<'a>(
    stack: &mut [RawElement<'a>],
    content: Cow<'a, str>,
    index: &LineIndex<'_>,
    offset: usize,
) -> Result<(), SyntaxError> {
    match stack.last_mut() {
        Some(parent) => {
            // Blanks before any content are trimmed anyway; skipping them saves an allocation
            // for every element that holds only child elements.
            if parent.text.is_empty() && content.trim().is_empty() {
                return Ok(());
            }
            if parent.text_pos.is_none() {
                if let Some(skip) = content.find(|c: char| !c.is_whitespace()) {
                    // Position of the first non-blank character (exact for unescaped text).
                    parent.text_pos = Some(index.pos(offset + skip));
                }
            }
            if parent.text.is_empty() {
                parent.text = content;
            } else {
                parent.text.to_mut().push_str(&content);
            }
            Ok(())
        }
        None => match content.find(|c: char| !c.is_whitespace()) {
            None => Ok(()),
            // Point at the text itself, not at the blank lines before it.
            Some(skip) => Err(err(index.pos(offset + skip), "text outside the root element")),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_are_one_based_lines_and_columns() {
        let idx = LineIndex::new("ab\ncdé\nx");
        assert_eq!(idx.pos(0), Pos { line: 1, col: 1 });
        assert_eq!(idx.pos(3), Pos { line: 2, col: 1 });
        assert_eq!(idx.pos(7), Pos { line: 2, col: 4 });
        assert_eq!(idx.pos(8), Pos { line: 3, col: 1 });
        // Backwards, and inside a character.
        assert_eq!(idx.pos(2), Pos { line: 1, col: 3 });
        assert_eq!(idx.pos(6), Pos { line: 2, col: 4 });
        assert_eq!(idx.pos(100), Pos { line: 3, col: 2 });
    }

    #[test]
    fn positions_on_one_long_line_take_linear_time() {
        let src = "<a>".repeat(200_000);
        let idx = LineIndex::new(&src);
        for i in 0..200_000 {
            assert_eq!(idx.pos(i * 3).col as usize, i * 3 + 1);
        }
    }

    #[test]
    fn tree_keeps_positions_text_and_attributes() {
        let root = parse("<a>\n  <b x=\"1 &amp; 2\">hi&lt;</b>\n  <c/>\n</a>").unwrap();
        assert_eq!(root.name, "a");
        assert_eq!(root.children.len(), 2);
        let b = &root.children[0];
        assert_eq!(b.pos, Pos { line: 2, col: 3 });
        assert_eq!(b.attr("x"), Some("1 & 2"));
        assert_eq!(b.text(), "hi<");
        assert_eq!(root.children[1].pos, Pos { line: 3, col: 3 });
    }

    #[test]
    fn syntax_errors_stay_on_one_line() {
        let e = parse("<a></\"\n\">").unwrap_err();
        assert!(!e.message.contains('\n'), "{}", e.message);
        assert_eq!(printable("a\nb\u{7f}cd", 4), "a\\nb\\u{7f}…");
    }

    #[test]
    fn unclosed_and_mismatched_elements_are_errors() {
        assert!(parse("<a><b></a>").unwrap_err().message.contains("malformed XML"));
        let e = parse("<a>\n<b>").unwrap_err();
        assert!(e.message.contains("<b> opened at line 2"), "{}", e.message);
    }
}
