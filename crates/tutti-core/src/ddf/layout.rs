//! The byte layout of a set: what the equivalent C struct would be on LP64 (each scalar
//! aligned to its size, a bus aligned to its strictest member, sizes rounded up to the
//! alignment), and the stable layout hash of a domain. The shared-memory segments, the
//! RTAPI buffers and the DDS types all use this one layout (see `docs/ddf.md`).

use serde::Serialize;

use super::model::{join_path, Domain, Flags, Item, ItemKind, Leaf, Role, Set};

/// The largest set accepted, in bytes.
pub const MAX_SET_BYTES: u64 = 256 << 20;

/// Layout of one set.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SetLayout {
    /// Size in bytes, a multiple of `align` (0 for an empty set).
    pub size: u32,
    /// Alignment in bytes (1 for an empty set).
    pub align: u32,
    /// Every scalar or array item in DDF order, with its path and offset.
    pub leaves: Vec<Leaf>,
}

impl SetLayout {
    pub fn leaf(&self, path: &str) -> Option<&Leaf> {
        self.leaves.iter().find(|l| l.path == path)
    }

    /// A buffer of `size` bytes holding every default (zero where none is given).
    pub fn default_bytes(&self) -> Vec<u8> {
        let mut buf = vec![0u8; self.size as usize];
        for leaf in &self.leaves {
            if let Some(value) = leaf.default {
                let n = leaf.ty.size() as usize;
                for chunk in buf[leaf.range()].chunks_exact_mut(n) {
                    leaf.ty.encode(value, chunk);
                }
            }
        }
        buf
    }
}

/// Computes the layout of `items`; `Err(bytes)` when it would exceed [`MAX_SET_BYTES`].
pub fn compute(items: &[Item]) -> Result<SetLayout, u64> {
    // Counted first: growing the vector leaf by leaf copied it several times.
    let mut leaves = Vec::with_capacity(leaf_count(items));
    let (size, align) = layout_struct(items, "", 0, &mut leaves)?;
    Ok(SetLayout { size: size as u32, align: align as u32, leaves })
}

/// Lays out `items` as a struct starting at absolute offset `base` (already aligned);
/// returns (size, align) of the struct.
fn layout_struct(items: &[Item], prefix: &str, base: u64, leaves: &mut Vec<Leaf>) -> Result<(u64, u64), u64> {
    let mut offset = 0u64;
    let mut align = 1u64;
    for item in items {
        let path = join_path(prefix, &item.name);
        match &item.kind {
            ItemKind::Scalar { ty, length, default } => {
                let a = u64::from(ty.size());
                offset = offset.next_multiple_of(a);
                let size = a * u64::from(*length);
                if base + offset + size > MAX_SET_BYTES {
                    return Err(base + offset + size);
                }
                leaves.push(Leaf {
                    path,
                    ty: *ty,
                    length: *length,
                    offset: (base + offset) as u32,
                    size: size as u32,
                    default: *default,
                });
                offset += size;
                align = align.max(a);
            }
            ItemKind::Bus { items } => {
                // A bus's alignment is known only after its members; compute it first.
                let inner_align = bus_align(items);
                offset = offset.next_multiple_of(inner_align);
                let (size, a) = layout_struct(items, &path, base + offset, leaves)?;
                offset += size;
                align = align.max(a);
            }
        }
    }
    let size = offset.next_multiple_of(align);
    if base + size > MAX_SET_BYTES {
        return Err(base + size);
    }
    Ok((size, align))
}

fn leaf_count(items: &[Item]) -> usize {
    items
        .iter()
        .map(|i| match &i.kind {
            ItemKind::Scalar { .. } => 1,
            ItemKind::Bus { items } => leaf_count(items),
        })
        .sum()
}

fn bus_align(items: &[Item]) -> u64 {
    items
        .iter()
        .map(|i| match &i.kind {
            ItemKind::Scalar { ty, .. } => u64::from(ty.size()),
            ItemKind::Bus { items } => bus_align(items),
        })
        .max()
        .unwrap_or(1)
}

