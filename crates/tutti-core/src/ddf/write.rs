//! The product dialect, written: an editable [`Document`] (a DDF as a person edits it, not
//! yet validated: every field is text, so a wrong value reaches the validator and gets its
//! diagnostic) and [`write()`], which turns it into XML with one element per line and tells
//! which line holds which field, so that a diagnostic's line leads back to the field it is
//! about (`tutti studio`).
//!
//! ```
//! use tutti_core::ddf::{parse_str, write::{write, Document}};
//! let model = parse_str(
//!     r#"<orchestra><domain name="d"><block name="d/Publish">
//!          <item name="x"><type>double</type></item></block></domain></orchestra>"#,
//!     "paper.ddf",
//! ).unwrap();
//! let written = write(&Document::from(&model));
//! assert!(written.xml.contains(r#"<set name="PUBLISH">"#));
//! let again = parse_str(&written.xml, "product.ddf").unwrap();
//! assert_eq!(again.domains[0].publish.layout, model.domains[0].publish.layout);
//! ```

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::model::{Connection, Item, ItemKind, Model};
use super::Diagnostic;

/// A DDF as edited: domains with their flags and the items of their two sets.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Document {
    pub domains: Vec<DocDomain>,
}

/// One domain of a [`Document`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DocDomain {
    pub name: String,
    pub synchronous: bool,
    /// `<synchronous>event</synchronous>` (with `synchronous`): event-driven.
    #[serde(default)]
    pub event: bool,
    pub multiple_publish_allowed: bool,
    pub states: bool,
    /// The attributes of the optional `<connection>` element, in order.
    #[serde(default)]
    pub connection: Option<Vec<(String, String)>>,
    /// Its child elements (name, text), in order: a `remote` connection's `card` and
    /// `pciindex`, a `dolphin` one's `nodeIdFramework` and `segmentId`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub connection_settings: Vec<(String, String)>,
    #[serde(default)]
    pub publish: Vec<DocItem>,
    #[serde(default)]
    pub subscribe: Vec<DocItem>,
}

/// One item of a [`Document`]: a scalar or array (`type` names a scalar type), or a bus
/// (`type` is `bus`) of nested `items`. `length` and `default` are left out of the XML when
/// empty.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DocItem {
    pub name: String,
    #[serde(rename = "type")]
    pub ty: String,
    #[serde(default)]
    pub length: String,
    #[serde(default)]
    pub default: String,
    #[serde(default)]
    pub items: Vec<DocItem>,
}

impl From<&Model> for Document {
    fn from(model: &Model) -> Self {
        let items = |items: &[Item]| items.iter().map(DocItem::from).collect();
        Document {
            domains: model
                .domains
                .iter()
                .map(|d| DocDomain {
                    name: d.name.clone(),
                    synchronous: d.flags.synchronous,
                    event: d.flags.event,
                    multiple_publish_allowed: d.flags.multiple_publish_allowed,
                    states: d.flags.states,
                    connection: d.connection.as_ref().map(|c: &Connection| c.attributes.clone()),
                    connection_settings: d.connection.as_ref().map_or_else(Vec::new, |c| c.settings.clone()),
                    publish: items(&d.publish.items),
                    subscribe: items(&d.subscribe.items),
                })
                .collect(),
        }
    }
}

impl From<&Item> for DocItem {
    fn from(item: &Item) -> Self {
        match &item.kind {
            ItemKind::Scalar { ty, length, default } => DocItem {
                name: item.name.clone(),
                ty: ty.canonical().to_string(),
                length: if *length == 1 { String::new() } else { length.to_string() },
                default: default.map(|v| v.to_string()).unwrap_or_default(),
                items: Vec::new(),
            },
            ItemKind::Bus { items } => DocItem {
                name: item.name.clone(),
                ty: "bus".to_string(),
                length: String::new(),
                default: String::new(),
                items: items.iter().map(DocItem::from).collect(),
            },
        }
    }
}

