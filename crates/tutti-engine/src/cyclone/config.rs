//! The participant's configuration: the domain's XML config (receive threads, interfaces,
//! peers) over `CYCLONEDDS_URI`, and the participant with its lease.

use std::net::IpAddr;
use std::ptr;
use std::time::Duration;

use cyclors::{
    dds_create_domain, dds_create_participant, dds_create_qos, dds_entity_t,
    dds_liveliness_kind_DDS_LIVELINESS_AUTOMATIC, dds_qset_liveliness, dds_qset_prop, dds_qset_userdata,
    DDS_RETCODE_OUT_OF_RESOURCES, DDS_RETCODE_PRECONDITION_NOT_MET,
};

use super::native::{c_string, retcode, NativeQos};
use crate::security::Enclave;
use crate::{EngineConfig, EngineError};

/// Escapes a value for an XML attribute in double quotes.
fn xml_attr(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// The configuration for `dds_create_domain`, or None when there is nothing to add to
/// `CYCLONEDDS_URI` (`env`): its value first, then the fragment for `interfaces` and `cfg.peers`.
pub(super) fn domain_config(cfg: &EngineConfig, interfaces: &[IpAddr], env: Option<&str>) -> Option<String> {
    let threads = !env.is_some_and(sets_receive_threads);
    if interfaces.is_empty() && cfg.peers.is_empty() && !threads {
        return None;
    }
    let mut fragment = String::new();
    if threads {
        fragment.push_str(RECEIVE_THREADS);
    }
    if !interfaces.is_empty() {
        fragment.push_str("<General><Interfaces>");
        for ip in interfaces {
            fragment.push_str(&format!("<NetworkInterface address=\"{}\"/>", xml_attr(&ip.to_string())));
        }
        fragment.push_str("</Interfaces></General>");
    }
    // Loopback has no multicast: a participant restricted to it finds the others on this
    // machine by unicast, at the well-known ports of their participant indices.
    let loopback = ["127.0.0.1".to_string()];
    let peers = if cfg.peers.is_empty() && !interfaces.is_empty() && interfaces.iter().all(IpAddr::is_loopback) {
        &loopback[..]
    } else {
        &cfg.peers[..]
    };
    if !peers.is_empty() {
        fragment.push_str("<Discovery><Peers>");
        for p in peers {
            fragment.push_str(&format!("<Peer address=\"{}\"/>", xml_attr(p)));
        }
        fragment.push_str(
            "</Peers><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>50</MaxAutoParticipantIndex>\
             </Discovery>",
        );
    }
    Some(match env {
        Some(e) => format!("{e},{fragment}"),
        None => fragment,
    })
}

/// One receive thread per socket, blocking in `recvmsg` (Cyclone 0.10's default, and what
/// `ddsperf` from Debian's cyclonedds-tools runs with), rather than Cyclone 11's one thread
/// multiplexing every socket with `epoll_wait` + `recvmsg`: one system call less per packet,
/// 0.6-0.8 µs of a one-core round trip (docs/benchmarks.md, "Where a one-core round trip
/// goes"). Cyclone wakes such threads at shutdown with a datagram to their own socket, which
/// a host firewall must let through; `CYCLONEDDS_URI` may set `MultipleReceiveThreads` itself.
pub(super) const RECEIVE_THREADS: &str = "<Internal><MultipleReceiveThreads>true</MultipleReceiveThreads></Internal>";

/// Whether `CYCLONEDDS_URI` (inline XML and `file://` entries, comma-separated) sets
/// `MultipleReceiveThreads` itself: then it stands.
fn sets_receive_threads(env: &str) -> bool {
    env.split(',').any(|part| {
        let part = part.trim();
        match part.strip_prefix("file://") {
            Some(path) => std::fs::read_to_string(path).is_ok_and(|t| t.contains("MultipleReceiveThreads")),
            None => part.contains("MultipleReceiveThreads"),
        }
    })
}

/// A participant on domain `id` announcing `lease` (None: Cyclone's, `Discovery/LeaseDuration`,
/// 10 s by default), in `enclave` (None: unsecured): its handle or Cyclone's return code. The
/// lease is the participant's automatic liveliness, which Cyclone renews every 4/5 of it.
///
/// As rmw_cyclonedds does, the participant's USER_DATA names its enclave (`enclave=/;` when
/// unsecured), and a secured participant gets the enclave's six files as DDS Security
/// properties (`file:` URIs) with the three plugins that Cyclone has built in
/// (`dds_security_auth`, `dds_security_ac`, `dds_security_crypto`).
pub(super) fn create_participant(
    id: u32,
    lease: Option<Duration>,
    enclave: Option<&Enclave>,
) -> Result<dds_entity_t, EngineError> {
    // SAFETY: plain allocation; null on failure.
    let qos = unsafe { dds_create_qos() };
    if qos.is_null() {
        return Ok(DDS_RETCODE_OUT_OF_RESOURCES);
    }
    let qos = NativeQos(qos);
    let user_data = format!("enclave={};", enclave.map_or(crate::security::DEFAULT_ENCLAVE, |e| e.name.as_str()));
    // SAFETY: `qos.0` is a valid QoS object; the setters copy their arguments.
    unsafe { dds_qset_userdata(qos.0, user_data.as_ptr().cast(), user_data.len()) };
    if let Some(lease) = lease {
        let ns = i64::try_from(lease.as_nanos()).unwrap_or(i64::MAX);
        // SAFETY: as above.
        unsafe { dds_qset_liveliness(qos.0, dds_liveliness_kind_DDS_LIVELINESS_AUTOMATIC, ns) };
    }
    if let Some(e) = enclave {
        for (name, value) in security_properties(e) {
            let (name, value) = (c_string("a DDS Security property", &name)?, c_string("a keystore path", &value)?);
            // SAFETY: as above; both strings are NUL-terminated.
            unsafe { dds_qset_prop(qos.0, name.as_ptr(), value.as_ptr()) };
        }
    }
    // SAFETY: a valid QoS, copied during the call; no listener.
    Ok(unsafe { dds_create_participant(id, qos.0, ptr::null()) })
}

/// Cyclone's three built-in DDS Security plugins: the prefix of their properties, their
/// element in Cyclone's XML configuration, their library and its init and finalize functions.
const PLUGINS: [(&str, &str, &str, &str, &str); 3] = [
    ("dds.sec.auth", "Authentication", "dds_security_auth", "init_authentication", "finalize_authentication"),
    ("dds.sec.access", "AccessControl", "dds_security_ac", "init_access_control", "finalize_access_control"),
    ("dds.sec.crypto", "Cryptographic", "dds_security_crypto", "init_crypto", "finalize_crypto"),
];

/// The enclave's six files as `file:` URIs, each with its property and its element in
/// Cyclone's XML configuration (both under its plugin's, [`PLUGINS`]).
fn enclave_files(e: &Enclave) -> [(&'static str, &'static str, String); 6] {
    let file = |p: &std::path::Path| format!("file:{}", std::path::absolute(p).unwrap_or_else(|_| p.into()).display());
    [
        ("dds.sec.auth.identity_ca", "IdentityCA", file(&e.identity_ca)),
        ("dds.sec.auth.identity_certificate", "IdentityCertificate", file(&e.certificate)),
        ("dds.sec.auth.private_key", "PrivateKey", file(&e.private_key)),
        ("dds.sec.access.permissions_ca", "PermissionsCA", file(&e.permissions_ca)),
        ("dds.sec.access.governance", "Governance", file(&e.governance)),
        ("dds.sec.access.permissions", "Permissions", file(&e.permissions)),
    ]
}

/// The DDS Security properties rmw_cyclonedds gives a participant in `e`.
pub(super) fn security_properties(e: &Enclave) -> Vec<(String, String)> {
    let mut props: Vec<(String, String)> =
        enclave_files(e).into_iter().map(|(prop, _, uri)| (prop.to_string(), uri)).collect();
    for (prefix, _, library, init, finalize) in PLUGINS {
        props.push((format!("{prefix}.library.path"), library.into()));
        props.push((format!("{prefix}.library.init"), init.into()));
        props.push((format!("{prefix}.library.finalize"), finalize.into()));
    }
    if let Some(crl) = &e.crl {
        let crl = std::path::absolute(crl).unwrap_or_else(|_| crl.clone());
        props.push(("org.eclipse.cyclonedds.sec.auth.crl".into(), format!("file:{}", crl.display())));
    }
    props
}

/// The same as the `<Security>` element of a Cyclone XML configuration (`CYCLONEDDS_URI`),
/// for another Cyclone program in enclave `e` (`ddsperf`, in the tests and the benchmark);
/// without the enclave's CRL.
pub fn security_xml(e: &Enclave) -> String {
    let files = enclave_files(e);
    let mut xml = String::from("<Security>");
    for (prefix, element, library, init, finalize) in PLUGINS {
        xml +=
            &format!(r#"<{element}><Library path="{library}" initFunction="{init}" finalizeFunction="{finalize}"/>"#);
        let ours = format!("{prefix}.");
        for (_, name, uri) in files.iter().filter(|(prop, ..)| prop.starts_with(&ours)) {
            xml += &format!("<{name}>{}</{name}>", xml_attr(uri));
        }
        xml += &format!("</{element}>");
    }
    xml + "</Security>"
}

/// Creates domain `id` with configuration `conf`: the handle or Cyclone's return code.
pub(super) fn create_domain(id: u32, conf: &str) -> Result<dds_entity_t, EngineError> {
    let cconf = c_string("Cyclone configuration", conf)?;
    // SAFETY: a NUL-terminated string that Cyclone parses during the call.
    Ok(unsafe { dds_create_domain(id, cconf.as_ptr()) })
}

/// The domain of `cfg.domain_id` with our configuration over `CYCLONEDDS_URI`, when there is
/// something to add to it (None: the participant makes the domain as the environment says, or
/// another participant of this process made it already and its configuration stands).
pub(super) fn domain(cfg: &EngineConfig) -> Result<Option<dds_entity_t>, EngineError> {
    let domain_id = u32::from(cfg.domain_id);
    let env = std::env::var("CYCLONEDDS_URI").ok();
    let env = env.as_deref().map(str::trim).filter(|e| !e.is_empty());
    let Some(conf) = domain_config(cfg, &cfg.interfaces, env) else { return Ok(None) };
    let mut d = create_domain(domain_id, &conf)?;
    let mut conf = Some(conf);
    if d < 0 && d != DDS_RETCODE_PRECONDITION_NOT_MET && env.is_some() && !cfg.interfaces.is_empty() {
        // Interface lists add up, and Cyclone refuses an interface selected twice (one that
        // CYCLONEDDS_URI names already): keep the environment's interfaces then.
        tracing::warn!(
            "cyclone: CYCLONEDDS_URI and the interfaces {:?} do not combine ({}); using the interfaces of \
             CYCLONEDDS_URI",
            cfg.interfaces,
            retcode(d)
        );
        conf = domain_config(cfg, &[], env);
        d = match &conf {
            Some(c) => create_domain(domain_id, c)?,
            None => 0,
        };
    }
    if d == DDS_RETCODE_PRECONDITION_NOT_MET {
        // Another participant of this process made the domain already: its config stands.
        if cfg.interfaces.is_empty() && cfg.peers.is_empty() {
            tracing::debug!("cyclone: domain {domain_id} already exists in this process; its config stands");
        } else {
            tracing::warn!("cyclone: domain {domain_id} already exists in this process; interfaces/peers not applied");
        }
        Ok(None)
    } else if d < 0 {
        let conf = conf.unwrap_or_default();
        Err(EngineError::dds(format!("domain {domain_id} with config {conf}"), retcode(d)))
    } else {
        Ok((d > 0).then_some(d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_fragment() {
        let mut cfg = EngineConfig::default();
        // One receive thread per socket, unless the environment's config says.
        assert_eq!(domain_config(&cfg, &[], Some("<x/>")).as_deref(), Some(&*format!("<x/>,{RECEIVE_THREADS}")));
        assert_eq!(domain_config(&cfg, &[], None).as_deref(), Some(RECEIVE_THREADS));
        let own = "<Internal><MultipleReceiveThreads>false</MultipleReceiveThreads></Internal>";
        assert_eq!(domain_config(&cfg, &[], Some(own)), None);
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("c.xml");
        std::fs::write(&file, format!("<CycloneDDS><Domain>{own}</Domain></CycloneDDS>")).unwrap();
        assert_eq!(domain_config(&cfg, &[], Some(&format!("<y/>, file://{}", file.display()))), None);
        cfg.interfaces = vec!["127.0.0.1".parse().unwrap()];
        cfg.peers = vec!["host\"a".into()];
        let c = domain_config(&cfg, &cfg.interfaces, Some("file:///etc/c.xml")).unwrap();
        assert!(c.starts_with(&format!(
            "file:///etc/c.xml,{RECEIVE_THREADS}<General><Interfaces><NetworkInterface address=\"127.0.0.1\"/>"
        )));
        assert!(c.contains("<Peer address=\"host&quot;a\"/>"));
        assert!(c.ends_with("<MaxAutoParticipantIndex>50</MaxAutoParticipantIndex></Discovery>"));
        assert!(!domain_config(&cfg, &cfg.interfaces, None).unwrap().contains(','));
        assert!(!domain_config(&cfg, &[], None).unwrap().contains("Interfaces"));
        // Loopback only and no peers: the other participants on loopback are the peers.
        cfg.peers.clear();
        assert!(domain_config(&cfg, &cfg.interfaces, None).unwrap().contains("<Peer address=\"127.0.0.1\"/>"));
        cfg.interfaces = vec!["192.0.2.1".parse().unwrap()];
        assert!(!domain_config(&cfg, &cfg.interfaces, None).unwrap().contains("Peer"));
    }
}
