//! Where a domain's segment lives: its namespace (checked) and its shared-memory name.

use crate::shm::{os, ShmError};

/// The namespace from `TUTTI_NAMESPACE` (default `tutti`).
pub fn namespace_from_env() -> String {
    std::env::var("TUTTI_NAMESPACE").ok().filter(|s| !s.is_empty()).unwrap_or_else(|| "tutti".to_string())
}

/// Checks a namespace: 1–64 characters of `[A-Za-z0-9_.-]`.
pub fn check_namespace(ns: &str) -> Result<(), ShmError> {
    let ok = !ns.is_empty()
        && ns.len() <= 64
        && ns.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '-'));
    if ok {
        Ok(())
    } else {
        Err(ShmError::InvalidNamespace { namespace: ns.to_string() })
    }
}

/// The shared-memory object name of a domain: `tutti.NAMESPACE.DOMAIN`.
pub fn segment_name(ns: &str, domain: &str) -> String {
    format!("tutti.{ns}.{domain}")
}

/// Where the segment of `domain` in namespace `ns` lives.
pub fn segment_path(ns: &str, domain: &str) -> std::path::PathBuf {
    std::path::Path::new(os::SHM_DIR).join(segment_name(ns, domain))
}

#[cfg(test)]
mod tests {
    use super::check_namespace;

    #[test]
    fn namespaces_are_checked() {
        assert!(check_namespace("tutti").is_ok());
        assert!(check_namespace("t-1.x_y").is_ok());
        assert!(check_namespace("").is_err());
        assert!(check_namespace("a/b").is_err());
        assert!(check_namespace(&"x".repeat(65)).is_err());
    }
}