/// What [`write()`] produced: the XML, and for each line that holds a field, which one.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Written {
    pub xml: String,
    /// `(line, field)`, lines 1-based and increasing. Fields are named `dN` (a domain, its
    /// name), `dN.synchronous`, `dN.multiple_publish_allowed`, `dN.states`,
    /// `dN.connection`, `dN.publish` / `dN.subscribe` (a set), and for items
    /// `dN.publish.iK` (the item, its name), `dN.publish.iK.type`, `.length`, `.default`,
    /// nested as `dN.publish.iK.iJ`.
    pub fields: Vec<(u32, String)>,
}

impl Written {
    /// The field a diagnostic is about: the one on its line, else the nearest one above.
    pub fn field_of(&self, diagnostic: &Diagnostic) -> Option<&str> {
        let line = diagnostic.pos.line;
        let at = self.fields.partition_point(|(l, _)| *l <= line);
        at.checked_sub(1).map(|i| self.fields[i].1.as_str())
    }
}

struct Out {
    xml: String,
    line: u32,
    fields: Vec<(u32, String)>,
}

impl Out {
    fn line(&mut self, indent: usize, text: &str, field: Option<String>) {
        if let Some(f) = field {
            self.fields.push((self.line, f));
        }
        for _ in 0..indent {
            self.xml.push_str("  ");
        }
        self.xml.push_str(text);
        self.xml.push('\n');
        self.line += 1;
    }
}

/// Escapes text for an XML attribute value or element content.
pub fn escape(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => s.push_str("&amp;"),
            '<' => s.push_str("&lt;"),
            '>' => s.push_str("&gt;"),
            '"' => s.push_str("&quot;"),
            '\'' => s.push_str("&apos;"),
            c => s.push(c),
        }
    }
    s
}

