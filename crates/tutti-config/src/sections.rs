//! A file whose keys lie flat, side by side, but belong to several owners: each owner parses
//! its own keys into a struct of its own (a [`Section`], an ordinary serde struct that refuses
//! unknown keys), and the file is the sum of its sections. [`take`] hands one key's value to
//! its section's own deserializer, still on the file's reader, so errors keep their positions;
//! [`KeySeed`] refuses a key no section owns where it stands in the file, naming the keys there
//! are, as serde does for a struct.

use std::fmt;

use serde::de::value::MapAccessDeserializer;
use serde::de::{DeserializeSeed, IntoDeserializer, MapAccess, Visitor};
use serde::{Deserialize, Deserializer};

/// The keys one owner parses, with the layering of a command line over a file.
pub trait Section: Default + for<'de> Deserialize<'de> {
    /// Its keys (aliases included), as the file spells them.
    const KEYS: &'static [&'static str];
    /// `self`'s keys, and `lower`'s where `self` has none (flags over the file).
    fn over(self, lower: Self) -> Self;
}

/// Reads the value of `key` (read already by `map`) into a `T` that holds that key alone.
pub fn take<'de, A: MapAccess<'de>, T: Deserialize<'de>>(key: &str, map: &mut A) -> Result<T, A::Error> {
    T::deserialize(MapAccessDeserializer::new(OneKey { key: Some(key.to_string()), map }))
}

/// Adds `key` (read by `map`) to section `s`; false when the key is not the section's.
pub fn take_into<'de, A: MapAccess<'de>, S: Section>(s: &mut S, key: &str, map: &mut A) -> Result<bool, A::Error> {
    if !S::KEYS.contains(&key) {
        return Ok(false);
    }
    let one: S = take(key, map)?;
    *s = one.over(std::mem::take(s));
    Ok(true)
}

/// A map of one entry: the key already read, then the value, read by the underlying map.
struct OneKey<'a, A> {
    key: Option<String>,
    map: &'a mut A,
}

impl<'de, A: MapAccess<'de>> MapAccess<'de> for OneKey<'_, A> {
    type Error = A::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(&mut self, seed: K) -> Result<Option<K::Value>, A::Error> {
        match self.key.take() {
            Some(k) => seed.deserialize(k.into_deserializer()).map(Some),
            None => Ok(None),
        }
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, A::Error> {
        self.map.next_value_seed(seed)
    }
}

/// A key of a file of sections: one of `keys` (every section's), or an error where it stands
/// (serde's "unknown field" message, listing them); a key seen before is refused too.
#[derive(Debug)]
pub struct KeySeed<'a> {
    pub keys: &'static [&'static str],
    /// (alias, key): an alias and its key count as one (the second of them is a duplicate).
    pub aliases: &'static [(&'static str, &'static str)],
    pub seen: &'a mut Vec<&'static str>,
}

impl<'de> DeserializeSeed<'de> for KeySeed<'_> {
    type Value = &'static str;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<&'static str, D::Error> {
        d.deserialize_identifier(self)
    }
}

impl Visitor<'_> for KeySeed<'_> {
    type Value = &'static str;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a key of the file")
    }

    fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<&'static str, E> {
        let Some(key) = self.keys.iter().copied().find(|k| *k == v) else {
            return Err(E::unknown_field(v, self.keys));
        };
        let canonical = self.aliases.iter().find(|(alias, _)| *alias == key).map_or(key, |(_, k)| *k);
        if self.seen.contains(&canonical) {
            return Err(E::duplicate_field(canonical));
        }
        self.seen.push(canonical);
        Ok(key)
    }
}

/// `Err` for a key [`KeySeed`] took but no section did (a list of keys that is not the
/// sections' own).
pub fn unowned<E: serde::de::Error>(key: &str) -> E {
    E::custom(format!("the key `{key}` has no section to read it"))
}