/// 64-bit FNV-1a: small, dependency-free and fixed forever, which is what a hash stored in
/// shared-memory headers and compared across versions needs.
#[derive(Debug)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) -> &mut Self {
        for &x in b {
            self.0 ^= u64::from(x);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self
    }
    fn str(&mut self, s: &str) -> &mut Self {
        self.bytes(&(s.len() as u32).to_le_bytes()).bytes(s.as_bytes())
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.bytes(&v.to_le_bytes())
    }
}

/// The layout hash of a domain: name, flags, and for each set its size, alignment and every
/// leaf's path, type, length and offset. Defaults are not part of it (they do not change
/// where bytes are).
pub fn layout_hash(name: &str, flags: Flags, publish: &SetLayout, subscribe: &SetLayout) -> u64 {
    let mut h = Fnv::new();
    h.str("tutti-layout-v1").str(name);
    h.bytes(&[u8::from(flags.synchronous), u8::from(flags.multiple_publish_allowed), u8::from(flags.states)]);
    if flags.event {
        // Only when set, so that the hashes of every other domain stay as they were.
        h.str("event");
    }
    for (role, set) in [(Role::Publish, publish), (Role::Subscribe, subscribe)] {
        h.str(role.as_str()).u32(set.size).u32(set.align).u32(set.leaves.len() as u32);
        for leaf in &set.leaves {
            h.str(&leaf.path).str(leaf.ty.canonical()).u32(u32::from(leaf.length)).u32(leaf.offset);
        }
    }
    h.0
}

impl Domain {
    /// Recomputes the layout hash from the sets (used by tests and by segment checks).
    pub fn compute_layout_hash(&self) -> u64 {
        layout_hash(&self.name, self.flags, &self.publish.layout, &self.subscribe.layout)
    }
}

impl Set {
    pub fn size(&self) -> usize {
        self.layout.size as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ddf::model::ScalarType;
    use crate::ddf::Pos;

    fn scalar(name: &str, ty: ScalarType, length: u16) -> Item {
        Item { name: name.into(), kind: ItemKind::Scalar { ty, length, default: None }, pos: Pos::default() }
    }

    #[test]
    fn layout_matches_c_struct_rules() {
        // struct { bool a; double v[3]; struct { float p; uint32_t s; } m; int8_t t; }
        let items = vec![
            scalar("a", ScalarType::Boolean, 1),
            scalar("v", ScalarType::Float64, 3),
            Item {
                name: "m".into(),
                kind: ItemKind::Bus {
                    items: vec![scalar("p", ScalarType::Float32, 1), scalar("s", ScalarType::UInt32, 1)],
                },
                pos: Pos::default(),
            },
            scalar("t", ScalarType::Int8, 1),
        ];
        let l = compute(&items).unwrap();
        let offsets: Vec<_> = l.leaves.iter().map(|l| (l.path.as_str(), l.offset)).collect();
        assert_eq!(offsets, vec![("a", 0), ("v", 8), ("m/p", 32), ("m/s", 36), ("t", 40)]);
        assert_eq!((l.size, l.align), (48, 8));
    }

    #[test]
    fn bus_is_aligned_to_its_strictest_member() {
        let items = vec![
            scalar("a", ScalarType::Int8, 1),
            Item {
                name: "b".into(),
                kind: ItemKind::Bus {
                    items: vec![scalar("c", ScalarType::Int8, 1), scalar("d", ScalarType::Int64, 1)],
                },
                pos: Pos::default(),
            },
        ];
        let l = compute(&items).unwrap();
        assert_eq!(l.leaves[1].offset, 8);
        assert_eq!(l.leaves[2].offset, 16);
        assert_eq!(l.size, 24);
    }

    #[test]
    fn oversized_sets_are_refused() {
        let items: Vec<_> = (0..600).map(|i| scalar(&format!("x{i}"), ScalarType::Float64, 65535)).collect();
        assert!(compute(&items).is_err());
    }
}
