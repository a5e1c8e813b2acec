//! Liveliness tokens: how rmw_zenoh tells the graph its nodes, publishers, subscriptions,
//! services and clients exist (`Entity`,
//! `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:435-619`).
//!
//! A token's key is `/`-separated fields in this order (`KeyexprIndex`,
//! `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:100-115`):
//!
//! `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node name>` and,
//! for all but nodes, `/<topic or service name>/<type>/<type hash>/<QoS>`.
//!
//! * `@ros2_lv` is the admin space (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:122`);
//! * the domain id and the node and entity ids are decimal (`std::to_string`); a node's entity id
//!   is its node id (`rmw_zenoh_cpp/src/detail/rmw_node_data.cpp:43-46`), and both come from one
//!   counter per context (`rmw_zenoh_cpp/src/detail/rmw_context_impl_s.cpp:129-132`);
//! * the zid is the session's id ([`ZenohId`]);
//! * the kind is `NN` node, `MP` publisher, `MS` subscription, `SS` service server, `SC` service
//!   client (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:123-127`);
//! * the enclave, namespace, node name, topic name, type and type hash are "mangled": every `/`
//!   becomes `%` (`mangle_name`, `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:697-708`), so the
//!   root namespace `/` is `%` and `/ns/chatter` is `%ns%chatter`; the enclave is rcl's, `/` by
//!   default;
//! * the QoS is [`QosProfile::to_keyexpr`] of the profile as rmw_zenoh adapts it
//!   ([`QosProfile::adapted`]).
//!
//! Reading a key (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:536-619`) needs at least the 9
//! fields up to the node name, none empty, the admin space and a known kind; all but nodes need
//! the 13 fields and a valid QoS. Fields beyond those are ignored. `%` reads back as `/`
//! (`demangle_name`, `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:711-722`). A liveliness
//! subscriber of rmw_zenoh listens on `@ros2_lv/<domain>/**` ([`subscription_key`],
//! `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:428-432`).

use super::gid::{gid_of_key, Gid};
use super::keyexpr::DataKey;
use super::qos::{QosError, QosProfile};
use super::zid::{ZenohId, ZidError};

/// The admin space every token key starts with
/// (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:122`).
pub const ADMIN_SPACE: &str = "@ros2_lv";

/// The node an entity belongs to (`NodeInfo`,
/// `rmw_zenoh_cpp/src/detail/liveliness_utils.hpp:36-48`).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct NodeInfo {
    pub domain_id: u64,
    /// The node's namespace, `/` for the root one.
    pub namespace: String,
    pub name: String,
    /// The security enclave, `/` unless one is given.
    pub enclave: String,
}

/// The topic or service of an entity that is not a node (`TopicInfo`,
/// `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:76-94`).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct TopicInfo {
    /// The fully qualified topic or service name (`/chatter`).
    pub name: String,
    /// The type as rmw_zenoh writes it ([`crate::rmw_zenoh::type_names`]).
    pub type_name: String,
    /// `RIHS01_…`.
    pub type_hash: String,
    pub qos: QosProfile,
}

/// What an entity is, with its topic or service for all but nodes.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum EntityKind {
    Node,
    Publisher(TopicInfo),
    Subscription(TopicInfo),
    Service(TopicInfo),
    Client(TopicInfo),
}

impl EntityKind {
    /// The kind's field in a token (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:123-139`).
    pub fn tag(&self) -> &'static str {
        match self {
            EntityKind::Node => "NN",
            EntityKind::Publisher(_) => "MP",
            EntityKind::Subscription(_) => "MS",
            EntityKind::Service(_) => "SS",
            EntityKind::Client(_) => "SC",
        }
    }

    /// The topic or service; None for a node.
    pub fn topic(&self) -> Option<&TopicInfo> {
        match self {
            EntityKind::Node => None,
            EntityKind::Publisher(t) | EntityKind::Subscription(t) | EntityKind::Service(t) | EntityKind::Client(t) => {
                Some(t)
            }
        }
    }

    fn from_tag(tag: &str, topic: TopicInfo) -> Option<EntityKind> {
        Some(match tag {
            "MP" => EntityKind::Publisher(topic),
            "MS" => EntityKind::Subscription(topic),
            "SS" => EntityKind::Service(topic),
            "SC" => EntityKind::Client(topic),
            _ => return None,
        })
    }
}

