//! Per-item mode: one topic per item with stock `std_msgs` types (`Float64` for numeric
//! scalars, `Float64MultiArray` with an empty layout for arrays, `Bool` for booleans), so
//! stock ROS 2 tools work without building anything. No step travels with the values: in
//! this mode every set behaves as asynchronous on the DDS side.

use std::sync::Arc;

use tutti_core::ddf::{Leaf, SetLayout, Value};
use tutti_core::mapping::{ItemTopic, Qos};

use crate::cdr::stock::{self, Stock};
use crate::engine::{Decode, Engine, TopicType, Writer};
use crate::GatewayError;

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
            let writer = dds.writer(&t.topic, &TopicType::stock(&t.dds_type), q)?;
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

/// How the samples of item `leaf`'s topic are decoded.
pub fn decoder(leaf: &Leaf) -> Decode {
    Decode::Item(Arc::new(leaf.clone()), Arc::from(leaf.path.as_str()))
}
