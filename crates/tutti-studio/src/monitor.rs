//! The live monitor: one Server-Sent Events stream per page, an event every 100 ms with the
//! status of every domain of the namespace (the core's `list_domains`, as `tutti status`
//! reads it), the values of the items the page plots, and the runs the studio started.
//!
//! Item values are read as a passive observer (the core's [`Observer`], as `tutti record`
//! does): no connection, so the studio never counts as a participant and never paces a
//! step. A segment that is corrupted or refused is reported in the event, never fatal.

use std::collections::HashMap;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::State;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures::Stream;
use serde::Deserialize;
use serde_json::{json, Value};
use tutti_core::ddf::Role;
use tutti_core::shm::list_domains;
use tutti_core::shm::observer::{Look, Observer};
use tutti_core::shm::segment::{check_namespace, Segment};

use crate::error::ApiError;
use crate::request::ApiQuery;
use crate::AppState;

/// Time between two events (10 Hz).
pub const PERIOD: Duration = Duration::from_millis(100);
/// Every how many events the catalog of plottable items is sent again.
const CATALOG_EVERY: u64 = 10;

#[derive(Debug, Deserialize)]
pub struct MonitorQuery {
    /// Namespace to follow (default: the studio's).
    #[serde(default)]
    pub namespace: Option<String>,
    /// Items to plot: `DOMAIN#ROLE#PATH`, comma-separated (names hold neither `#` nor `,`).
    #[serde(default)]
    pub items: Option<String>,
}

/// One item the page plots.
#[derive(Debug, Clone)]
struct Wanted {
    key: String,
    domain: String,
    role: Role,
    path: String,
}

fn parse_items(text: &str) -> Result<Vec<Wanted>, ApiError> {
    let mut out = Vec::new();
    for key in text.split(',').filter(|s| !s.is_empty()) {
        let mut parts = key.splitn(3, '#');
        let (Some(domain), Some(role), Some(path)) = (parts.next(), parts.next(), parts.next()) else {
            return Err(ApiError::bad_request(format!("item '{key}': expected DOMAIN#ROLE#PATH")));
        };
        let role = match role.to_ascii_uppercase().as_str() {
            "PUBLISH" => Role::Publish,
            "SUBSCRIBE" => Role::Subscribe,
            _ => return Err(ApiError::bad_request(format!("item '{key}': the role is PUBLISH or SUBSCRIBE"))),
        };
        out.push(Wanted { key: key.to_string(), domain: domain.to_string(), role, path: path.to_string() });
    }
    Ok(out)
}

/// What one page's stream keeps between events.
struct Follow {
    state: Arc<AppState>,
    namespace: String,
    wanted: Vec<Wanted>,
    observers: HashMap<String, Observer>,
    n: u64,
    buf: Vec<u8>,
}