/// One entity of the ROS 2 graph as its liveliness token says it.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Entity {
    pub zid: ZenohId,
    pub node_id: u64,
    pub entity_id: u64,
    pub node: NodeInfo,
    pub kind: EntityKind,
}

/// Why a token key cannot be written or read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TokenError {
    #[error("a token key has at least {expected} '/'-separated fields, this one has {found}")]
    TooFewFields { found: usize, expected: usize },
    #[error("field {index} of the token key is empty")]
    EmptyField { index: usize },
    #[error("a token key starts with {ADMIN_SPACE:?}, not {0:?}")]
    AdminSpace(String),
    #[error("unknown entity kind {0:?} (NN, MP, MS, SS or SC)")]
    BadKind(String),
    #[error("the {field} is not a decimal number: {value:?}")]
    BadNumber { field: &'static str, value: String },
    #[error("bad session id: {0}")]
    BadZid(#[from] ZidError),
    #[error("bad QoS: {0}")]
    BadQos(#[from] QosError),
    #[error("the {field} cannot be written in a token (empty, or holds '%' or one of '*', '$', '?', '#'): {value:?}")]
    Unwritable { field: &'static str, value: String },
}

/// Every `/` as `%` (`mangle_name`, `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:697-708`).
pub fn mangle_name(name: &str) -> String {
    name.replace('/', "%")
}

/// Every `%` as `/` (`demangle_name`, `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:711-722`).
pub fn demangle_name(name: &str) -> String {
    name.replace('%', "/")
}

/// The key rmw_zenoh's graph subscribes to for `domain_id`'s tokens (`subscription_token`,
/// `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:428-432`).
pub fn subscription_key(domain_id: u64) -> String {
    format!("{ADMIN_SPACE}/{domain_id}/**")
}

/// A field mangled for a token, refused where rmw_zenoh would write a key it cannot read back or
/// Zenoh would refuse.
fn mangled(field: &'static str, value: &str) -> Result<String, TokenError> {
    if value.is_empty() || value.contains(|c| c == '%' || super::keyexpr::zenoh_reserved(c)) {
        return Err(TokenError::Unwritable { field, value: value.to_owned() });
    }
    Ok(mangle_name(value))
}

fn number(field: &'static str, value: &str) -> Result<u64, TokenError> {
    super::parse_decimal(value).ok_or_else(|| TokenError::BadNumber { field, value: value.to_owned() })
}

impl Entity {
    /// The token's key expression (`Entity`'s constructor,
    /// `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:449-484`).
    pub fn to_key(&self) -> Result<String, TokenError> {
        let mut fields = vec![
            ADMIN_SPACE.to_owned(),
            self.node.domain_id.to_string(),
            self.zid.to_string(),
            self.node_id.to_string(),
            self.entity_id.to_string(),
            self.kind.tag().to_owned(),
            mangled("enclave", &self.node.enclave)?,
            mangled("namespace", &self.node.namespace)?,
            mangled("node name", &self.node.name)?,
        ];
        if let Some(topic) = self.kind.topic() {
            fields.push(mangled("topic name", &topic.name)?);
            fields.push(mangled("type name", &topic.type_name)?);
            fields.push(mangled("type hash", &topic.type_hash)?);
            fields.push(topic.qos.to_keyexpr());
        }
        Ok(fields.join("/"))
    }

    /// The entity a token key stands for (`Entity::make(const std::string &)`,
    /// `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:536-619`).
    pub fn parse(key: &str) -> Result<Entity, TokenError> {
        let fields: Vec<&str> = key.split('/').collect();
        if fields.len() < 9 {
            return Err(TokenError::TooFewFields { found: fields.len(), expected: 9 });
        }
        if let Some(index) = fields.iter().position(|f| f.is_empty()) {
            return Err(TokenError::EmptyField { index });
        }
        if fields[0] != ADMIN_SPACE {
            return Err(TokenError::AdminSpace(fields[0].to_owned()));
        }
        let tag = fields[5];
        if !["NN", "MP", "MS", "SS", "SC"].contains(&tag) {
            return Err(TokenError::BadKind(tag.to_owned()));
        }
        let node = NodeInfo {
            domain_id: number("domain id", fields[1])?,
            enclave: demangle_name(fields[6]),
            namespace: demangle_name(fields[7]),
            name: demangle_name(fields[8]),
        };
        let zid = fields[2].parse::<ZenohId>()?;
        let node_id = number("node id", fields[3])?;
        let entity_id = number("entity id", fields[4])?;
        let kind = if tag == "NN" {
            EntityKind::Node
        } else {
            if fields.len() < 13 {
                return Err(TokenError::TooFewFields { found: fields.len(), expected: 13 });
            }
            let topic = TopicInfo {
                qos: QosProfile::from_keyexpr(fields[12])?,
                name: demangle_name(fields[9]),
                type_name: demangle_name(fields[10]),
                type_hash: demangle_name(fields[11]),
            };
            EntityKind::from_tag(tag, topic).ok_or_else(|| TokenError::BadKind(tag.to_owned()))?
        };
        Ok(Entity { zid, node_id, entity_id, node, kind })
    }

    /// The entity's GID: the hash of its key
    /// (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:486-493`). For a parsed entity that is the
    /// key rmw_zenoh rebuilds from the fields it read, as here.
    pub fn gid(&self) -> Result<Gid, TokenError> {
        Ok(gid_of_key(&self.to_key()?))
    }

    /// The data key of its topic or service; None for a node.
    pub fn data_key(&self) -> Option<DataKey> {
        self.kind.topic().map(|topic| DataKey::for_topic(self.node.domain_id, topic))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node() -> Entity {
        Entity {
            zid: "1f".parse().expect("zid"),
            node_id: 3,
            entity_id: 3,
            node: NodeInfo { domain_id: 0, namespace: "/".into(), name: "n".into(), enclave: "/".into() },
            kind: EntityKind::Node,
        }
    }

    #[test]
    fn node_round_trip() {
        let n = node();
        assert_eq!(n.to_key().as_deref(), Ok("@ros2_lv/0/1f/3/3/NN/%/%/n"));
        assert_eq!(Entity::parse("@ros2_lv/0/1f/3/3/NN/%/%/n"), Ok(n.clone()));
        // Fields past the node name are ignored for a node, as rmw_zenoh ignores them.
        assert_eq!(Entity::parse("@ros2_lv/0/1f/3/3/NN/%/%/n/x/y"), Ok(n));
    }

    #[test]
    fn bad_keys_are_refused() {
        let e = |k: &str| Entity::parse(k).expect_err(k);
        assert_eq!(e("@ros2_lv/0/1f/3/3/NN/%/%"), TokenError::TooFewFields { found: 8, expected: 9 });
        assert_eq!(e("@ros2_lv/0/1f/3/3/NN//%/n"), TokenError::EmptyField { index: 6 });
        assert_eq!(e("@ros2/0/1f/3/3/NN/%/%/n"), TokenError::AdminSpace("@ros2".into()));
        assert_eq!(e("@ros2_lv/0/1f/3/3/XX/%/%/n"), TokenError::BadKind("XX".into()));
        assert!(matches!(e("@ros2_lv/a/1f/3/3/NN/%/%/n"), TokenError::BadNumber { field: "domain id", .. }));
        assert!(matches!(e("@ros2_lv/0/1F/3/3/NN/%/%/n"), TokenError::BadZid(_)));
        assert!(matches!(e("@ros2_lv/0/1f/-3/3/NN/%/%/n"), TokenError::BadNumber { field: "node id", .. }));
        assert!(matches!(e("@ros2_lv/0/1f/3/3x/NN/%/%/n"), TokenError::BadNumber { field: "entity id", .. }));
        assert_eq!(e("@ros2_lv/0/1f/3/4/MP/%/%/n/%t/T_/H"), TokenError::TooFewFields { found: 12, expected: 13 });
        assert!(matches!(e("@ros2_lv/0/1f/3/4/MP/%/%/n/%t/T_/H/::"), TokenError::BadQos(_)));
    }

    #[test]
    fn unwritable_fields_are_refused() {
        for (enclave, name) in [("", "n"), ("/", ""), ("/", "a%b"), ("/", "a*")] {
            let mut n = node();
            n.node.enclave = enclave.into();
            n.node.name = name.into();
            assert!(matches!(n.to_key(), Err(TokenError::Unwritable { .. })), "{enclave:?} {name:?}");
        }
    }

    #[test]
    fn subscription_key_for_a_domain() {
        assert_eq!(subscription_key(7), "@ros2_lv/7/**");
    }
}
