//! DDS Security as ROS 2 sets it up (SROS2, docs/security.md, "What the network can do"):
//! the gateway's identity is an enclave of a keystore, chosen as rcl chooses a node's
//! (`ROS_SECURITY_ENABLE`, `ROS_SECURITY_KEYSTORE`, `ROS_SECURITY_ENCLAVE_OVERRIDE`,
//! `ROS_SECURITY_STRATEGY`, or the gateway's flags and config keys of the same meaning).
//!
//! [`SecuritySettings::resolve`] finds the enclave's six files as rmw_dds_common does
//! (`identity_ca.cert.pem`, `cert.pem`, `key.pem`, `permissions_ca.cert.pem`,
//! `governance.p7s`, `permissions.p7s`) and checks them before DDS sees them, so that an
//! error names the file and the reason: the certificate against the identity CA (issuer,
//! validity), the key against the certificate, the two documents' S/MIME signatures against
//! the permissions CA, and the permissions' grant for the certificate's subject. DDS Security
//! (Cyclone's plugins) checks them again, and decides per topic what the permissions allow.
//! `Enforce` refuses to start on any of these errors; `Permissive` warns and runs unsecured,
//! as rcl does.

use std::path::{Path, PathBuf};

use openssl::pkcs7::{Pkcs7, Pkcs7Flags};
use openssl::pkey::{PKey, Private};
use openssl::stack::Stack;
use openssl::x509::store::{X509Store, X509StoreBuilder};
use openssl::x509::{X509StoreContext, X509};

use crate::EngineKind;

/// What to do when the enclave's files are missing or do not check out (`ROS_SECURITY_STRATEGY`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Strategy {
    /// Refuse to start (exit status 2), naming the file.
    Enforce,
    /// Warn, and run without DDS Security (rcl's default).
    #[default]
    Permissive,
}

impl std::str::FromStr for Strategy {
    type Err = SecurityError;
    fn from_str(s: &str) -> Result<Strategy, SecurityError> {
        match s.trim() {
            s if s.eq_ignore_ascii_case("enforce") => Ok(Strategy::Enforce),
            s if s.eq_ignore_ascii_case("permissive") => Ok(Strategy::Permissive),
            _ => Err(SecurityError::Strategy { value: s.escape_debug().to_string() }),
        }
    }
}

/// Whether engine `kind` takes an enclave: Cyclone only. rustdds' own DDS Security does
/// not complete a handshake with Cyclone's plugins (docs/security.md, "rustdds and DDS
/// Security"); Zenoh's wire is not DDS.
pub fn engine_does_security(kind: EngineKind) -> bool {
    kind == EngineKind::Cyclone
}

/// Why engine `engine` takes no enclave, for [`SecurityError::Unsupported`].
fn unsupported_why(engine: &str) -> &'static str {
    if engine == EngineKind::Rustdds.name() {
        "rustdds' handshake refuses Cyclone's ECDH key agreement: docs/security.md, \"rustdds and DDS Security\""
    } else {
        "its wire is not DDS; rmw_zenoh secures sessions in the Zenoh configuration"
    }
}

/// rcl's variables, as [`SecuritySettings::from_env`] reads them: enable, strategy, keystore,
/// enclave.
pub const ENV_VARS: [&str; 4] =
    ["ROS_SECURITY_ENABLE", "ROS_SECURITY_STRATEGY", "ROS_SECURITY_KEYSTORE", "ROS_SECURITY_ENCLAVE_OVERRIDE"];

/// The enclave rcl gives a node that names none.
pub const DEFAULT_ENCLAVE: &str = "/";

/// The security settings as given (flags over the config file over the environment).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SecuritySettings {
    /// `ROS_SECURITY_ENABLE=true`, `--security`, `security_enable: true`.
    pub enable: bool,
    /// `ROS_SECURITY_KEYSTORE`, `--security-keystore`, `security_keystore`.
    pub keystore: Option<PathBuf>,
    /// `ROS_SECURITY_ENCLAVE_OVERRIDE`, `--enclave`, `enclave` (default `/`).
    pub enclave: Option<String>,
    /// `ROS_SECURITY_STRATEGY`, `--security-strategy`, `security_strategy`.
    pub strategy: Strategy,
}

