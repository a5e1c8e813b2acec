//! Step one of reading a DDF: XML text to a tree of raw elements that keep their source
//! positions. Nothing here knows what a domain or an item is; `validate` does.
//!
//! The tree is built with quick-xml's event reader rather than its serde deserializer:
//! serde would drop the line and column of each element, report only the first error and
//! silently accept or reject unknown elements depending on struct attributes. See
//! `docs/ddf.md`.

use quick_xml::events::Event;
use quick_xml::Reader;

use super::Pos;

/// Deepest XML element nesting accepted. A valid DDF needs 3 + 17 levels at most (orchestra,
/// domain, set, 16 nested buses and a leaf item, plus its `<type>`); anything past this is
/// refused before it can exhaust memory or stack.
pub const MAX_XML_DEPTH: usize = 40;

/// One XML element with its position (the `<` of its start tag).
#[derive(Debug, Clone, PartialEq)]
pub struct RawElement {
    pub name: String,
    pub pos: Pos,
    pub attrs: Vec<RawAttr>,
    pub children: Vec<RawElement>,
    /// Concatenated character data directly inside this element.
    pub text: String,
    /// Position of the first non-whitespace character data, if any.
    pub text_pos: Option<Pos>,
}

/// One attribute; its position is the one of the element that carries it.
#[derive(Debug, Clone, PartialEq)]
pub struct RawAttr {
    pub name: String,
    pub value: String,
}

impl RawElement {
    fn new(name: String, pos: Pos) -> Self {
        RawElement { name, pos, attrs: Vec::new(), children: Vec::new(), text: String::new(), text_pos: None }
    }

    /// The trimmed text content.
    pub fn text(&self) -> &str {
        self.text.trim()
    }

    /// The value of attribute `name`, if present.
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs.iter().find(|a| a.name == name).map(|a| a.value.as_str())
    }
}

/// Maps byte offsets to 1-based line and column (columns count characters).
#[derive(Debug)]
pub struct LineIndex<'a> {
    src: &'a str,
    starts: Vec<usize>,
}

impl<'a> LineIndex<'a> {
    pub fn new(src: &'a str) -> Self {
        let mut starts = vec![0];
        starts.extend(src.match_indices('\n').map(|(i, _)| i + 1));
        LineIndex { src, starts }
    }

    pub fn pos(&self, offset: usize) -> Pos {
        let offset = offset.min(self.src.len());
        let line = self.starts.partition_point(|&s| s <= offset).max(1);
        let start = self.starts[line - 1];
        let col = self.src.get(start..offset).map_or(offset - start, |s| s.chars().count()) + 1;
        Pos { line: line as u32, col: col as u32 }
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
pub fn parse(src: &str) -> Result<RawElement, SyntaxError> {
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
                return Err(err(at, format!("malformed XML: {e}")));
            }
        };
        let here = index.pos(before);
        match event {
            Event::Start(start) | Event::Empty(start) if root.is_some() && stack.is_empty() => {
                let _ = start;
                return Err(err(here, "content after the root element: a DDF has one <orchestra> root"));
            }
            Event::Start(ref start) | Event::Empty(ref start) => {
                if stack.len() >= MAX_XML_DEPTH {
                    return Err(err(here, format!("XML elements nested deeper than {MAX_XML_DEPTH} levels")));
                }
                let mut element = RawElement::new(start.name().as_ref().to_string(), here);
                for attr in start.attributes() {
                    let attr = attr.map_err(|e| err(here, format!("malformed attribute: {e}")))?;
                    let value = attr
                        .normalized_value(quick_xml::XmlVersion::Implicit1_0)
                        .map_err(|e| err(here, format!("malformed attribute value: {e}")))?;
                    element.attrs.push(RawAttr { name: attr.key.as_ref().to_string(), value: value.into_owned() });
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
                add_text(&mut stack, &content, here, &index, before)?;
            }
            Event::CData(data) => {
                let content = data.xml_content(quick_xml::XmlVersion::Implicit1_0);
                add_text(&mut stack, &content, here, &index, before)?;
            }
            Event::GeneralRef(reference) => {
                let resolved = match reference.resolve_char_ref() {
                    Ok(Some(c)) => c.to_string(),
                    Ok(None) => match quick_xml::escape::resolve_predefined_entity(&reference) {
                        Some(s) => s.to_string(),
                        None => return Err(err(here, format!("unknown entity '&{};'", &*reference))),
                    },
                    Err(e) => return Err(err(here, format!("malformed character reference: {e}"))),
                };
                add_text(&mut stack, &resolved, here, &index, before)?;
            }
            Event::DocType(_) => {
                return Err(err(here, "DOCTYPE declarations are not supported in a DDF"));
            }
            Event::Decl(_) | Event::PI(_) | Event::Comment(_) => {}
            Event::Eof => break,
        }
    }
    if let Some(open) = stack.last() {
        let at = index.pos(src.len());
        return Err(err(
            at,
            format!("unexpected end of file: <{}> opened at line {}, column {} is not closed", open.name, open.pos.line, open.pos.col),
        ));
    }
    root.ok_or_else(|| err(Pos { line: 1, col: 1 }, "no XML element found: expected an <orchestra> document"))
}

fn close(element: RawElement, stack: &mut [RawElement], root: &mut Option<RawElement>) {
    match stack.last_mut() {
        Some(parent) => parent.children.push(element),
        None => *root = Some(element),
    }
}

fn add_text(stack: &mut [RawElement], content: &str, here: Pos, index: &LineIndex<'_>, offset: usize) -> Result<(), SyntaxError> {
    match stack.last_mut() {
        Some(parent) => {
            if parent.text_pos.is_none() {
                if let Some(skip) = content.find(|c: char| !c.is_whitespace()) {
                    // Position of the first non-blank character (exact for unescaped text).
                    parent.text_pos = Some(index.pos(offset + skip));
                }
            }
            parent.text.push_str(content);
            Ok(())
        }
        None if content.trim().is_empty() => Ok(()),
        None => Err(err(here, "text outside the root element")),
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
    fn unclosed_and_mismatched_elements_are_errors() {
        assert!(parse("<a><b></a>").unwrap_err().message.contains("malformed XML"));
        let e = parse("<a>\n<b>").unwrap_err();
        assert!(e.message.contains("<b> opened at line 2"), "{}", e.message);
    }
}