fn yes_no(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

/// Writes `doc` in the product dialect (`<set name="PUBLISH">`, one element per line).
/// Whatever the document holds is written as is; validating the result (with
/// [`super::parse_str`]) is what finds its problems.
pub fn write(doc: &Document) -> Written {
    let mut out = Out { xml: String::new(), line: 1, fields: Vec::new() };
    out.line(0, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>", None);
    out.line(0, "<orchestra>", None);
    for (n, d) in doc.domains.iter().enumerate() {
        let id = format!("d{n}");
        out.line(1, &format!("<domain name=\"{}\">", escape(&d.name)), Some(id.clone()));
        if d.event {
            out.line(2, "<synchronous>event</synchronous>", Some(format!("{id}.synchronous")));
        }
        for (tag, field, v) in [
            ("synchronous", "synchronous", d.synchronous),
            ("multiplePublishAllowed", "multiple_publish_allowed", d.multiple_publish_allowed),
            ("states", "states", d.states),
        ] {
            if d.event && tag == "synchronous" {
                continue;
            }
            out.line(2, &format!("<{tag}>{}</{tag}>", yes_no(v)), Some(format!("{id}.{field}")));
        }
        if let Some(attrs) = &d.connection {
            let mut text = String::from("<connection");
            for (k, v) in attrs {
                let _ = write!(text, " {}=\"{}\"", escape(k), escape(v));
            }
            if d.connection_settings.is_empty() {
                text.push_str("/>");
                out.line(2, &text, Some(format!("{id}.connection")));
            } else {
                text.push('>');
                out.line(2, &text, Some(format!("{id}.connection")));
                for (k, v) in &d.connection_settings {
                    let (k, v) = (escape(k), escape(v));
                    out.line(3, &format!("<{k}>{v}</{k}>"), Some(format!("{id}.connection")));
                }
                out.line(2, "</connection>", Some(format!("{id}.connection")));
            }
        }
        for (role, set, items) in [("PUBLISH", "publish", &d.publish), ("SUBSCRIBE", "subscribe", &d.subscribe)] {
            let set_id = format!("{id}.{set}");
            if items.is_empty() {
                out.line(2, &format!("<set name=\"{role}\"/>"), Some(set_id));
                continue;
            }
            out.line(2, &format!("<set name=\"{role}\">"), Some(set_id.clone()));
            write_items(&mut out, 3, &set_id, items);
            out.line(2, "</set>", None);
        }
        out.line(1, "</domain>", None);
    }
    out.line(0, "</orchestra>", None);
    Written { xml: out.xml, fields: out.fields }
}

fn write_items(out: &mut Out, indent: usize, parent: &str, items: &[DocItem]) {
    for (k, item) in items.iter().enumerate() {
        let id = format!("{parent}.i{k}");
        out.line(indent, &format!("<item name=\"{}\">", escape(&item.name)), Some(id.clone()));
        out.line(indent + 1, &format!("<type>{}</type>", escape(&item.ty)), Some(format!("{id}.type")));
        if !item.length.is_empty() {
            out.line(indent + 1, &format!("<length>{}</length>", escape(&item.length)), Some(format!("{id}.length")));
        }
        if !item.default.is_empty() {
            out.line(
                indent + 1,
                &format!("<default>{}</default>", escape(&item.default)),
                Some(format!("{id}.default")),
            );
        }
        write_items(out, indent + 1, &id, &item.items);
        out.line(indent, "</item>", None);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ddf::{parse_str, synth};

    /// The model as JSON, without its source path (which names the file it came from).
    fn json(model: &Model) -> serde_json::Value {
        let mut v = serde_json::to_value(model).unwrap();
        v.as_object_mut().unwrap().remove("source");
        v
    }

    fn round_trip(text: &str) {
        let model = parse_str(text, "in.ddf").unwrap();
        let written = write(&Document::from(&model));
        let again = parse_str(&written.xml, "out.ddf").unwrap_or_else(|e| panic!("{e}\n{}", written.xml));
        assert_eq!(json(&model), json(&again), "{}", written.xml);
        assert_eq!(Document::from(&model), Document::from(&again));
    }

    #[test]
    fn parse_write_parse_gives_the_same_model() {
        for file in ["paper-figure2.ddf", "multiuav.ddf", "product-sample.ddf"] {
            let path = format!("{}/../../ddf/{file}", env!("CARGO_MANIFEST_DIR"));
            round_trip(&std::fs::read_to_string(&path).unwrap());
        }
        round_trip(&synth::large_ddf(9, 23));
        // The three connection forms (remote and dolphin with child elements) are kept.
        let forms = format!("{}/../../tests/ddf/connection-forms.ddf", env!("CARGO_MANIFEST_DIR"));
        round_trip(&std::fs::read_to_string(forms).unwrap());
        // An event-driven domain (docs/timing.md) stays one.
        let event =
            std::fs::read_to_string(format!("{}/../../tests/event/event.ddf", env!("CARGO_MANIFEST_DIR"))).unwrap();
        round_trip(&event);
        let model = parse_str(&event, "event.ddf").unwrap();
        let written = write(&Document::from(&model)).xml;
        assert!(written.contains("<synchronous>event</synchronous>"), "{written}");
        let again = parse_str(&written, "written.ddf").unwrap();
        assert!(again.domains[0].flags.event && again.domains[0].flags.synchronous);
    }

    #[test]
    fn names_are_escaped_and_diagnostics_lead_to_their_field() {
        let doc = Document {
            domains: vec![DocDomain {
                name: "a&b".into(),
                synchronous: true,
                event: false,
                multiple_publish_allowed: false,
                states: false,
                connection: None,
                connection_settings: Vec::new(),
                publish: vec![DocItem {
                    name: "has space".into(),
                    ty: "double".into(),
                    length: String::new(),
                    default: String::new(),
                    items: vec![],
                }],
                subscribe: vec![DocItem {
                    name: "n".into(),
                    ty: "double".into(),
                    length: "0".into(),
                    default: String::new(),
                    items: vec![],
                }],
            }],
        };
        let written = write(&doc);
        assert!(written.xml.contains("name=\"a&amp;b\""));
        let err = parse_str(&written.xml, "doc.ddf").unwrap_err();
        let fields: Vec<_> = err.diagnostics().iter().map(|d| written.field_of(d).unwrap_or("")).collect();
        assert_eq!(parse_str(&written.xml, "doc.ddf").err().map(|e| e.diagnostics().len()), Some(2));
        assert!(fields.contains(&"d0.publish.i0"), "{fields:?}\n{err}");
        assert!(fields.contains(&"d0.subscribe.i0.length"), "{fields:?}\n{err}");
    }
}
