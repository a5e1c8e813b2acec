//! Step two of reading a DDF: raw elements to the validated [`Model`], checking every rule
//! of `docs/ddf.md` and collecting every violation with its position.

use std::borrow::Cow;
use std::collections::hash_map::Entry;
use std::collections::HashMap;

use super::layout::{self, SetLayout, MAX_SET_BYTES};
use super::model::{
    join_path, Connection, ConnectionKind, Domain, Flags, Item, ItemKind, Model, Role, ScalarType, Set, TypeName, Value,
};
use super::raw::RawElement;
use super::{Diagnostic, Pos};

/// Deepest bus nesting accepted (a bus inside a bus inside … counts one level each).
pub const MAX_BUS_DEPTH: usize = 16;
/// Longest name accepted, in characters.
pub const MAX_NAME_LEN: usize = 63;
/// Largest `<length>`.
pub const MAX_LENGTH: u32 = 65535;

#[derive(Debug, Default)]
struct Diags(Vec<Diagnostic>);

impl Diags {
    fn at(&mut self, pos: Pos, message: impl Into<String>) {
        self.0.push(Diagnostic { pos, message: message.into() });
    }
}

/// The names given so far in one list of items (a set or a bus) and where each was first
/// given. Most lists are short, and comparing a name with a dozen others costs less than
/// hashing it (hashing every name was an eighth of the validation); past [`Seen::FEW`]
/// names they go into a hash map, so a set of thousands of items is still linear.
#[derive(Debug, Default)]
struct Seen<'a> {
    few: Vec<(&'a str, Pos)>,
    many: HashMap<&'a str, Pos>,
}

impl<'a> Seen<'a> {
    const FEW: usize = 32;

    /// Where `name` was first given, or `None` (and `name` is recorded at `pos`).
    fn first(&mut self, name: &'a str, pos: Pos) -> Option<Pos> {
        if self.many.is_empty() {
            if let Some(&(_, first)) = self.few.iter().find(|(n, _)| *n == name) {
                return Some(first);
            }
            if self.few.len() < Self::FEW {
                self.few.push((name, pos));
                return None;
            }
            self.many.extend(self.few.drain(..));
        }
        match self.many.entry(name) {
            Entry::Occupied(first) => Some(*first.get()),
            Entry::Vacant(slot) => {
                slot.insert(pos);
                None
            }
        }
    }
}

/// Checks a name (domain or item): 1–63 characters, no whitespace, `,`, `#`, or `/` (the
/// path separator). Returns the problem, if any.
pub fn name_problem(name: &str) -> Option<String> {
    // The usual name, short printable ASCII, passes without decoding its characters.
    let plain = |b: u8| b.is_ascii_graphic() && !matches!(b, b',' | b'#' | b'/');
    if (1..=MAX_NAME_LEN).contains(&name.len()) && name.bytes().all(plain) {
        return None;
    }
    let n = name.chars().count();
    if n == 0 {
        return Some("is empty".into());
    }
    if n > MAX_NAME_LEN {
        return Some(format!("is {n} characters long; the limit is {MAX_NAME_LEN}"));
    }
    if let Some(c) = name.chars().find(|c| c.is_whitespace() || matches!(c, ',' | '#' | '/') || c.is_control()) {
        let shown = if c.is_whitespace() || c.is_control() { format!("{:?}", c) } else { format!("'{c}'") };
        return Some(format!("contains {shown}; names may not contain whitespace, ',', '#' or '/'"));
    }
    None
}

