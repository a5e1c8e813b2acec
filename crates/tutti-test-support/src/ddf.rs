//! DDF texts for tests that need a small DDF of their own: one domain, its items one value
//! each, written as the product's DDFs are (`ddf/product-sample.ddf`).

use std::fmt;

/// A DDF of one domain, built item by item; its text is [`OneDomain::text`] (or `Display`).
///
/// ```ignore
/// let ddf = one_domain("plant").synchronous().publish("x", "float64").subscribe("y", "float64").text();
/// ```
#[derive(Debug, Clone)]
pub struct OneDomain {
    name: String,
    synchronous: bool,
    publish: Vec<(String, String)>,
    subscribe: Vec<(String, String)>,
}

/// A DDF with one asynchronous domain `name` that allows several publishers, has no
/// states and no items yet.
pub fn one_domain(name: &str) -> OneDomain {
    OneDomain { name: name.into(), synchronous: false, publish: Vec::new(), subscribe: Vec::new() }
}

impl OneDomain {
    /// Makes the domain synchronous (lock-step).
    pub fn synchronous(mut self) -> Self {
        self.synchronous = true;
        self
    }

    /// Adds PUBLISH item `name` of DDF type `ty` (`float64`, `int32`, …), one value.
    pub fn publish(mut self, name: &str, ty: &str) -> Self {
        self.publish.push((name.into(), ty.into()));
        self
    }

    /// Adds SUBSCRIBE item `name` of DDF type `ty`, one value.
    pub fn subscribe(mut self, name: &str, ty: &str) -> Self {
        self.subscribe.push((name.into(), ty.into()));
        self
    }

    /// The DDF's text.
    pub fn text(&self) -> String {
        self.to_string()
    }
}

impl fmt::Display for OneDomain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let yes_no = if self.synchronous { "yes" } else { "no" };
        writeln!(f, r#"<?xml version="1.0" encoding="UTF-8"?>"#)?;
        writeln!(f, "<orchestra>")?;
        writeln!(f, r#"  <domain name="{}">"#, self.name)?;
        writeln!(f, "    <synchronous>{yes_no}</synchronous>")?;
        writeln!(f, "    <multiplePublishAllowed>yes</multiplePublishAllowed>")?;
        writeln!(f, "    <states>no</states>")?;
        for (set, items) in [("PUBLISH", &self.publish), ("SUBSCRIBE", &self.subscribe)] {
            writeln!(f, r#"    <set name="{set}">"#)?;
            for (name, ty) in items {
                writeln!(f, r#"      <item name="{name}"><type>{ty}</type><length>1</length></item>"#)?;
            }
            writeln!(f, "    </set>")?;
        }
        writeln!(f, "  </domain>")?;
        writeln!(f, "</orchestra>")
    }
}
