//! Step one of reading a DDF: XML text to a tree of raw elements that keep their source
//! positions. Nothing here knows what a domain or an item is; `validate` does.
//!
//! The tree is built with quick-xml's event reader rather than its serde deserializer:
//! serde would drop the line and column of each element, report only the first error and
//! silently accept or reject unknown elements depending on struct attributes. See
//! `docs/ddf.md`.

use std::borrow::Cow;
use std::cell::Cell;

use quick_xml::events::{BytesRef, BytesStart, Event};
use quick_xml::Reader;

use super::Pos;

/// Deepest XML element nesting accepted. A valid DDF needs 3 + 17 levels at most (orchestra,
/// domain, set, 16 nested buses and a leaf item, plus its `<type>`); anything past this is
/// refused before it can exhaust memory or stack.
pub const MAX_XML_DEPTH: usize = 40;

/// A parsed XML document: every element in one vector, in document order (each element is
/// followed by all its descendants), and every attribute in another. A large DDF has tens of
/// thousands of elements; one allocation for all of them, instead of a vector of children
/// and one of attributes per element, halved the time to build and to free the tree.
///
/// Names, attribute values and text borrow from the source where they can, for the same
/// reason. Read it through [`Document::root`].
#[derive(Debug, Clone)]
pub struct Document<'a> {
    src: &'a str,
    elements: Vec<Node<'a>>,
    attrs: Vec<RawAttr<'a>>,
}

/// One element in [`Document::elements`].
#[derive(Debug, Clone)]
struct Node<'a> {
    name: Cow<'a, str>,
    /// The `<` of the start tag, as a byte offset and as a line and column.
    offset: usize,
    pos: Pos,
    /// Concatenated character data directly inside this element.
    text: Cow<'a, str>,
    /// Byte offset of the first non-whitespace character data, if any. Only a diagnostic
    /// needs its line and column, so they are computed on demand (see
    /// [`RawElement::text_pos`]): doing it for every text cost as much as for every element.
    text_offset: Option<usize>,
    /// This element's attributes are `attrs[attrs.0..attrs.1]`.
    attrs: (usize, usize),
    /// One past the index of the last descendant: the first child, if any, is the next
    /// element, and each child's `end` is the index of its next sibling.
    end: usize,
}

impl Document<'_> {
    /// The root element.
    pub fn root(&self) -> RawElement<'_> {
        RawElement { doc: self, index: 0 }
    }
}

/// One XML element of a [`Document`]: a cheap handle (copy it freely) to its name,
/// position, attributes, text and children.
#[derive(Clone, Copy)]
pub struct RawElement<'a> {
    doc: &'a Document<'a>,
    index: usize,
}

/// One attribute; its position is the one of the element that carries it.
#[derive(Debug, Clone, PartialEq)]
pub struct RawAttr<'a> {
    pub name: Cow<'a, str>,
    pub value: Cow<'a, str>,
}

impl<'a> RawElement<'a> {
    fn node(&self) -> &'a Node<'a> {
        &self.doc.elements[self.index]
    }

    pub fn name(&self) -> &'a str {
        &self.node().name
    }

    /// Position of the `<` of the start tag.
    pub fn pos(&self) -> Pos {
        self.node().pos
    }

    /// The attributes, in document order.
    pub fn attrs(&self) -> &'a [RawAttr<'a>] {
        let (from, to) = self.node().attrs;
        &self.doc.attrs[from..to]
    }

    /// The value of attribute `name`, if present.
    pub fn attr(&self, name: &str) -> Option<&'a str> {
        self.attrs().iter().find(|a| a.name == name).map(|a| &*a.value)
    }

    /// The child elements, in document order.
    pub fn children(&self) -> Children<'a> {
        Children { doc: self.doc, next: self.index + 1, end: self.node().end }
    }

    pub fn has_children(&self) -> bool {
        self.node().end > self.index + 1
    }

    /// The trimmed text content.
    pub fn text(&self) -> &'a str {
        self.node().text.trim()
    }

    /// Position of the first non-whitespace character data, if any.
    pub fn text_pos(&self) -> Option<Pos> {
        let node = self.node();
        // Counted from the element's own position: the text is inside the element, so this
        // scans at most the element, whatever order positions are asked for in.
        let start = Cursor { offset: node.offset, line: node.pos.line, col: node.pos.col - 1 };
        let to = node.text_offset?.clamp(node.offset, self.doc.src.len());
        Some(LineIndex::starting_at(self.doc.src, start).pos(to))
    }
}