/// Why a watched item cannot be read now.
#[derive(Debug, thiserror::Error)]
enum ReadError {
    #[error("no item {path} in the {role} set")]
    NoItem { path: String, role: Role },
    #[error(transparent)]
    Shm(#[from] tutti_core::shm::ShmError),
}

/// The elements of leaf `path` of set `role`, as numbers, or why it cannot be read now.
fn read_leaf(seg: &Segment, role: Role, path: &str, buf: &mut Vec<u8>) -> Result<Vec<f64>, ReadError> {
    let leaf = seg.info.set(role).leaf(path).ok_or_else(|| ReadError::NoItem { path: path.to_string(), role })?;
    buf.resize(leaf.size as usize, 0);
    seg.read_set_at(role, leaf.offset as usize, buf)?;
    let n = leaf.ty.size() as usize;
    Ok(buf.chunks_exact(n).map(|c| leaf.ty.decode(c).as_f64()).collect())
}

impl Follow {
    fn sample(&mut self) -> Value {
        self.n += 1;
        let t = tutti_core::shm::os::now_ns() as f64 / 1e9;
        let (domains, error) = match list_domains(&self.namespace) {
            Ok(list) => (
                list.into_iter()
                    .map(|d| match d {
                        Ok(s) => serde_json::to_value(s).unwrap_or(Value::Null),
                        Err(e) => json!({ "error": e.to_string() }),
                    })
                    .collect::<Vec<_>>(),
                None,
            ),
            Err(e) => (Vec::new(), Some(e.to_string())),
        };
        let mut values = serde_json::Map::new();
        let mut catalog = Vec::new();
        let send_catalog = self.n % CATALOG_EVERY == 1;
        let live: Vec<String> =
            domains.iter().filter_map(|d| d.get("domain").and_then(Value::as_str).map(str::to_string)).collect();
        let mut names: Vec<String> = self.wanted.iter().map(|w| w.domain.clone()).collect();
        if send_catalog {
            names.extend(live.iter().cloned());
        }
        names.sort();
        names.dedup();
        self.observers.retain(|d, _| names.contains(d));
        for name in &names {
            let obs = self.observers.entry(name.clone()).or_insert_with(|| Observer::new(name.clone()));
            let refused = match obs.look(&self.namespace) {
                Look::Refused(e) => Some(e.to_string()),
                _ => None,
            };
            let Some(seg) = obs.segment() else {
                for w in self.wanted.iter().filter(|w| &w.domain == name) {
                    let why = refused.clone().unwrap_or_else(|| "no running framework".into());
                    values.insert(w.key.clone(), json!({ "error": why }));
                }
                continue;
            };
            let step = seg.step();
            for w in self.wanted.iter().filter(|w| &w.domain == name) {
                let v = match read_leaf(seg, w.role, &w.path, &mut self.buf) {
                    Ok(v) => json!({ "step": step, "v": v }),
                    Err(e) => json!({ "error": e.to_string() }),
                };
                values.insert(w.key.clone(), v);
            }
            if send_catalog {
                for (role, leaf) in seg.info.leaves() {
                    catalog.push(json!({ "domain": name, "role": role, "path": leaf.path, "length": leaf.length }));
                }
            }
        }
        let mut event = json!({
            "t": t,
            "namespace": self.namespace,
            "domains": domains,
            "error": error,
            "values": values,
            "runs": crate::run::snapshot(&self.state),
        });
        if send_catalog {
            event["catalog"] = Value::Array(catalog);
        }
        event
    }
}

/// `GET /api/monitor?namespace=NS&items=...`: the event stream.
pub async fn stream(
    State(state): State<Arc<AppState>>,
    ApiQuery(q): ApiQuery<MonitorQuery>,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let namespace = q.namespace.filter(|n| !n.is_empty()).unwrap_or_else(|| state.namespace.clone());
    check_namespace(&namespace).map_err(|e| ApiError::bad_request(e.to_string()))?;
    let wanted = parse_items(q.items.as_deref().unwrap_or(""))?;
    let follow = Follow { state, namespace, wanted, observers: HashMap::new(), n: 0, buf: Vec::new() };
    let mut interval = tokio::time::interval(PERIOD);
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let stream = futures::stream::unfold((follow, interval), |(mut follow, mut interval)| async move {
        interval.tick().await;
        // Segment reads are short copies; the stream yields between events.
        let data = follow.sample().to_string();
        Some((Ok(Event::default().data(data)), (follow, interval)))
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn items_are_parsed_and_bad_ones_refused() {
        let w = parse_items("uav1#PUBLISH#X,uav1#subscribe#gps/fix/lat").unwrap();
        assert_eq!(w.len(), 2);
        assert_eq!((w[1].role, w[1].path.as_str()), (Role::Subscribe, "gps/fix/lat"));
        assert!(parse_items("uav1#X").is_err());
        assert!(parse_items("uav1#BOTH#X").is_err());
        assert!(parse_items("").unwrap().is_empty());
    }
}