/// An enclave whose files checked out: what a DDS engine gives its participant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Enclave {
    /// Its name (`/tutti/gateway`), announced in the participant's USER_DATA.
    pub name: String,
    /// `KEYSTORE/enclaves/NAME`.
    pub dir: PathBuf,
    pub identity_ca: PathBuf,
    pub certificate: PathBuf,
    pub private_key: PathBuf,
    pub permissions_ca: PathBuf,
    pub governance: PathBuf,
    pub permissions: PathBuf,
    /// `crl.pem`, when the enclave has one.
    pub crl: Option<PathBuf>,
}

/// Why an enclave cannot be used; each names the file (or setting) and the reason.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SecurityError {
    #[error("security strategy '{value}': expected Enforce or Permissive")]
    Strategy { value: String },
    #[error("ROS_SECURITY_ENABLE='{value}': expected true or false")]
    Enable { value: String },
    #[error("DDS Security is enabled but no keystore is given (ROS_SECURITY_KEYSTORE, --security-keystore or security_keystore)")]
    NoKeystore,
    #[error("keystore {}: {why}", path.display())]
    Keystore { path: PathBuf, why: String },
    #[error("enclave '{enclave}': {why}")]
    EnclaveName { enclave: String, why: &'static str },
    #[error("enclave '{enclave}' is not in keystore {}: no directory {} (it has: {have})", keystore.display(), dir.display())]
    NoEnclave { enclave: String, keystore: PathBuf, dir: PathBuf, have: String },
    #[error("{}: {why}", file.display())]
    File { file: PathBuf, why: String },
    #[error("{}: not issued by the identity CA {}: {why}", file.display(), ca.display())]
    NotIssued { file: PathBuf, ca: PathBuf, why: String },
    #[error("{}: the certificate expired on {not_after} (the identity CA {} says so; make the enclave again)", file.display(), ca.display())]
    Expired { file: PathBuf, ca: PathBuf, not_after: String },
    #[error("{}: the certificate is not valid before {not_before}", file.display())]
    NotYetValid { file: PathBuf, not_before: String },
    #[error("{}: the private key does not belong to the certificate {}", file.display(), certificate.display())]
    KeyMismatch { file: PathBuf, certificate: PathBuf },
    #[error("{}: its signature does not verify against the permissions CA {}: {why}", file.display(), ca.display())]
    Signature { file: PathBuf, ca: PathBuf, why: String },
    #[error("{}: no grant for the certificate's subject '{subject}' (the grants are for: {grants})", file.display())]
    NoGrant { file: PathBuf, subject: String, grants: String },
    #[error("the {engine} engine does not do DDS Security ({}): use --engine cyclone, or ROS_SECURITY_STRATEGY=Permissive to run unsecured", unsupported_why(engine))]
    Unsupported { engine: &'static str },
}

impl SecuritySettings {
    /// The settings of the environment, as rcl reads them.
    pub fn from_env() -> Result<SecuritySettings, SecurityError> {
        let [enable_var, strategy_var, keystore_var, enclave_var] = ENV_VARS;
        let enable = match tutti_ros2::env::var(enable_var) {
            None => false,
            Some(v) => match v.trim() {
                "true" => true,
                "false" => false,
                _ => return Err(SecurityError::Enable { value: v.escape_debug().to_string() }),
            },
        };
        let strategy = match tutti_ros2::env::var(strategy_var) {
            None => Strategy::default(),
            Some(v) => v.parse()?,
        };
        Ok(SecuritySettings {
            enable,
            keystore: tutti_ros2::env::var(keystore_var).map(PathBuf::from),
            enclave: tutti_ros2::env::var(enclave_var),
            strategy,
        })
    }

    /// The environment that gives a process (an rclpy node, a gateway) enclave `enclave` of
    /// `keystore` under `Enforce`: what [`SecuritySettings::from_env`] reads back.
    pub fn enforce_env(keystore: &Path, enclave: &str) -> [(&'static str, String); 4] {
        let [enable, strategy, ks, name] = ENV_VARS;
        [
            (enable, "true".into()),
            (strategy, "Enforce".into()),
            (ks, keystore.display().to_string()),
            (name, enclave.into()),
        ]
    }

    /// The enclave engine `kind`'s participant runs in: None when security is off, or when
    /// the strategy is `Permissive` and the enclave cannot be used (a warning says why);
    /// with `Enforce`, an error naming the file.
    pub fn resolve(&self, kind: EngineKind) -> Result<Option<Enclave>, SecurityError> {
        if !self.enable {
            return Ok(None);
        }
        let found = if engine_does_security(kind) {
            self.enclave()
        } else {
            Err(SecurityError::Unsupported { engine: kind.name() })
        };
        match (found, self.strategy) {
            (Ok(e), _) => {
                tracing::info!("DDS Security: enclave {} ({})", e.name, e.dir.display());
                Ok(Some(e))
            }
            (Err(e), Strategy::Enforce) => Err(e),
            (Err(e), Strategy::Permissive) => {
                tracing::warn!("DDS Security: {e}; running WITHOUT security (ROS_SECURITY_STRATEGY=Permissive)");
                Ok(None)
            }
        }
    }

    /// The enclave's files, checked.
    pub fn enclave(&self) -> Result<Enclave, SecurityError> {
        let keystore = self.keystore.as_deref().ok_or(SecurityError::NoKeystore)?;
        let name = self.enclave.as_deref().unwrap_or(DEFAULT_ENCLAVE);
        let bad = |why| Err(SecurityError::EnclaveName { enclave: name.to_string(), why });
        if !name.starts_with('/') {
            return bad("an enclave is an absolute name, like /tutti/gateway");
        }
        if name.split('/').any(|p| p == "." || p == "..") || name.contains('\0') {
            return bad("'.' and '..' are not names of enclaves");
        }
        match std::fs::metadata(keystore) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => return Err(SecurityError::Keystore { path: keystore.into(), why: "not a directory".into() }),
            Err(e) => return Err(SecurityError::Keystore { path: keystore.into(), why: e.to_string() }),
        }
        let enclaves = keystore.join("enclaves");
        let dir = enclaves.join(name.trim_start_matches('/'));
        if !dir.is_dir() {
            return Err(SecurityError::NoEnclave {
                enclave: name.to_string(),
                keystore: keystore.into(),
                dir,
                have: enclaves_in(&enclaves),
            });
        }
        let file = |f: &str| {
            let p = dir.join(f);
            match std::fs::metadata(&p) {
                Ok(m) if m.is_file() => Ok(p),
                Ok(_) => Err(SecurityError::File { file: p, why: "not a file".into() }),
                Err(e) => Err(SecurityError::File { file: p, why: e.to_string() }),
            }
        };
        let crl = dir.join("crl.pem");
        let e = Enclave {
            name: name.to_string(),
            identity_ca: file("identity_ca.cert.pem")?,
            certificate: file("cert.pem")?,
            private_key: file("key.pem")?,
            permissions_ca: file("permissions_ca.cert.pem")?,
            governance: file("governance.p7s")?,
            permissions: file("permissions.p7s")?,
            crl: crl.is_file().then_some(crl),
            dir,
        };
        e.check()?;
        Ok(e)
    }
}

/// The enclaves under `dir` (directories holding a `cert.pem`), for the message that names
/// none of them.
fn enclaves_in(dir: &Path) -> String {
    fn walk(base: &Path, dir: &Path, out: &mut Vec<String>, depth: usize) {
        let Ok(entries) = std::fs::read_dir(dir) else { return };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() && depth < 8 {
                if p.join("cert.pem").is_file() {
                    let rel = p.strip_prefix(base).unwrap_or(&p);
                    out.push(format!("/{}", rel.display()));
                }
                walk(base, &p, out, depth + 1);
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out, 0);
    out.sort();
    if out.is_empty() {
        "no enclaves".into()
    } else {
        out.join(", ")
    }
}

fn read(file: &Path) -> Result<Vec<u8>, SecurityError> {
    std::fs::read(file).map_err(|e| SecurityError::File { file: file.into(), why: e.to_string() })
}

fn certificate(file: &Path) -> Result<X509, SecurityError> {
    X509::from_pem(&read(file)?)
        .map_err(|e| SecurityError::File { file: file.into(), why: format!("not a PEM certificate: {e}") })
}

fn private_key(file: &Path) -> Result<PKey<Private>, SecurityError> {
    PKey::private_key_from_pem(&read(file)?).map_err(|e| SecurityError::File {
        file: file.into(),
        why: format!("not a PEM private key (unencrypted): {e}"),
    })
}

/// A store that trusts `ca` alone.
fn trusting(ca: &X509, file: &Path) -> Result<X509Store, SecurityError> {
    let fail = |e: openssl::error::ErrorStack| SecurityError::File { file: file.into(), why: e.to_string() };
    let mut b = X509StoreBuilder::new().map_err(fail)?;
    b.add_cert(ca.clone()).map_err(fail)?;
    Ok(b.build())
}

/// A certificate's subject as `CN=…` pairs, comma-separated, as SROS2 writes it in a grant.
fn subject(cert: &X509) -> String {
    let parts: Vec<String> = cert
        .subject_name()
        .entries()
        .map(|e| {
            let key = e.object().nid().short_name().unwrap_or("?");
            let value = e.data().to_string().unwrap_or_default();
            format!("{key}={value}")
        })
        .collect();
    parts.join(",")
}

/// A subject name's `KEY=value` pairs, for comparing two spellings of one name.
fn pairs(name: &str) -> Vec<String> {
    let mut v: Vec<String> = name.split(',').map(|p| p.trim().to_string()).filter(|p| !p.is_empty()).collect();
    v.sort();
    v
}

/// The texts of each `<tag>…</tag>` in `xml`.
fn elements<'a>(xml: &'a str, tag: &str) -> Vec<&'a str> {
    let (open, close) = (format!("<{tag}>"), format!("</{tag}>"));
    xml.split(&open).skip(1).filter_map(|rest| rest.split(&close).next()).map(str::trim).collect()
}