impl std::fmt::Debug for RawElement<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Not the whole document: the handle's own element.
        f.debug_struct("RawElement")
            .field("name", &self.name())
            .field("pos", &self.pos())
            .field("attrs", &self.attrs())
            .field("text", &self.text())
            .finish_non_exhaustive()
    }
}

/// The child elements of a [`RawElement`], in document order.
#[derive(Debug, Clone)]
pub struct Children<'a> {
    doc: &'a Document<'a>,
    next: usize,
    end: usize,
}

impl<'a> Iterator for Children<'a> {
    type Item = RawElement<'a>;

    fn next(&mut self) -> Option<RawElement<'a>> {
        if self.next >= self.end {
            return None;
        }
        let child = RawElement { doc: self.doc, index: self.next };
        // The next sibling comes after this child's descendants.
        self.next = self.doc.elements[self.next].end;
        Some(child)
    }
}

/// Maps byte offsets to 1-based line and column (columns count characters).
///
/// The parser asks for positions in increasing order, so the index keeps a cursor and only
/// looks at the bytes between the previous offset and the new one: linear in the file size
/// even for a DDF written on one line. An offset before the cursor rescans from the start.
#[derive(Debug)]
pub struct LineIndex<'a> {
    src: &'a str,
    cursor: Cell<Cursor>,
    /// Offset of the first newline at or after the cursor (the length when none is left).
    next_newline: Cell<usize>,
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

impl Cursor {
    fn pos(self) -> Pos {
        Pos { line: self.line, col: self.col + 1 }
    }
}

/// Characters are counted as bytes that do not continue a UTF-8 sequence, which also works
/// for an offset inside a character.
fn continues_no_character(b: u8) -> bool {
    b & 0xC0 != 0x80
}

/// The characters that start in `bytes`.
fn characters(bytes: &[u8]) -> u32 {
    let n = if bytes.is_ascii() { bytes.len() } else { bytes.iter().filter(|&&b| continues_no_character(b)).count() };
    n as u32
}

impl<'a> LineIndex<'a> {
    pub fn new(src: &'a str) -> Self {
        Self::starting_at(src, START)
    }

    /// An index whose cursor is already at `cursor` (on a character boundary), for offsets
    /// from there on.
    fn starting_at(src: &'a str, cursor: Cursor) -> Self {
        let index = LineIndex { src, cursor: Cell::new(cursor), next_newline: Cell::new(0) };
        index.next_newline.set(index.newline_from(cursor.offset));
        index
    }

    pub fn pos(&self, offset: usize) -> Pos {
        let offset = offset.min(self.src.len());
        let (mut c, mut newline) = (self.cursor.get(), self.next_newline.get());
        if offset < c.offset {
            (c, newline) = (START, self.newline_from(0));
        }
        // Whole lines first, then the characters of the last one. Newlines are searched for
        // with `find` and ASCII is recognised a word at a time: looking at every byte was 8 %
        // of the instructions of a parse and validation, and most steps (from one start tag
        // to the next) stay on one line and in ASCII.
        while newline < offset {
            c = Cursor { offset: newline + 1, line: c.line + 1, col: 0 };
            newline = self.newline_from(c.offset);
        }
        c.col += characters(&self.src.as_bytes()[c.offset..offset]);
        c.offset = offset;
        self.cursor.set(c);
        self.next_newline.set(newline);
        c.pos()
    }