/// Validates a parsed tree; `source` is only recorded in the model.
pub fn validate(root: RawElement, source: &str) -> Result<Model, Vec<Diagnostic>> {
    let mut d = Diags::default();
    if root.name() != "orchestra" {
        d.at(root.pos(), format!("the root element is <{}>; a DDF's root element is <orchestra>", root.name()));
        return Err(d.0);
    }
    no_attrs(root, &mut d);
    no_text(root, &mut d);
    let mut domains = Vec::new();
    let mut seen: HashMap<String, Pos> = HashMap::new();
    for child in root.children() {
        if child.name() != "domain" {
            d.at(child.pos(), format!("unknown element <{}> in <orchestra>; expected <domain>", child.name()));
            continue;
        }
        if let Some(domain) = domain(child, &mut d) {
            if let Some(first) = seen.get(&domain.name) {
                d.at(
                    child.pos(),
                    format!(
                        "duplicate domain name '{}' (first defined at line {}, column {})",
                        domain.name, first.line, first.col
                    ),
                );
            } else {
                seen.insert(domain.name.clone(), child.pos());
                domains.push(domain);
            }
        }
    }
    if !root.has_children() {
        d.at(root.pos(), "<orchestra> contains no <domain>: the file describes no data");
    }
    if d.0.is_empty() {
        Ok(Model { source: source.to_string(), domains })
    } else {
        d.0.sort_by_key(|x| (x.pos.line, x.pos.col));
        Err(d.0)
    }
}

fn no_attrs(el: RawElement, d: &mut Diags) {
    only_attrs(el, &[], d);
}

fn only_attrs(el: RawElement, allowed: &[&str], d: &mut Diags) {
    for a in el.attrs() {
        if !allowed.contains(&&*a.name) {
            d.at(el.pos(), format!("unknown attribute '{}' on <{}>", a.name, el.name()));
        }
    }
}

fn no_text(el: RawElement, d: &mut Diags) {
    if !el.text().is_empty() {
        d.at(el.text_pos().unwrap_or(el.pos()), format!("unexpected text '{}' in <{}>", shorten(el.text()), el.name()));
    }
}

fn leaf_element(el: RawElement, d: &mut Diags) {
    no_attrs(el, d);
    for c in el.children() {
        d.at(c.pos(), format!("unexpected element <{}> inside <{}>", c.name(), el.name()));
    }
}

fn shorten(s: &str) -> String {
    super::raw::printable(s, 40)
}

/// The `name` attribute, checked; reports and returns `None` when missing or invalid.
fn name_attr<'a>(el: RawElement<'a>, what: &str, d: &mut Diags) -> Option<&'a str> {
    match el.attr("name") {
        None => {
            d.at(el.pos(), format!("<{}> has no name attribute", el.name()));
            None
        }
        Some(name) => match name_problem(name) {
            Some(problem) => {
                d.at(el.pos(), format!("{what} name '{}' {problem}", shorten(name)));
                None
            }
            None => Some(name),
        },
    }
}

fn yes_no(el: RawElement, d: &mut Diags) -> Option<bool> {
    leaf_element(el, d);
    let text = el.text();
    // Compared in place: lower-casing a copy of every flag cost an allocation each.
    if text.eq_ignore_ascii_case("yes") {
        Some(true)
    } else if text.eq_ignore_ascii_case("no") {
        Some(false)
    } else {
        d.at(
            el.text_pos().unwrap_or(el.pos()),
            format!(
                "<{}> must be yes or no{}, found '{}'",
                el.name(),
                // tutti's extension (docs/timing.md).
                if el.name() == "synchronous" { " (or event)" } else { "" },
                shorten(&text.to_ascii_lowercase())
            ),
        );
        None
    }
}

