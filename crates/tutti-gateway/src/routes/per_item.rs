//! Per-item mode: one topic per item with stock `std_msgs` types (`Float64` for numeric
//! scalars, `Float64MultiArray` with an empty layout for arrays, `Bool` for booleans), so
//! stock ROS 2 tools work without building anything. No step travels with the values: in
//! this mode every set behaves as asynchronous on the DDS side.

use std::sync::Arc;

use ros2_client::dds::{Publisher, Subscription};
use serde::de::DeserializeOwned;
use tutti_core::ddf::{Leaf, ScalarType, SetLayout, Value};
use tutti_core::mapping::{self, ItemTopic, Qos};

use super::from_dds::{self, Destination};
use super::Payload;
use crate::cdr::{Bool, Float64, Float64MultiArray};
use crate::node::{Dds, PREFIX_LEN};
use crate::stats::Stats;
use crate::GatewayError;

/// The stock type of a leaf.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stock {
    Float64,
    Bool,
    Array,
}

impl Stock {
    pub fn of(leaf: &Leaf) -> Stock {
        match mapping::per_item_type(leaf.ty, leaf.length) {
            "std_msgs::msg::dds_::Bool_" => Stock::Bool,
            "std_msgs::msg::dds_::Float64_" => Stock::Float64,
            _ => Stock::Array,
        }
    }
}

enum ItemPub {
    Float64(Publisher<Float64>),
    Bool(Publisher<Bool>),
    Array(Publisher<Float64MultiArray>),
}

struct ItemWriter {
    leaf: Leaf,
    publisher: ItemPub,
    last: Option<Vec<u8>>,
}

/// The writers of every item of one set.
pub struct ItemWriters {
    items: Vec<ItemWriter>,
}

impl std::fmt::Debug for ItemWriters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ItemWriters").field("items", &self.items.len()).finish()
    }
}

fn elements<'a>(leaf: &Leaf, bytes: &'a [u8]) -> impl Iterator<Item = Value> + 'a {
    let ty = leaf.ty;
    bytes.chunks_exact(ty.size() as usize).map(move |c| ty.decode(c))
}

impl ItemWriters {
    /// Creates a writer for every topic of `topics` (leaves looked up in `layout`).
    pub fn create(
        dds: &mut Dds,
        topics: &[ItemTopic],
        layout: &SetLayout,
        q: &Qos,
    ) -> Result<ItemWriters, GatewayError> {
        let mut items = Vec::with_capacity(topics.len());
        for t in topics {
            let Some(leaf) = layout.leaf(&t.path) else { continue };
            let publisher = match Stock::of(leaf) {
                Stock::Float64 => ItemPub::Float64(dds.publisher(&t.topic, &t.dds_type, q)?),
                Stock::Bool => ItemPub::Bool(dds.publisher(&t.topic, &t.dds_type, q)?),
                Stock::Array => ItemPub::Array(dds.publisher(&t.topic, &t.dds_type, q)?),
            };
            items.push(ItemWriter { leaf: leaf.clone(), publisher, last: None });
        }
        Ok(ItemWriters { items })
    }

    /// Writes every item of `shm` that changed since the last call; returns (written, failed).
    pub fn send(&mut self, shm: &[u8]) -> (u64, u64) {
        let (mut sent, mut failed) = (0, 0);
        for w in &mut self.items {
            let Some(bytes) = shm.get(w.leaf.range()) else { continue };
            if w.last.as_deref() == Some(bytes) {
                continue;
            }
            let ok = match &w.publisher {
                ItemPub::Float64(p) => {
                    p.publish(Float64 { data: elements(&w.leaf, bytes).next().map_or(0.0, Value::as_f64) }).is_ok()
                }
                ItemPub::Bool(p) => p.publish(Bool { data: bytes.first().is_some_and(|&b| b != 0) }).is_ok(),
                ItemPub::Array(p) => p
                    .publish(Float64MultiArray {
                        layout: Default::default(),
                        data: elements(&w.leaf, bytes).map(Value::as_f64).collect(),
                    })
                    .is_ok(),
            };
            if ok {
                sent += 1;
                w.last = Some(bytes.to_vec());
            } else {
                failed += 1;
            }
        }
        (sent, failed)
    }

    pub fn reset(&mut self) {
        self.items.iter_mut().for_each(|w| w.last = None);
    }
}

/// A stock message turned into the bytes of its leaf.
trait IntoLeaf {
    fn into_leaf(self, leaf: &Leaf) -> Result<Vec<u8>, String>;
}

fn encode(ty: ScalarType, values: impl Iterator<Item = Value>, n: usize) -> Vec<u8> {
    let size = ty.size() as usize;
    let mut out = vec![0u8; size * n];
    for (chunk, v) in out.chunks_exact_mut(size).zip(values) {
        ty.encode(v, chunk);
    }
    out
}

impl IntoLeaf for Float64 {
    fn into_leaf(self, leaf: &Leaf) -> Result<Vec<u8>, String> {
        Ok(encode(leaf.ty, std::iter::once(Value::Float(self.data)), 1))
    }
}

impl IntoLeaf for Bool {
    fn into_leaf(self, leaf: &Leaf) -> Result<Vec<u8>, String> {
        Ok(encode(leaf.ty, std::iter::once(Value::Bool(self.data)), 1))
    }
}

impl IntoLeaf for Float64MultiArray {
    fn into_leaf(self, leaf: &Leaf) -> Result<Vec<u8>, String> {
        let n = usize::from(leaf.length);
        if self.data.len() != n {
            return Err(format!("{} has {n} elements, the sample {}", leaf.path, self.data.len()));
        }
        Ok(encode(leaf.ty, self.data.into_iter().map(Value::Float), n))
    }
}

/// Creates the reader of one item topic and the task that forwards its samples as route
/// `to.0`.
pub fn spawn_reader(
    dds: &mut Dds,
    topic: &ItemTopic,
    leaf: &Leaf,
    q: &Qos,
    to: Destination,
    stats: Arc<Stats>,
    rt: &tokio::runtime::Handle,
) -> Result<(), GatewayError> {
    let own = dds.own_prefix;
    match Stock::of(leaf) {
        Stock::Float64 => {
            let s: Subscription<Float64> = dds.subscription(&topic.topic, &topic.dds_type, q)?;
            rt.spawn(forward(s, leaf.clone(), to, stats, own));
        }
        Stock::Bool => {
            let s: Subscription<Bool> = dds.subscription(&topic.topic, &topic.dds_type, q)?;
            rt.spawn(forward(s, leaf.clone(), to, stats, own));
        }
        Stock::Array => {
            let s: Subscription<Float64MultiArray> = dds.subscription(&topic.topic, &topic.dds_type, q)?;
            rt.spawn(forward(s, leaf.clone(), to, stats, own));
        }
    }
    Ok(())
}

async fn forward<M>(sub: Subscription<M>, leaf: Leaf, to: Destination, stats: Arc<Stats>, own: [u8; PREFIX_LEN])
where
    M: DeserializeOwned + IntoLeaf + 'static,
{
    let path: Arc<str> = Arc::from(leaf.path.as_str());
    let to_payload = |m: M| m.into_leaf(&leaf).map(|bytes| Payload::Item { path: path.clone(), bytes });
    from_dds::forward(sub.async_stream(), to_payload, to, stats, own).await;
}
