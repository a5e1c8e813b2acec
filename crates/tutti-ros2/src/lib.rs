//! tutti's ROS 2 interfaces, each defined once, by its `.msg`, `.srv` or `.action` file.
//!
//! The files of the ROS 2 packages tutti speaks lie in `interfaces/PKG/{msg,srv,action}/`,
//! byte for byte as ROS 2 Jazzy ships them (`interfaces/SOURCES.txt` names each package's
//! repository and commit). The build embeds them; the first call to [`registry()`] parses
//! them ([`parse`], as `rosidl_adapter` reads them) into a [`Registry`] of message specs,
//! with the messages rosidl makes of each service and action. From a spec come:
//!
//! * its type description and RIHS01 hash ([`typehash`]: what a ROS 2 endpoint announces);
//! * its plain CDR, both ways, over a [`Value`] tree ([`cdr`], [`Message::encode`],
//!   [`Message::decode`]);
//! * its `.msg` and IDL text ([`idl::write`]).
//!
//! A DDF's sets are messages too ([`idl`]): `tutti idl` writes them, and their hashes and CDR
//! come from the same code. Adding a message to tutti is adding its file under `interfaces/`.
//!
//! ```
//! use tutti_ros2::{registry, Struct, Value};
//!
//! let msg = registry().message("std_msgs/msg/Float64").expect("a stock message");
//! let body = msg.encode(&Struct::new().with("data", 1.5).into()).expect("a Float64");
//! assert_eq!(body, 1.5f64.to_le_bytes());
//! assert_eq!(msg.decode(&body, true).unwrap().get("data"), Some(&Value::Float(1.5)));
//! assert!(msg.hash().to_string().starts_with("RIHS01_705ba9c3"));
//! let ok = registry().message("simulation_interfaces/msg/Result").and_then(|m| m.constant("RESULT_OK").cloned());
//! assert_eq!(ok, Some(Value::UInt(1)));
//! ```
//!
//! [`simulation`] is ROS 2's `simulation_interfaces` services and action as a tutti run serves
//! them, over these messages.
//!
//! No DDS crate, no async runtime: the engines (`tutti-engine`) stand on this crate.

pub mod cdr;
pub mod clock;
pub mod env;
pub mod idl;
pub mod names;
pub mod parse;
pub mod registry;
pub mod simulation;
pub mod spec;
pub mod typehash;
pub mod value;

pub use cdr::CdrError;
pub use parse::{ParseError, Problem};
pub use registry::{registry, Action, Message, Registry, RegistryBuilder, RegistryError, Service};
pub use spec::{
    ActionSpec, BaseType, Constant, Field, FieldType, Kind, MessageSpec, Primitive, ServiceSpec, Shape, TypeName,
};
pub use typehash::{TypeDescription, TypeHash};
pub use value::{Struct, Value};
