//! The SSD and SSV files as trees of elements with their namespaces resolved and their
//! positions kept. The text is read by the core's positioned XML reader (quick-xml's event
//! reader: `tutti_core::ddf::raw`), as the DDF and `modelDescription.xml` are, rather than by
//! serde: every element keeps its line and column for the messages, and an element tutti does
//! not know is seen (and refused where it stands) instead of silently dropped.

use tutti_core::ddf::raw;
use tutti_core::ddf::Pos;

use crate::SspError;

/// The namespaces of SSP 1.0 and 2.0, by the prefix the standard gives them.
pub const SSD1: &str = "http://ssp-standard.org/SSP1/SystemStructureDescription";
pub const SSC1: &str = "http://ssp-standard.org/SSP1/SystemStructureCommon";
pub const SSV1: &str = "http://ssp-standard.org/SSP1/SystemStructureParameterValues";
pub const SSD2: &str = "http://ssp-standard.org/SSP2/SystemStructureDescription";
pub const SSC2: &str = "http://ssp-standard.org/SSP2/SystemStructureCommon";
pub const SSV2: &str = "http://ssp-standard.org/SSP2/SystemStructureParameterValues";

/// Which vocabulary an element belongs to, whatever the version.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ns {
    Ssd,
    Ssc,
    Ssv,
    /// Another namespace (SSM, SSB, a tool's annotations) or none.
    Other,
}

/// One element: its vocabulary, local name, position, attributes, children and text.
#[derive(Debug, Clone)]
pub struct Node {
    pub ns: Ns,
    /// The namespace URI (empty for none).
    pub uri: String,
    pub name: String,
    /// The name as written (`ssd:System`), for messages.
    pub qname: String,
    pub pos: Pos,
    pub attrs: Vec<(String, String)>,
    pub children: Vec<Node>,
    pub text: String,
}

impl Node {
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }

    /// Whether it is `ns:name`.
    pub fn is(&self, ns: Ns, name: &str) -> bool {
        self.ns == ns && self.name == name
    }
}

/// Parses `text`, named `file` in messages, into its root element.
pub fn parse(text: &str, file: &str) -> Result<Node, SspError> {
    let doc = raw::parse(text).map_err(|e| SspError::At {
        file: file.to_string(),
        line: e.pos.line,
        col: e.pos.col,
        message: e.message,
    })?;
    let mut scope: Vec<(String, String)> = Vec::new();
    Ok(node(doc.root(), &mut scope))
}

fn node(el: raw::RawElement<'_>, scope: &mut Vec<(String, String)>) -> Node {
    let depth = scope.len();
    let mut attrs = Vec::new();
    for a in el.attrs() {
        if a.name == "xmlns" {
            scope.push((String::new(), a.value.to_string()));
        } else if let Some(prefix) = a.name.strip_prefix("xmlns:") {
            scope.push((prefix.to_string(), a.value.to_string()));
        } else {
            attrs.push((a.name.to_string(), a.value.to_string()));
        }
    }
    let qname = el.name().to_string();
    let (prefix, name) = qname.split_once(':').unwrap_or(("", &qname));
    let uri = scope.iter().rev().find(|(p, _)| p == prefix).map(|(_, u)| u.clone()).unwrap_or_default();
    let ns = match uri.as_str() {
        SSD1 | SSD2 => Ns::Ssd,
        SSC1 | SSC2 => Ns::Ssc,
        SSV1 | SSV2 => Ns::Ssv,
        _ => Ns::Other,
    };
    let name = name.to_string();
    let children = el.children().map(|c| node(c, scope)).collect();
    scope.truncate(depth);
    Node { ns, uri, name, qname, pos: el.pos(), attrs, children, text: el.text().to_string() }
}