impl Enclave {
    /// The checks DDS Security makes at the participant's creation, made here first so
    /// that an error names its file.
    fn check(&self) -> Result<(), SecurityError> {
        let identity_ca = certificate(&self.identity_ca)?;
        let cert = certificate(&self.certificate)?;
        let mut ctx = X509StoreContext::new()
            .map_err(|e| SecurityError::File { file: self.certificate.clone(), why: e.to_string() })?;
        let store = trusting(&identity_ca, &self.identity_ca)?;
        let chain =
            Stack::new().map_err(|e| SecurityError::File { file: self.certificate.clone(), why: e.to_string() })?;
        let verdict = ctx
            .init(&store, &cert, &chain, |c| Ok((c.verify_cert()?, c.error())))
            .map_err(|e| SecurityError::File { file: self.certificate.clone(), why: e.to_string() })?;
        match verdict {
            (true, _) => {}
            (false, r) if r.as_raw() == openssl_sys_codes::CERT_HAS_EXPIRED => {
                return Err(SecurityError::Expired {
                    file: self.certificate.clone(),
                    ca: self.identity_ca.clone(),
                    not_after: cert.not_after().to_string(),
                })
            }
            (false, r) if r.as_raw() == openssl_sys_codes::CERT_NOT_YET_VALID => {
                return Err(SecurityError::NotYetValid {
                    file: self.certificate.clone(),
                    not_before: cert.not_before().to_string(),
                })
            }
            (false, r) => {
                return Err(SecurityError::NotIssued {
                    file: self.certificate.clone(),
                    ca: self.identity_ca.clone(),
                    why: r.error_string().to_string(),
                })
            }
        }
        let key = private_key(&self.private_key)?;
        let public = cert
            .public_key()
            .map_err(|e| SecurityError::File { file: self.certificate.clone(), why: e.to_string() })?;
        if !public.public_eq(&key) {
            return Err(SecurityError::KeyMismatch {
                file: self.private_key.clone(),
                certificate: self.certificate.clone(),
            });
        }
        let permissions_ca = certificate(&self.permissions_ca)?;
        let store = trusting(&permissions_ca, &self.permissions_ca)?;
        self.signed(&self.governance, &store)?;
        let permissions = self.signed(&self.permissions, &store)?;
        let subject = subject(&cert);
        let grants = elements(&permissions, "subject_name");
        if !grants.iter().any(|g| pairs(g) == pairs(&subject)) {
            return Err(SecurityError::NoGrant {
                file: self.permissions.clone(),
                subject,
                grants: if grants.is_empty() { "none".into() } else { grants.join("; ") },
            });
        }
        Ok(())
    }

