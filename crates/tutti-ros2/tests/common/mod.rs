//! What the tests of tutti-ros2 share: deterministic sample values of any message.

use tutti_ros2::{BaseType, Message, Primitive, Shape, Struct, Value};

/// A value of `msg` with every field set, different for each `seed`: negative numbers, the
/// extremes of the wide integers, sequences of 0 to 3 elements (fewer deeper down, never above
/// their bound), strings (non-ASCII where unbounded), nested messages.
pub fn sample(msg: Message<'_>, seed: u64) -> Value {
    sample_at(msg, seed, 0)
}

fn sample_at(msg: Message<'_>, seed: u64, depth: u64) -> Value {
    let mut s = Struct::new();
    for (i, f) in msg.spec().fields.iter().enumerate() {
        let k = seed.wrapping_mul(31).wrapping_add(i as u64 * 7 + depth);
        let one = |k: u64| -> Value {
            match &f.ty.base {
                BaseType::Nested(_) => {
                    msg.nested(&f.name).map_or(Value::Struct(Struct::new()), |m| sample_at(m, k, depth + 1))
                }
                base => primitive(base, k),
            }
        };
        let count = |bound: u64| (k % if depth > 1 { 2 } else { 4 }).min(bound);
        let v = match f.ty.shape {
            Shape::Single => one(k),
            Shape::Array(n) => Value::Array((0..n).map(|j| one(k + j)).collect()),
            Shape::Bounded(b) => Value::Array((0..count(b)).map(|j| one(k + j)).collect()),
            Shape::Unbounded => Value::Array((0..count(u64::MAX)).map(|j| one(k + j)).collect()),
        };
        s.set(&f.name, v);
    }
    Value::Struct(s)
}

fn primitive(base: &BaseType, k: u64) -> Value {
    let small = (k % 100) as i64;
    match base {
        BaseType::Primitive(p) => match p {
            Primitive::Bool => Value::Bool(k % 2 == 1),
            Primitive::Byte | Primitive::Char | Primitive::UInt8 => Value::UInt((k * 37 + 200) % 256),
            Primitive::Int8 => Value::Int(-small - 1),
            Primitive::UInt16 => Value::UInt(60_000 - k % 1000),
            Primitive::Int16 => Value::Int(-30_000 + small),
            Primitive::UInt32 => Value::UInt(4_000_000_000 - k % 1000),
            Primitive::Int32 => Value::Int(-2_000_000_000 + small),
            Primitive::UInt64 => Value::UInt(u64::MAX - k % 1000),
            Primitive::Int64 => Value::Int(i64::MIN + 1 + small),
            // Exact in an f32.
            Primitive::Float32 => Value::Float(-(small as f64) * 0.25 - 0.5),
            Primitive::Float64 => Value::Float(small as f64 * -1.0625 + 0.1),
        },
        BaseType::String { bound: Some(b) } => {
            let mut s = format!("s{k}");
            s.truncate(usize::try_from(*b).unwrap_or(usize::MAX));
            Value::String(s)
        }
        BaseType::String { bound: None } => {
            Value::String(if k % 3 == 0 { String::new() } else { format!("s{k} é∑") })
        }
        BaseType::WString { .. } => Value::String(format!("w{k}")),
        BaseType::Nested(_) => Value::Struct(Struct::new()),
    }
}
