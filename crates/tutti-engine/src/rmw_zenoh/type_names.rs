//! Type names as rmw_zenoh writes them in data keys and tokens.
//!
//! A message type `pkg/msg/Type` is written `pkg::msg::dds_::Type_` (`_create_type_name`,
//! `rmw_zenoh_cpp/src/detail/type_support_common.cpp:31-49`: the type support's
//! `message_namespace_`, which rosidl_typesupport_fastrtps makes `pkg::msg` from the interface's
//! path, then `::dds_::`, the name and `_`).
//!
//! A service `pkg/srv/Name` is written `pkg::srv::dds_::Name_`: the server takes its response
//! type's name `pkg::srv::dds_::Name_Response_` and cuts it at the last `Response_`
//! (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:77-90`), the client its request type's name at
//! the last `Request_` (`rmw_zenoh_cpp/src/detail/rmw_client_data.cpp:80-93`): both give the
//! message rule applied to the service's own name. The request and response messages themselves
//! are `pkg::srv::dds_::Name_Request_` and `pkg::srv::dds_::Name_Response_`
//! (`rmw_zenoh_cpp/src/detail/service_type_support.cpp:34-57`); they appear in no key. Actions'
//! services and messages follow the same rules (`pkg::action::dds_::Name_SendGoal_`).

/// Why a ROS 2 type name cannot be written.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TypeNameError {
    #[error("not a ROS 2 type name of the form pkg/msg/Type: {0:?}")]
    Malformed(String),
}

/// `pkg/msg/Type` as rmw_zenoh writes it: `pkg::msg::dds_::Type_`
/// (`rmw_zenoh_cpp/src/detail/type_support_common.cpp:39-48`). The name has a package, any
/// interface folders and a type, `/`-separated, none empty and none holding `:`, `/` or blanks.
pub fn dds_type_name(ros_type: &str) -> Result<String, TypeNameError> {
    let parts: Vec<&str> = ros_type.split('/').collect();
    let valid = |p: &&str| !p.is_empty() && !p.contains(|c: char| c == ':' || c.is_whitespace());
    if parts.len() < 2 || !parts.iter().all(valid) {
        return Err(TypeNameError::Malformed(ros_type.to_owned()));
    }
    let (name, namespace) = parts.split_last().ok_or_else(|| TypeNameError::Malformed(ros_type.to_owned()))?;
    Ok(format!("{}::dds_::{name}_", namespace.join("::")))
}

/// The type a service's key and tokens carry, `pkg/srv/Name` to `pkg::srv::dds_::Name_`
/// (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:80-90`,
/// `rmw_zenoh_cpp/src/detail/rmw_client_data.cpp:83-93`): the message rule.
pub fn service_type_name(ros_service_type: &str) -> Result<String, TypeNameError> {
    dds_type_name(ros_service_type)
}

/// A service's request message type, `pkg::srv::dds_::Name_Request_`
/// (`rmw_zenoh_cpp/src/detail/service_type_support.cpp:34-44`).
pub fn request_type_name(ros_service_type: &str) -> Result<String, TypeNameError> {
    dds_type_name(&format!("{ros_service_type}_Request"))
}

/// A service's response message type, `pkg::srv::dds_::Name_Response_`
/// (`rmw_zenoh_cpp/src/detail/service_type_support.cpp:47-57`).
pub fn response_type_name(ros_service_type: &str) -> Result<String, TypeNameError> {
    dds_type_name(&format!("{ros_service_type}_Response"))
}

/// The service type of a request type as rmw_zenoh names services
/// (`pkg::srv::dds_::Name_Request_` to `pkg::srv::dds_::Name_`); a name that is no request's
/// comes back as it is.
pub fn service_of_request(request_type: &str) -> String {
    match request_type.strip_suffix("Request_") {
        Some(service) if service.ends_with('_') => service.to_owned(),
        _ => request_type.to_owned(),
    }
}

/// The ROS 2 name of a type as written in a key or token, as rmw_zenoh's graph gives it to ROS 2
/// (`_demangle_if_ros_type`, `rmw_zenoh_cpp/src/detail/graph_cache.cpp:733-753`):
/// `pkg::msg::dds_::Type_` is `pkg/msg/Type`, services alike. A name that does not end in `_` or
/// holds no `dds_::` is "not a ROS type" and comes back unchanged, as there.
pub fn ros_type_name(dds_type: &str) -> String {
    const MARK: &str = "dds_::";
    if !dds_type.ends_with('_') {
        return dds_type.to_owned();
    }
    let Some(at) = dds_type.find(MARK) else {
        return dds_type.to_owned();
    };
    let start = at + MARK.len();
    // `dds_::` then at least the final `_`: start <= len - 1.
    let name = dds_type.get(start..dds_type.len() - 1).unwrap_or_default();
    format!("{}{name}", dds_type[..at].replace("::", "/"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_and_services_are_written_as_rmw_zenoh_writes_them() {
        assert_eq!(dds_type_name("std_msgs/msg/String").as_deref(), Ok("std_msgs::msg::dds_::String_"));
        let srv = "example_interfaces/srv/AddTwoInts";
        assert_eq!(service_type_name(srv).as_deref(), Ok("example_interfaces::srv::dds_::AddTwoInts_"));
        assert_eq!(request_type_name(srv).as_deref(), Ok("example_interfaces::srv::dds_::AddTwoInts_Request_"));
        assert_eq!(response_type_name(srv).as_deref(), Ok("example_interfaces::srv::dds_::AddTwoInts_Response_"));
        // The server's rule: the response type cut at its last "Response_".
        let response = response_type_name(srv).expect("valid");
        let cut = response.rfind("Response_").map(|at| &response[..at]);
        assert_eq!(cut, service_type_name(srv).ok().as_deref());
        assert_eq!(
            dds_type_name("action_tutorials_interfaces/action/Fibonacci_SendGoal").as_deref(),
            Ok("action_tutorials_interfaces::action::dds_::Fibonacci_SendGoal_")
        );
    }

    #[test]
    fn a_request_type_names_its_service() {
        let srv = "example_interfaces/srv/AddTwoInts";
        let request = request_type_name(srv).expect("valid");
        assert_eq!(Ok(service_of_request(&request)), service_type_name(srv));
        let send_goal = "simulation_interfaces::action::dds_::SimulateSteps_SendGoal_Request_";
        assert_eq!(service_of_request(send_goal), "simulation_interfaces::action::dds_::SimulateSteps_SendGoal_");
        for not_a_request in ["", "Request_", "pkg::msg::dds_::Request_", "a::b::X_Response_"] {
            assert_eq!(service_of_request(not_a_request), not_a_request);
        }
    }

    #[test]
    fn ros_names_come_back() {
        assert_eq!(ros_type_name("std_msgs::msg::dds_::String_"), "std_msgs/msg/String");
        assert_eq!(ros_type_name("example_interfaces::srv::dds_::AddTwoInts_"), "example_interfaces/srv/AddTwoInts");
        for not_ros in ["", "_", "Foo", "dds_::", "a::b::Type_"] {
            assert_eq!(ros_type_name(not_ros), not_ros);
        }
        assert_eq!(ros_type_name("dds_::_"), "");
    }

    #[test]
    fn malformed_names_are_refused() {
        for bad in ["", "String", "std_msgs//String", "/std_msgs/msg/String", "a::b/msg/C", "a/msg/B C"] {
            assert!(dds_type_name(bad).is_err(), "{bad:?}");
        }
    }
}