fn domain(el: RawElement, d: &mut Diags) -> Option<Domain> {
    only_attrs(el, &["name"], d);
    no_text(el, d);
    let name = name_attr(el, "domain", d);
    let label = name.unwrap_or("?");
    let mut flags = Flags { synchronous: false, event: false, multiple_publish_allowed: true, states: false };
    // Where each of synchronous, multiplePublishAllowed and states was first given.
    let mut flag_seen: [Option<Pos>; 3] = [None; 3];
    let mut connection = None;
    let mut connection_seen = false;
    let mut sets: [Option<(Set, Pos)>; 2] = [None, None];
    for child in el.children() {
        match child.name() {
            flag @ ("synchronous" | "multiplePublishAllowed" | "states") => {
                let which = match flag {
                    "synchronous" => 0,
                    "multiplePublishAllowed" => 1,
                    _ => 2,
                };
                if let Some(first) = flag_seen[which] {
                    d.at(
                        child.pos(),
                        format!(
                            "domain '{label}' has a second <{flag}> (the first is at line {}, column {})",
                            first.line, first.col
                        ),
                    );
                    continue;
                }
                flag_seen[which] = Some(child.pos());
                if which == 0 && child.text().eq_ignore_ascii_case("event") {
                    // tutti's extension: event-driven synchronisation (docs/ddf.md).
                    leaf_element(child, d);
                    flags.synchronous = true;
                    flags.event = true;
                    continue;
                }
                if let Some(v) = yes_no(child, d) {
                    match which {
                        0 => flags.synchronous = v,
                        1 => flags.multiple_publish_allowed = v,
                        _ => flags.states = v,
                    }
                }
            }
            "connection" => {
                if connection_seen {
                    d.at(child.pos(), format!("domain '{label}' has a second <connection>"));
                }
                connection_seen = true;
                connection = connection_element(child, label, d).or(connection);
            }
            "block" | "set" => {
                let Some(role) = set_role(child, d) else { continue };
                let set = set(child, role, label, d);
                let slot = &mut sets[role as usize];
                if let Some((_, first)) = slot {
                    d.at(
                        child.pos(),
                        format!(
                            "domain '{label}' has a second {role} set (the first is at line {}, column {}); a domain has at most one set of each role",
                            first.line, first.col
                        ),
                    );
                } else if let Some(set) = set {
                    *slot = Some((set, child.pos()));
                }
            }
            other => {
                d.at(
                    child.pos(),
                    format!(
                        "unknown element <{other}> in domain '{label}'; expected <synchronous>, <multiplePublishAllowed>, <states>, <connection>, <set> or <block>"
                    ),
                );
            }
        }
    }
    let name = name?.to_string();
    let [publish, subscribe] = sets;
    let empty =
        |role| Set { role, items: Vec::new(), layout: SetLayout { size: 0, align: 1, leaves: Vec::new() }, pos: None };
    let publish = publish.map(|(s, _)| s).unwrap_or_else(|| empty(Role::Publish));
    let subscribe = subscribe.map(|(s, _)| s).unwrap_or_else(|| empty(Role::Subscribe));
    let layout_hash = layout::layout_hash(&name, flags, &publish.layout, &subscribe.layout);
    Some(Domain { name, flags, connection, publish, subscribe, layout_hash, pos: el.pos() })
}

/// The attributes of a `local` connection, and the integer range of those that are numbers.
const LOCAL_ATTRIBUTES: &[(&str, Option<(i64, i64)>)] = &[
    ("extcomm", None),
    ("addrframework", None),
    ("portframework", Some((0, 65535))),
    ("nicframework", None),
    ("nicclient", None),
    ("coreframework", Some((-1, 4095))),
    ("coreclient", Some((-1, 4095))),
];

/// The settings (child elements) of the `remote` and `dolphin` connections: name, and the
/// integer range when it is a number (`None`: a name, such as the card's).
const REMOTE_SETTINGS: &[(&str, Option<(i64, i64)>)] = &[("card", None), ("pciindex", Some((0, 255)))];
const DOLPHIN_SETTINGS: &[(&str, Option<(i64, i64)>)] =
    &[("nodeIdFramework", Some((0, 65535))), ("segmentId", Some((0, u32::MAX as i64)))];

/// What is wrong with a connection setting that must be an integer in a range.
#[derive(Debug, thiserror::Error)]
enum IntegerError {
    #[error("out of range {lo}..{hi}")]
    OutOfRange { lo: i64, hi: i64 },
    #[error("not an integer ({lo}..{hi})")]
    NotAnInteger { lo: i64, hi: i64 },
}

