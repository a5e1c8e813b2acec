//! Checks of a value where it stands. json5 gives an error its line and column only while
//! the value is being visited: a check made once `deserialize` has returned would lose them.
//! These helpers make the check inside the visit, for a field's `deserialize_with` or a
//! type's own `Deserialize`:
//!
//! * [`then`]: any value read as an `R` (with `R`'s own words for a value of the wrong type),
//!   then passed through a check;
//! * [`Parsed`]: a string parsed, a value of another type refused as "expected" what it says;
//! * [`Number`]: a number (json5 reads integers as i64, others as f64) in a range.

use std::fmt;
use std::marker::PhantomData;

use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
use serde::de::{self, DeserializeSeed, Deserializer, IntoDeserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;

/// Reads an `R` from the value `d` and passes it through `check`; an error of `check` gets
/// the value's position.
pub fn then<'de, D, R, T, E>(d: D, check: impl FnOnce(R) -> Result<T, E>) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    R: Deserialize<'de>,
    E: fmt::Display,
{
    d.deserialize_any(Then(check, PhantomData))
}

struct Then<R, F>(F, PhantomData<R>);

impl<'de, R, T, E, F> Visitor<'de> for Then<R, F>
where
    R: Deserialize<'de>,
    E: fmt::Display,
    F: FnOnce(R) -> Result<T, E>,
{
    type Value = T;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a value")
    }
    fn visit_bool<X: de::Error>(self, v: bool) -> Result<T, X> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(X::custom)
    }
    fn visit_i64<X: de::Error>(self, v: i64) -> Result<T, X> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(X::custom)
    }
    fn visit_u64<X: de::Error>(self, v: u64) -> Result<T, X> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(X::custom)
    }
    fn visit_f64<X: de::Error>(self, v: f64) -> Result<T, X> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(X::custom)
    }
    fn visit_str<X: de::Error>(self, v: &str) -> Result<T, X> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(X::custom)
    }
    fn visit_unit<X: de::Error>(self) -> Result<T, X> {
        (self.0)(R::deserialize(().into_deserializer())?).map_err(X::custom)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<T, A::Error> {
        (self.0)(R::deserialize(SeqAccessDeserializer::new(seq))?).map_err(de::Error::custom)
    }
    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<T, A::Error> {
        (self.0)(R::deserialize(MapAccessDeserializer::new(map))?).map_err(de::Error::custom)
    }
}

/// A string parsed where it stands: `d.deserialize_any(Parsed { .. })` for a field, or as the
/// seed of a list's elements. A value of another type is refused as "invalid type: …,
/// expected `expecting`".
#[derive(Debug, Clone, Copy)]
pub struct Parsed<T, P> {
    /// What the value should be, like `a duration like "10ms"`.
    pub expecting: &'static str,
    pub parse: fn(&str) -> Result<T, P>,
}

impl<T, P: fmt::Display> Visitor<'_> for Parsed<T, P> {
    type Value = T;
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.expecting)
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<T, E> {
        (self.parse)(v).map_err(E::custom)
    }
}

impl<'de, T, P: fmt::Display> DeserializeSeed<'de> for Parsed<T, P> {
    type Value = T;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<T, D::Error> {
        d.deserialize_any(self)
    }
}

/// A number checked where it stands: finite and `ok`, else refused as "V is not
/// `expecting`" (another type as "invalid type: …, expected `expecting`").
#[derive(Debug, Clone, Copy)]
pub struct Number {
    /// What the number should be, like `a depth of 1 or more`.
    pub expecting: &'static str,
    pub ok: fn(f64) -> bool,
}

impl Visitor<'_> for Number {
    type Value = f64;
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.expecting)
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<f64, E> {
        if v.is_finite() && (self.ok)(v) {
            Ok(v)
        } else {
            Err(E::custom(format!("{v} is not {}", self.expecting)))
        }
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<f64, E> {
        self.visit_f64(v as f64)
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<f64, E> {
        self.visit_f64(v as f64)
    }
}

#[cfg(test)]
mod tests {
    use serde::Deserializer;

    use super::*;
    use crate::{from_str, Error, Kind};

    const KIND: Kind = Kind { name: "test file", levels: 2 };

    #[derive(Debug, Deserialize)]
    #[allow(dead_code)]
    struct Keys {
        #[serde(default, deserialize_with = "de_even")]
        even: Option<u32>,
        #[serde(default, deserialize_with = "de_word")]
        word: Option<String>,
        #[serde(default, deserialize_with = "de_small")]
        small: Option<f64>,
    }

    fn de_even<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
        then(d, |v: u32| if v % 2 == 0 { Ok(Some(v)) } else { Err(format!("{v} is odd")) })
    }

    #[derive(Debug, thiserror::Error)]
    #[error("'{0}' is not a word")]
    struct NotAWord(String);

    fn word(s: &str) -> Result<String, NotAWord> {
        match s.chars().all(char::is_alphabetic) {
            true => Ok(s.to_string()),
            false => Err(NotAWord(s.to_string())),
        }
    }

    fn de_word<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
        d.deserialize_any(Parsed { expecting: "a word", parse: word }).map(Some)
    }

    fn de_small<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        d.deserialize_any(Number { expecting: "a number below 10", ok: |v| v < 10.0 }).map(Some)
    }

    fn error(text: &str) -> String {
        from_str::<Keys>(text, "t.json5", KIND).map(|_| ()).map_err(|e: Error| e.to_string()).unwrap_err()
    }

    #[test]
    fn a_check_refuses_a_value_at_its_line_and_column() {
        let k = from_str::<Keys>("{ even: 4, word: \"abc\", small: 3 }", "t.json5", KIND).unwrap();
        assert_eq!((k.even, k.word.as_deref(), k.small), (Some(4), Some("abc"), Some(3.0)));
        assert_eq!(error("{\n  even: 3 }"), "t.json5:2:9: 3 is odd");
        assert_eq!(error("{ even: [4] }"), "t.json5:1:9: invalid type: sequence, expected u32");
        assert_eq!(error("{\n word: \"a b\" }"), "t.json5:2:8: 'a b' is not a word");
        assert_eq!(error("{ word: 1 }"), "t.json5:1:9: invalid type: integer `1`, expected a word");
        assert_eq!(error("{ small: 12 }"), "t.json5:1:10: 12 is not a number below 10");
        assert_eq!(error("{ small: Infinity }"), "t.json5:1:10: inf is not a number below 10");
        assert_eq!(error("{ small: \"1\" }"), "t.json5:1:10: invalid type: string \"1\", expected a number below 10");
    }
}
