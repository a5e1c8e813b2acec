//! Helpers shared by the shared-memory tests.

use tutti_core::ddf::{self, Model};

/// A model of one domain "d" with the three flags and the given PUBLISH and SUBSCRIBE
/// items (DDF `<item>` elements).
pub fn domain(sync: bool, mpa: bool, states: bool, publish: &str, subscribe: &str) -> Model {
    let yn = |b| if b { "yes" } else { "no" };
    ddf::parse_str(
        &format!(
            r#"<orchestra><domain name="d"><synchronous>{}</synchronous><multiplePublishAllowed>{}</multiplePublishAllowed><states>{}</states>
            <set name="PUBLISH">{publish}</set>
            <set name="SUBSCRIBE">{subscribe}</set>
            </domain></orchestra>"#,
            yn(sync),
            yn(mpa),
            yn(states)
        ),
        "test.ddf",
    )
    .unwrap()
}