/// `value` as an integer within `range`, or what is wrong with it.
fn integer_in(value: &str, (lo, hi): (i64, i64)) -> Result<i64, IntegerError> {
    match value.trim().parse::<i64>() {
        Ok(v) if (lo..=hi).contains(&v) => Ok(v),
        Ok(_) => Err(IntegerError::OutOfRange { lo, hi }),
        Err(_) => Err(IntegerError::NotAnInteger { lo, hi }),
    }
}

/// A `<connection>` in one of the three forms the product's tools write:
/// `<connection type="local" extcomm=".." addrframework=".." portframework=".." .../>`,
/// `<connection type="remote"><card>NAME</card><pciindex>N</pciindex></connection>`,
/// `<connection type="dolphin"><nodeIdFramework>N</nodeIdFramework><segmentId>N</segmentId></connection>`.
fn connection_element(el: RawElement, domain: &str, d: &mut Diags) -> Option<Connection> {
    no_text(el, d);
    let kind = match el.attr("type").map(str::to_ascii_lowercase).as_deref() {
        None | Some("local") => ConnectionKind::Local,
        Some("remote") => ConnectionKind::Remote,
        Some("dolphin") => ConnectionKind::Dolphin,
        Some(_) => {
            let t = el.attr("type").unwrap_or_default();
            d.at(el.pos(), format!("<connection> type must be local, remote or dolphin, found '{}'", shorten(t)));
            return None;
        }
    };
    let before = d.0.len();
    let attributes: Vec<(String, String)> =
        el.attrs().iter().map(|a| (a.name.to_string(), a.value.to_string())).collect();
    let mut settings = Vec::new();
    match kind {
        ConnectionKind::Local => {
            for a in el.attrs() {
                if a.name == "type" {
                    continue;
                }
                match LOCAL_ATTRIBUTES.iter().find(|(n, _)| *n == a.name) {
                    None => d.at(
                        el.pos(),
                        format!(
                            "unknown attribute '{}' on a local <connection> of domain '{domain}'; expected {}",
                            shorten(&a.name),
                            LOCAL_ATTRIBUTES.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
                        ),
                    ),
                    Some((_, Some(range))) if !(a.value.trim().is_empty()) => {
                        if let Err(e) = integer_in(&a.value, *range) {
                            d.at(el.pos(), format!("<connection> {}='{}': {e}", a.name, shorten(&a.value)));
                        }
                    }
                    Some(_) => {}
                }
            }
            for c in el.children() {
                d.at(
                    c.pos(),
                    format!("unexpected element <{}> inside a local <connection> (it takes attributes)", c.name()),
                );
            }
        }
        ConnectionKind::Remote | ConnectionKind::Dolphin => {
            only_attrs(el, &["type"], d);
            let expected = if kind == ConnectionKind::Remote { REMOTE_SETTINGS } else { DOLPHIN_SETTINGS };
            let names = || expected.iter().map(|(n, _)| format!("<{n}>")).collect::<Vec<_>>().join(" and ");
            for c in el.children() {
                let Some((_, range)) = expected.iter().find(|(n, _)| *n == c.name()) else {
                    d.at(
                        c.pos(),
                        format!(
                            "unexpected element <{}> inside a {} <connection>; expected {}",
                            c.name(),
                            kind.as_str(),
                            names()
                        ),
                    );
                    continue;
                };
                leaf_element(c, d);
                if settings.iter().any(|(n, _): &(String, String)| *n == c.name()) {
                    d.at(c.pos(), format!("a second <{}> in the <connection> of domain '{domain}'", c.name()));
                    continue;
                }
                let text = c.text().trim().to_string();
                if let Some(range) = range {
                    if let Err(e) = integer_in(&text, *range) {
                        d.at(c.text_pos().unwrap_or(c.pos()), format!("<{}> '{}': {e}", c.name(), shorten(&text)));
                    }
                }
                settings.push((c.name().to_string(), text));
            }
            for (n, _) in expected {
                if !settings.iter().any(|(s, _)| s == n) {
                    d.at(el.pos(), format!("the {} <connection> of domain '{domain}' has no <{n}>", kind.as_str()));
                }
            }
        }
    }
    (d.0.len() == before).then_some(Connection { kind, attributes, settings })
}

