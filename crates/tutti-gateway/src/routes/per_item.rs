//! Per-item mode: one topic per item with stock `std_msgs` types (`Float64` for numeric
//! scalars, `Float64MultiArray` with an empty layout for arrays, `Bool` for booleans), so
//! stock ROS 2 tools work without building anything. No step travels with the values: in
//! this mode every set behaves as asynchronous on the DDS side.

use std::sync::Arc;

use tutti_core::ddf::{Leaf, ScalarType, SetLayout, Value};
use tutti_core::mapping::{self, ItemTopic, Qos};

use crate::cdr::stock;
use crate::engine::{Decode, Engine, Writer};
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

struct ItemWriter {
    leaf: Leaf,
    stock: Stock,
    writer: Box<dyn Writer>,
    last: Option<Vec<u8>>,
}

/// The writers of every item of one set.
pub struct ItemWriters {
    items: Vec<ItemWriter>,
    body: Vec<u8>,
}

impl std::fmt::Debug for ItemWriters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ItemWriters").field("items", &self.items.len()).finish()
    }
}

fn elements<'a>(leaf: &Leaf, bytes: &'a [u8]) -> impl ExactSizeIterator<Item = Value> + 'a {
    let ty = leaf.ty;
    bytes.chunks_exact(ty.size() as usize).map(move |c| ty.decode(c))
}

impl ItemWriters {
    /// Creates a writer for every topic of `topics` (leaves looked up in `layout`).
    pub fn create(
        dds: &dyn Engine,
        topics: &[ItemTopic],
        layout: &SetLayout,
        q: &Qos,
    ) -> Result<ItemWriters, GatewayError> {
        let mut items = Vec::with_capacity(topics.len());
        for t in topics {
            let Some(leaf) = layout.leaf(&t.path) else { continue };
            let writer = dds.writer(&t.topic, &t.dds_type, q)?;
            items.push(ItemWriter { leaf: leaf.clone(), stock: Stock::of(leaf), writer, last: None });
        }
        Ok(ItemWriters { items, body: Vec::new() })
    }

    /// Writes every item of `shm` that changed since the last call; returns (written, failed).
    pub fn send(&mut self, shm: &[u8]) -> (u64, u64) {
        let (mut sent, mut failed) = (0, 0);
        let body = &mut self.body;
        for w in &mut self.items {
            let Some(bytes) = shm.get(w.leaf.range()) else { continue };
            if w.last.as_deref() == Some(bytes) {
                continue;
            }
            match w.stock {
                Stock::Float64 => {
                    stock::encode_float64(elements(&w.leaf, bytes).next().map_or(0.0, Value::as_f64), body)
                }
                Stock::Bool => stock::encode_bool(bytes.first().is_some_and(|&b| b != 0), body),
                Stock::Array => stock::encode_float64_array(elements(&w.leaf, bytes).map(Value::as_f64), body),
            }
            if w.writer.write(body) {
                sent += 1;
                w.last = Some(bytes.to_vec());
            } else {
                failed += 1;
            }
        }
        (sent, failed)
    }

    /// Sends what batching writers hold.
    pub fn flush(&mut self) {
        for w in &mut self.items {
            w.writer.flush();
        }
    }

    pub fn reset(&mut self) {
        self.items.iter_mut().for_each(|w| w.last = None);
    }
}

/// `n` values of type `ty`, in shared-memory layout.
pub fn leaf_bytes(ty: ScalarType, values: impl Iterator<Item = Value>, n: usize) -> Vec<u8> {
    let size = ty.size() as usize;
    let mut out = vec![0u8; size * n];
    for (chunk, v) in out.chunks_exact_mut(size).zip(values) {
        ty.encode(v, chunk);
    }
    out
}

/// The bytes of array `leaf` from the data of a `Float64MultiArray`.
pub fn array_leaf(leaf: &Leaf, data: Vec<f64>) -> Result<Vec<u8>, String> {
    let n = usize::from(leaf.length);
    if data.len() != n {
        return Err(format!("{} has {n} elements, the sample {}", leaf.path, data.len()));
    }
    Ok(leaf_bytes(leaf.ty, data.into_iter().map(Value::Float), n))
}

/// The bytes of `leaf` from a serialized stock sample.
pub fn decode(leaf: &Leaf, raw: &[u8]) -> Result<Vec<u8>, String> {
    match Stock::of(leaf) {
        Stock::Float64 => Ok(leaf_bytes(leaf.ty, std::iter::once(Value::Float(stock::float64(raw)?)), 1)),
        Stock::Bool => Ok(leaf_bytes(leaf.ty, std::iter::once(Value::Bool(stock::boolean(raw)?)), 1)),
        Stock::Array => array_leaf(leaf, stock::float64_array(raw)?),
    }
}

/// How the samples of item `leaf`'s topic are decoded.
pub fn decoder(leaf: &Leaf) -> Decode {
    Decode::Item(Arc::new(leaf.clone()), Arc::from(leaf.path.as_str()))
}