    /// The document an S/MIME file signs, once its signature verifies against `store`.
    fn signed(&self, file: &Path, store: &X509Store) -> Result<String, SecurityError> {
        let bad = |why: String| SecurityError::Signature { file: file.into(), ca: self.permissions_ca.clone(), why };
        let (p7, content) = Pkcs7::from_smime(&read(file)?)
            .map_err(|e| SecurityError::File { file: file.into(), why: format!("not an S/MIME document: {e}") })?;
        let certs = Stack::new().map_err(|e| bad(e.to_string()))?;
        let mut out = Vec::new();
        p7.verify(&certs, store, content.as_deref(), Some(&mut out), Pkcs7Flags::TEXT)
            .map_err(|e| bad(first_reason(&e)))?;
        Ok(String::from_utf8_lossy(&out).into_owned())
    }
}

/// OpenSSL's first reason in `e`, or all of it.
fn first_reason(e: &openssl::error::ErrorStack) -> String {
    e.errors().iter().find_map(|e| e.reason().map(str::to_string)).unwrap_or_else(|| e.to_string())
}

/// The X509 verification codes this module tells apart (`X509_V_ERR_*`).
mod openssl_sys_codes {
    pub const CERT_NOT_YET_VALID: i32 = 9;
    pub const CERT_HAS_EXPIRED: i32 = 10;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strategies_and_names() {
        assert_eq!("Enforce".parse::<Strategy>().unwrap(), Strategy::Enforce);
        assert_eq!("permissive".parse::<Strategy>().unwrap(), Strategy::Permissive);
        assert!("strict".parse::<Strategy>().unwrap_err().to_string().contains("'strict'"));
        assert_eq!(pairs("CN=/a/b, O=x"), pairs("O=x,CN=/a/b"));
        assert_eq!(elements("<g><s>CN=a</s></g><s> CN=b </s>", "s"), ["CN=a", "CN=b"]);
        let off = SecuritySettings::default();
        assert_eq!(off.resolve(EngineKind::Rustdds).unwrap(), None);
        let on = SecuritySettings { enable: true, strategy: Strategy::Enforce, ..SecuritySettings::default() };
        assert!(matches!(on.resolve(EngineKind::Cyclone), Err(SecurityError::NoKeystore)));
        assert!(matches!(on.resolve(EngineKind::Rustdds), Err(SecurityError::Unsupported { engine: "rustdds" })));
        let relative = SecuritySettings { enclave: Some("tutti".into()), keystore: Some("/".into()), ..on };
        assert!(matches!(relative.enclave(), Err(SecurityError::EnclaveName { .. })));
        let permissive = SecuritySettings { strategy: Strategy::Permissive, ..relative };
        assert_eq!(permissive.resolve(EngineKind::Cyclone).unwrap(), None);
    }
}