    /// The first newline at or after `from`, which is on a character boundary (0, just after
    /// a newline, or an element's `<`).
    fn newline_from(&self, from: usize) -> usize {
        self.src[from..].find('\n').map_or(self.src.len(), |at| from + at)
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

/// Parses XML text into a document (with at least its root element).
pub fn parse(src: &str) -> Result<Document<'_>, SyntaxError> {
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
    let mut tree = Tree { doc: Document::sized_for(src), open: Vec::new(), index: &index };
    loop {
        let before = reader.buffer_position() as usize;
        let event = match reader.read_event() {
            Ok(Event::Eof) => break,
            Ok(e) => e,
            Err(e) => {
                let at = index.pos(reader.error_position() as usize);
                return Err(err(at, format!("malformed XML: {}", printable(&e.to_string(), 200))));
            }
        };
        tree.add(event, before)?;
    }
    tree.finish()
}

impl<'a> Document<'a> {
    /// An empty document of `src`, its vectors sized up front: growing them copied them
    /// several times. Every element starts with a `<` and every attribute has an `=`, so
    /// their counts bound the vectors (loosely: end tags count too), and capacity never
    /// written to costs only address space. A text full of `<` that is no document must
    /// still get its syntax error, hence `try_`. (Counted in byte-sized lanes, 255 bytes at a
    /// time, which the compiler vectorises; a plain count of matching bytes was not, and cost
    /// more than the copies it saved.)
    fn sized_for(src: &'a str) -> Self {
        let count = |needle: u8| -> usize {
            let lane = |c: &[u8]| c.iter().fold(0u8, |n, &b| n + u8::from(b == needle));
            src.as_bytes().chunks(255).map(|c| usize::from(lane(c))).sum()
        };
        let mut doc = Document { src, elements: Vec::new(), attrs: Vec::new() };
        let _ = doc.elements.try_reserve_exact(count(b'<'));
        let _ = doc.attrs.try_reserve_exact(count(b'='));
        doc
    }
}

/// A document being built from the reader's events.
struct Tree<'a, 'i> {
    doc: Document<'a>,
    /// Indices of the open elements, innermost last.
    open: Vec<usize>,
    index: &'i LineIndex<'a>,
}

impl<'a> Tree<'a, '_> {
    /// Adds what `event`, read from byte `before` on, says to the tree.
    fn add(&mut self, event: Event<'a>, before: usize) -> Result<(), SyntaxError> {
        let index = self.index;
        // Positions are computed only where needed: they cost more than the XML reading.
        let here = || index.pos(before);
        match event {
            Event::Start(_) | Event::Empty(_) if !self.doc.elements.is_empty() && self.open.is_empty() => {
                Err(err(here(), "content after the root element: a DDF has one <orchestra> root"))
            }
            Event::Start(ref start) => self.element(start, before, true),
            Event::Empty(ref start) => self.element(start, before, false),
            Event::End(_) => {
                // check_end_names guarantees a matching open element.
                if let Some(at) = self.open.pop() {
                    self.doc.elements[at].end = self.doc.elements.len();
                }
                Ok(())
            }
            Event::Text(text) => {
                let content = text.xml_content(quick_xml::XmlVersion::Implicit1_0);
                add_text(&mut self.doc, &self.open, content, index, before)
            }
            Event::CData(data) => {
                let content = data.xml_content(quick_xml::XmlVersion::Implicit1_0);
                add_text(&mut self.doc, &self.open, content, index, before)
            }
            Event::GeneralRef(reference) => {
                let resolved = resolve(&reference, here())?;
                add_text(&mut self.doc, &self.open, Cow::Owned(resolved), index, before)
            }
            Event::DocType(_) => Err(err(here(), "DOCTYPE declarations are not supported in a DDF")),
            Event::Decl(_) if self.doc.src.get(..before).is_some_and(|s| !s.trim().is_empty()) => {
                Err(err(here(), "the XML declaration <?xml …?> must come first in the file"))
            }
            Event::Decl(_) | Event::PI(_) | Event::Comment(_) | Event::Eof => Ok(()),
        }
    }

    /// An element with its attributes, from its start tag (`open`: its content and end tag
    /// follow) or its empty-element tag, read from byte `before` on.
    fn element(&mut self, start: &BytesStart<'a>, before: usize, open: bool) -> Result<(), SyntaxError> {
        let (src, here) = (self.doc.src, self.index.pos(before));
        if self.open.len() >= MAX_XML_DEPTH {
            return Err(err(here, format!("XML elements nested deeper than {MAX_XML_DEPTH} levels")));
        }
        let first_attr = self.doc.attrs.len();
        for attr in start.attributes() {
            let attr =
                attr.map_err(|e| err(here, format!("malformed attribute: {}", printable(&e.to_string(), 200))))?;
            let value = attr
                .normalized_value(quick_xml::XmlVersion::Implicit1_0)
                .map_err(|e| err(here, format!("malformed attribute value: {}", printable(&e.to_string(), 200))))?;
            self.doc.attrs.push(RawAttr { name: borrow(src, attr.key.as_ref()), value: borrow(src, &value) });
        }
        let at = self.doc.elements.len();
        self.doc.elements.push(Node {
            name: borrow(src, start.name().as_ref()),
            offset: before,
            pos: here,
            text: Cow::Borrowed(""),
            text_offset: None,
            attrs: (first_attr, self.doc.attrs.len()),
            // An empty element ends here; an open one when its end tag comes.
            end: at + 1,
        });
        if open {
            self.open.push(at);
        }
        Ok(())
    }