fn set_role(el: RawElement, d: &mut Diags) -> Option<Role> {
    only_attrs(el, &["name"], d);
    let Some(name) = el.attr("name") else {
        d.at(el.pos(), format!("<{}> has no name attribute", el.name()));
        return None;
    };
    // Paper dialect: "DOMAIN/Publish"; product dialect: "PUBLISH". Either way the last
    // path segment names the role.
    let last = name.rsplit('/').next().unwrap_or(name);
    if last.eq_ignore_ascii_case("publish") {
        Some(Role::Publish)
    } else if last.eq_ignore_ascii_case("subscribe") {
        Some(Role::Subscribe)
    } else {
        let expected = if el.name() == "block" {
            "a block name must end in /Publish or /Subscribe"
        } else {
            "a set is named PUBLISH or SUBSCRIBE"
        };
        d.at(el.pos(), format!("<{}> name '{}' names no role: {expected}", el.name(), shorten(name)));
        None
    }
}

fn set(el: RawElement, role: Role, domain: &str, d: &mut Diags) -> Option<Set> {
    no_text(el, d);
    let before = d.0.len();
    // Room for every child (all of them are items in a valid set): growing the vector
    // item by item copied it several times.
    let mut items = Vec::with_capacity(el.children().count());
    item_list(el, role, domain, "", 0, &mut items, d);
    if d.0.len() != before {
        return None;
    }
    match layout::compute(&items) {
        Ok(layout) => Some(Set { role, items, layout, pos: Some(el.pos()) }),
        Err(bytes) => {
            d.at(
                el.pos(),
                format!(
                    "set {role} of domain '{domain}' would take {bytes} bytes; the limit is {} MiB",
                    MAX_SET_BYTES >> 20
                ),
            );
            None
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn item_list(
    parent: RawElement<'_>,
    role: Role,
    domain: &str,
    prefix: &str,
    depth: usize,
    out: &mut Vec<Item>,
    d: &mut Diags,
) {
    // Names as written, borrowed from the source: copying each one cost an allocation.
    let mut seen = Seen::default();
    for child in parent.children() {
        if child.name() != "item" {
            // Inside a bus item, its other children (<type>, <length>, <default> and unknown
            // elements) are checked and reported by `item`.
            if parent.name() == "item" {
                continue;
            }
            d.at(child.pos(), format!("unknown element <{}> in <{}>; expected <item>", child.name(), parent.name()));
            continue;
        }
        let Some((name, item)) = item(child, role, domain, prefix, depth, d) else { continue };
        if let Some(first) = seen.first(name, child.pos()) {
            let path = join_path(prefix, name);
            d.at(
                child.pos(),
                format!(
                    "item path '{path}' appears twice in set {role} of domain '{domain}' (first at line {}, column {})",
                    first.line, first.col
                ),
            );
            continue;
        }
        out.push(item);
    }
}

/// A valid item, with its name as written in the source.
fn item<'a>(
    el: RawElement<'a>,
    role: Role,
    domain: &str,
    prefix: &str,
    depth: usize,
    d: &mut Diags,
) -> Option<(&'a str, Item)> {
    only_attrs(el, &["name"], d);
    no_text(el, d);
    let name = name_attr(el, "item", d);
    // The path for messages and nested items; at the top of a set (most items) the name.
    let label: Cow<str> = match name {
        Some(n) if prefix.is_empty() => Cow::Borrowed(n),
        Some(n) => Cow::Owned(join_path(prefix, n)),
        None => Cow::Owned(format!("{prefix}/?")),
    };
    let parts = item_parts(el, name, &label, d);
    let ty = item_type(&parts, d)?;
    let length = item_length(&parts, d);
    match ty {
        TypeName::Bus => bus_item(&parts, length, role, domain, depth, d),
        TypeName::Scalar(ty) => scalar_item(&parts, ty, length, d),
    }
}

/// An `<item>` element as read so far: its name as written, its path for messages, and its
/// `<type>`, `<length>` and `<default>` children (nested items are read apart).
struct ItemParts<'a, 'l> {
    el: RawElement<'a>,
    name: Option<&'a str>,
    label: &'l str,
    ty: Option<RawElement<'a>>,
    length: Option<RawElement<'a>>,
    default: Option<RawElement<'a>>,
}

/// The children of item `el` that describe it, each at most once; unknown and repeated
/// children are reported.
fn item_parts<'a, 'l>(el: RawElement<'a>, name: Option<&'a str>, label: &'l str, d: &mut Diags) -> ItemParts<'a, 'l> {
    let mut parts = ItemParts { el, name, label, ty: None, length: None, default: None };
    for child in el.children() {
        let slot = match child.name() {
            "type" => &mut parts.ty,
            "length" => &mut parts.length,
            "default" => &mut parts.default,
            "item" => continue,
            other => {
                d.at(
                    child.pos(),
                    format!("unknown element <{other}> in item '{label}'; expected <type>, <length>, <default> or nested <item>"),
                );
                continue;
            }
        };
        if slot.is_some() {
            d.at(child.pos(), format!("item '{label}' has a second <{}>", child.name()));
            continue;
        }
        leaf_element(child, d);
        *slot = Some(child);
    }
    parts
}

/// The item's `<type>`; `None` (reported) when it has none or an unknown one.
fn item_type(parts: &ItemParts<'_, '_>, d: &mut Diags) -> Option<TypeName> {
    let label = parts.label;
    let Some(ty_el) = parts.ty else {
        d.at(parts.el.pos(), format!("item '{label}' has no <type>"));
        return None;
    };
    let Some(ty) = TypeName::parse(ty_el.text()) else {
        d.at(
            ty_el.text_pos().unwrap_or(ty_el.pos()),
            format!(
                "item '{label}' has unknown type '{}'; expected boolean, int8…int64, unsigned int8…unsigned int64, float32, float64 or bus",
                shorten(ty_el.text())
            ),
        );
        return None;
    };
    Some(ty)
}

/// The item's `<length>` (1 without one); `None` (reported) when it is out of range.
fn item_length(parts: &ItemParts<'_, '_>, d: &mut Diags) -> Option<u16> {
    let label = parts.label;
    match parts.length {
        None => Some(1u16),
        Some(l) => match l.text().parse::<u64>() {
            Ok(n) if (1..=u64::from(MAX_LENGTH)).contains(&n) => Some(n as u16),
            _ => {
                d.at(
                    l.text_pos().unwrap_or(l.pos()),
                    format!(
                        "item '{label}' has length '{}'; a length is a whole number from 1 to {MAX_LENGTH}",
                        shorten(l.text())
                    ),
                );
                None
            }
        },
    }
}

/// A bus item: no default, length 1, and nested items (read as a list of their own, one
/// level deeper).
fn bus_item<'a>(
    parts: &ItemParts<'a, '_>,
    length: Option<u16>,
    role: Role,
    domain: &str,
    depth: usize,
    d: &mut Diags,
) -> Option<(&'a str, Item)> {
    let (el, label) = (parts.el, parts.label);
    if let Some(def) = parts.default {
        d.at(def.pos(), format!("bus item '{label}' cannot have a <default>; give defaults to its members"));
    }
    if length.is_some_and(|l| l != 1) {
        d.at(
            parts.length.map_or(el.pos(), |l| l.pos()),
            format!("bus item '{label}' must have length 1; arrays of buses are not supported"),
        );
    }
    if !el.children().any(|c| c.name() == "item") {
        d.at(el.pos(), format!("bus item '{label}' has no nested <item>"));
        return None;
    }
    if depth + 1 > MAX_BUS_DEPTH {
        d.at(el.pos(), format!("bus item '{label}' is nested deeper than {MAX_BUS_DEPTH} levels"));
        return None;
    }
    let mut items = Vec::with_capacity(el.children().count());
    item_list(el, role, domain, label, depth + 1, &mut items, d);
    let name = parts.name?;
    Some((name, Item { name: name.to_string(), kind: ItemKind::Bus { items }, pos: el.pos() }))
}

/// A scalar item: no nested items, and a default (if any) that fits its type.
fn scalar_item<'a>(
    parts: &ItemParts<'a, '_>,
    ty: ScalarType,
    length: Option<u16>,
    d: &mut Diags,
) -> Option<(&'a str, Item)> {
    let (el, label) = (parts.el, parts.label);
    for n in el.children().filter(|c| c.name() == "item") {
        d.at(n.pos(), format!("item '{label}' has type {} and cannot contain items; only a bus can", ty.canonical()));
    }
    let default = scalar_default(parts, ty, d)?;
    let name = parts.name?;
    let kind = ItemKind::Scalar { ty, length: length?, default };
    Some((name, Item { name: name.to_string(), kind, pos: el.pos() }))
}

