//! The key expressions data travels on: one per topic and one per service.
//!
//! rmw_zenoh builds a topic's key in `TopicInfo`'s constructor
//! (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:76-94`): `<domain id>/<name>/<type>/<type
//! hash>`, the name with one leading and one trailing `/` cut (`strip_slashes`,
//! `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:61-73`), so `/ns/chatter` of
//! `std_msgs/msg/String` in domain 0 is `0/ns/chatter/std_msgs::msg::dds_::String_/RIHS01_<64 hex
//! digits>`. The type is written as [`crate::rmw_zenoh::type_names`] says; the hash is
//! `rosidl_stringify_type_hash` of the type's hash
//! (`rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:72-90`).
//!
//! A publisher publishes on it (`rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:134`), a
//! subscription subscribes to it (`rmw_zenoh_cpp/src/detail/rmw_subscription_data.cpp:168`). A
//! service is the same with the service's name, its type `pkg::srv::dds_::Name_` and the service
//! type's hash: the server declares a queryable on it
//! (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:129-157`) and replies on that same key
//! (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:454`); the client queries it
//! (`rmw_zenoh_cpp/src/detail/rmw_client_data.cpp:132-149`). Requests and replies share one key;
//! no `rq/`/`rr/` pair as in DDS.

use super::liveliness::TopicInfo;

/// A topic's or service's data key, its parts as ROS 2 names them.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct DataKey {
    pub domain_id: u64,
    /// The fully qualified name, with its leading `/` (`/ns/chatter`).
    pub name: String,
    /// The type as rmw_zenoh writes it (`std_msgs::msg::dds_::String_`).
    pub type_name: String,
    /// `RIHS01_…`, as written.
    pub type_hash: String,
}

/// Why a data key cannot be written or read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DataKeyError {
    #[error("a data key has at least 4 '/'-separated chunks, this one has {0}")]
    TooFewChunks(usize),
    #[error("a key expression has no empty chunk: {0:?}")]
    EmptyChunk(String),
    #[error("the domain id is not a decimal number: {0:?}")]
    BadDomain(String),
    #[error("not a fully qualified ROS 2 name for a key: {0:?}")]
    BadName(String),
    #[error("the {field} is empty or holds '/' or one of Zenoh's '*', '$', '?', '#': {value:?}")]
    BadField { field: &'static str, value: String },
}

/// Zenoh's reserved characters: no chunk of a plain key may hold them.
pub(crate) fn zenoh_reserved(c: char) -> bool {
    matches!(c, '*' | '$' | '?' | '#')
}

fn check_field(field: &'static str, value: &str) -> Result<(), DataKeyError> {
    if value.is_empty() || value.contains(|c| c == '/' || zenoh_reserved(c)) {
        return Err(DataKeyError::BadField { field, value: value.to_owned() });
    }
    Ok(())
}

impl DataKey {
    /// The key of a token's topic or service in `domain_id` (`TopicInfo`'s constructor,
    /// `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:76-94`).
    pub fn for_topic(domain_id: u64, topic: &TopicInfo) -> DataKey {
        DataKey {
            domain_id,
            name: topic.name.clone(),
            type_name: topic.type_name.clone(),
            type_hash: topic.type_hash.clone(),
        }
    }

    /// The key expression (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:87-93`). The name must
    /// be a fully qualified name (`/` then non-empty `/`-separated chunks, no trailing `/`), for
    /// which `strip_slashes` cuts just the leading `/`.
    pub fn to_keyexpr(&self) -> Result<String, DataKeyError> {
        let bad_name = || DataKeyError::BadName(self.name.clone());
        let relative = self.name.strip_prefix('/').ok_or_else(bad_name)?;
        if relative.split('/').any(|c| c.is_empty() || c.contains(zenoh_reserved)) {
            return Err(bad_name());
        }
        check_field("type name", &self.type_name)?;
        check_field("type hash", &self.type_hash)?;
        Ok(format!("{}/{relative}/{}/{}", self.domain_id, self.type_name, self.type_hash))
    }

    /// The parts of a data key: the first chunk the domain, the last two the type and its hash,
    /// those between the name.
    pub fn parse(key: &str) -> Result<DataKey, DataKeyError> {
        let chunks: Vec<&str> = key.split('/').collect();
        if chunks.len() < 4 {
            return Err(DataKeyError::TooFewChunks(chunks.len()));
        }
        if chunks.iter().any(|c| c.is_empty()) {
            return Err(DataKeyError::EmptyChunk(key.to_owned()));
        }
        let domain_id = super::parse_decimal(chunks[0]).ok_or_else(|| DataKeyError::BadDomain(chunks[0].to_owned()))?;
        let (type_hash, rest) = chunks[1..].split_last().ok_or(DataKeyError::TooFewChunks(chunks.len()))?;
        let (type_name, name) = rest.split_last().ok_or(DataKeyError::TooFewChunks(chunks.len()))?;
        let key = DataKey {
            domain_id,
            name: format!("/{}", name.join("/")),
            type_name: (*type_name).to_owned(),
            type_hash: (*type_hash).to_owned(),
        };
        key.to_keyexpr()?;
        Ok(key)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HASH: &str = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";

    fn key(domain_id: u64, name: &str, type_name: &str) -> DataKey {
        DataKey { domain_id, name: name.into(), type_name: type_name.into(), type_hash: HASH.into() }
    }

    #[test]
    fn topic_and_service_keys() {
        let topic = key(0, "/chatter", "std_msgs::msg::dds_::String_");
        let text = format!("0/chatter/std_msgs::msg::dds_::String_/{HASH}");
        assert_eq!(topic.to_keyexpr().as_deref(), Ok(text.as_str()));
        assert_eq!(DataKey::parse(&text), Ok(topic));
        let nested = key(42, "/a/b/c", "std_msgs::msg::dds_::String_");
        let text = format!("42/a/b/c/std_msgs::msg::dds_::String_/{HASH}");
        assert_eq!(nested.to_keyexpr().as_deref(), Ok(text.as_str()));
        assert_eq!(DataKey::parse(&text), Ok(nested));
        let service = key(0, "/add_two_ints", "example_interfaces::srv::dds_::AddTwoInts_");
        let text = format!("0/add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/{HASH}");
        assert_eq!(service.to_keyexpr().as_deref(), Ok(text.as_str()));
    }

    #[test]
    fn bad_keys_are_refused() {
        for name in ["chatter", "/", "//a", "/a/", "/a//b", "/a*"] {
            assert_eq!(key(0, name, "T_").to_keyexpr(), Err(DataKeyError::BadName(name.into())), "{name:?}");
        }
        assert!(matches!(key(0, "/a", "").to_keyexpr(), Err(DataKeyError::BadField { .. })));
        assert_eq!(DataKey::parse("0/a/T_"), Err(DataKeyError::TooFewChunks(3)));
        assert!(matches!(DataKey::parse("0//a/T_/H"), Err(DataKeyError::EmptyChunk(_))));
        assert!(matches!(DataKey::parse("x/a/T_/H"), Err(DataKeyError::BadDomain(_))));
        assert!(matches!(DataKey::parse("0/a/T_/H*"), Err(DataKeyError::BadField { .. })));
    }
}