    /// The document, once the input has ended: every element closed, and at least one.
    fn finish(self) -> Result<Document<'a>, SyntaxError> {
        let Tree { doc, open, index } = self;
        if let Some(&innermost) = open.last() {
            let at = index.pos(doc.src.len());
            let open = &doc.elements[innermost];
            return Err(err(
                at,
                format!(
                    "unexpected end of file: <{}> opened at line {}, column {} is not closed",
                    open.name, open.pos.line, open.pos.col
                ),
            ));
        }
        if doc.elements.is_empty() {
            return Err(err(Pos { line: 1, col: 1 }, "no XML element found: expected an <orchestra> document"));
        }
        Ok(doc)
    }
}

/// The text an entity or character reference (at `at`) stands for, or what is wrong with it.
fn resolve(reference: &BytesRef<'_>, at: Pos) -> Result<String, SyntaxError> {
    match reference.resolve_char_ref() {
        Ok(Some(c)) => Ok(c.to_string()),
        Ok(None) => match quick_xml::escape::resolve_predefined_entity(reference) {
            Some(s) => Ok(s.to_string()),
            None => Err(err(at, format!("unknown entity '&{};'", printable(reference, 40)))),
        },
        Err(e) => Err(err(at, format!("malformed character reference: {}", printable(&e.to_string(), 200)))),
    }
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

fn add_text<'a>(
    doc: &mut Document<'a>,
    open: &[usize],
    content: Cow<'a, str>,
    index: &LineIndex<'_>,
    offset: usize,
) -> Result<(), SyntaxError> {
    match open.last() {
        Some(&at) => {
            let parent = &mut doc.elements[at];
            // Blanks before any content are trimmed anyway; skipping them saves an allocation
            // for every element that holds only child elements. (Most are indentation: ASCII
            // blanks, recognised without decoding characters.)
            let blank = |s: &str| s.bytes().all(|b| matches!(b, b' ' | b'\n' | b'\t' | b'\r')) || s.trim().is_empty();
            if parent.text.is_empty() && blank(&content) {
                return Ok(());
            }
            if parent.text_offset.is_none() {
                if let Some(skip) = content.find(|c: char| !c.is_whitespace()) {
                    // The first non-blank character (exact for unescaped text).
                    parent.text_offset = Some(offset + skip);
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
        let doc = parse("<a>\n  <b x=\"1 &amp; 2\">hi&lt;</b>\n  <c/>\n</a>").unwrap();
        let root = doc.root();
        assert_eq!(root.name(), "a");
        let children: Vec<_> = root.children().collect();
        assert_eq!(children.len(), 2);
        let b = children[0];
        assert_eq!(b.pos(), Pos { line: 2, col: 3 });
        assert_eq!(b.attr("x"), Some("1 & 2"));
        assert_eq!(b.text(), "hi<");
        assert_eq!(b.text_pos(), Some(Pos { line: 2, col: 20 }));
        assert_eq!(children[1].pos(), Pos { line: 3, col: 3 });
    }

    #[test]
    fn text_positions_are_found_after_children_and_lines() {
        let doc = parse("<a>\r\n  <b>x</b>\n\n é\ty </a>").unwrap();
        let a = doc.root();
        assert_eq!(a.text(), "é\ty");
        assert_eq!(a.text_pos(), Some(Pos { line: 4, col: 2 }));
        assert_eq!(a.children().next().unwrap().text_pos(), Some(Pos { line: 2, col: 6 }));
        assert_eq!(parse("<a/>").unwrap().root().text_pos(), None);
    }

    #[test]
    fn children_skip_their_siblings_descendants() {
        let doc = parse("<a><b><c/><d>t<e/></d></b><f/>x</a>").unwrap();
        fn names(el: RawElement<'_>) -> Vec<&str> {
            el.children().map(|c| c.name()).collect()
        }
        let root = doc.root();
        assert_eq!(names(root), ["b", "f"]);
        assert_eq!(root.text(), "x");
        let b = root.children().next().unwrap();
        assert_eq!(names(b), ["c", "d"]);
        let d = b.children().nth(1).unwrap();
        assert_eq!((names(d), d.text()), (vec!["e"], "t"));
        assert!(d.has_children() && !d.children().next().unwrap().has_children());
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