/// The `<default>` of a scalar item of type `ty` (`Some(None)` without one); `None`
/// (reported) when it does not fit the type.
fn scalar_default(parts: &ItemParts<'_, '_>, ty: ScalarType, d: &mut Diags) -> Option<Option<Value>> {
    let Some(def) = parts.default else { return Some(None) };
    if let Some(v) = ty.parse_value(def.text()) {
        return Some(Some(v));
    }
    let expected =
        if ty == ScalarType::Boolean { "yes or no".to_string() } else { format!("a value of type {}", ty.canonical()) };
    d.at(
        def.text_pos().unwrap_or(def.pos()),
        format!(
            "default '{}' of item '{}' does not fit its type: expected {expected}",
            shorten(def.text()),
            parts.label
        ),
    );
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seen_finds_the_first_position_before_and_after_hashing() {
        let names: Vec<String> = (0..3 * Seen::FEW).map(|i| format!("n{i}")).collect();
        let at = |i: usize| Pos { line: i as u32 + 1, col: 1 };
        let mut seen = Seen::default();
        for (i, name) in names.iter().enumerate() {
            assert_eq!(seen.first(name, at(i)), None);
            // A name seen just before, and the very first one, whichever way they are kept.
            assert_eq!(seen.first(name, at(1000)), Some(at(i)));
            assert_eq!(seen.first(&names[0], at(1000)), Some(at(0)));
        }
    }

    #[test]
    fn name_problems_are_the_same_for_ascii_and_other_names() {
        assert_eq!(name_problem("cosim_0001"), None);
        assert_eq!(name_problem("é"), None);
        assert_eq!(name_problem(&"x".repeat(MAX_NAME_LEN)), None);
        assert_eq!(name_problem(&"é".repeat(MAX_NAME_LEN)), None);
        assert_eq!(name_problem(""), Some("is empty".into()));
        assert!(name_problem(&"x".repeat(MAX_NAME_LEN + 1)).unwrap().starts_with("is 64 characters long"));
        assert!(name_problem("a,b").unwrap().starts_with("contains ','"));
        assert!(name_problem("a b").unwrap().starts_with("contains ' '"));
        assert!(name_problem("a\u{7f}").unwrap().starts_with("contains '\\u{7f}'"));
        assert!(name_problem("a\u{a0}b").unwrap().starts_with("contains '\\u{a0}'"));
    }
}
