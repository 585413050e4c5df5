//! JSON answers with each key once per object: serde_json keeps the last of two equal keys
//! without a word, so the helpers that read the API's answers parse them through
//! [`parse_unique_keys`] and fail on a repeated key (two flattened structs sharing a field).

use serde::de::{DeserializeSeed, Error, MapAccess, SeqAccess, Visitor};
use serde_json::{Map, Value};

/// Parses JSON `text` as serde_json does, but fails on an object holding a key twice, naming the
/// key and where the object lies (a JSON pointer).
pub fn parse_unique_keys(text: &str) -> Result<Value, String> {
    let mut de = serde_json::Deserializer::from_str(text);
    let value = Unique {
        path: String::new(),
    }
    .deserialize(&mut de)
    .map_err(|e| e.to_string())?;
    de.end().map_err(|e| e.to_string())?;
    Ok(value)
}

/// The answer `text` of `what` (e.g. the request) as JSON: panics on a repeated key; text that is
/// not JSON at all (a CSV, an empty body) is `Null`, as `reqwest`'s `json()` was read before.
pub fn answer_json(text: &str, what: &str) -> Value {
    if serde_json::from_str::<serde::de::IgnoredAny>(text).is_err() {
        return Value::Null;
    }
    parse_unique_keys(text).unwrap_or_else(|e| panic!("{what}: malformed answer: {e}\n{text}"))
}

/// A value at `path` (JSON pointer of its place in the document).
struct Unique {
    path: String,
}

impl<'de> DeserializeSeed<'de> for Unique {
    type Value = Value;

    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Value, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Unique {
    type Value = Value;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E: Error>(self, v: bool) -> Result<Value, E> {
        Ok(Value::Bool(v))
    }
    fn visit_i64<E: Error>(self, v: i64) -> Result<Value, E> {
        Ok(Value::from(v))
    }
    fn visit_u64<E: Error>(self, v: u64) -> Result<Value, E> {
        Ok(Value::from(v))
    }
    fn visit_f64<E: Error>(self, v: f64) -> Result<Value, E> {
        Ok(Value::from(v))
    }
    fn visit_str<E: Error>(self, v: &str) -> Result<Value, E> {
        Ok(Value::String(v.to_string()))
    }
    fn visit_string<E: Error>(self, v: String) -> Result<Value, E> {
        Ok(Value::String(v))
    }
    fn visit_unit<E: Error>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut out = Vec::new();
        while let Some(v) = seq.next_element_seed(Unique {
            path: format!("{}/{}", self.path, out.len()),
        })? {
            out.push(v);
        }
        Ok(Value::Array(out))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        let mut out = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            let path = format!(
                "{}/{}",
                self.path,
                key.replace('~', "~0").replace('/', "~1")
            );
            let value = map.next_value_seed(Unique { path })?;
            if out.contains_key(&key) {
                let at = if self.path.is_empty() {
                    "/"
                } else {
                    &self.path
                };
                return Err(A::Error::custom(format!(
                    "key \"{key}\" appears twice in the object at {at}"
                )));
            }
            out.insert(key, value);
        }
        Ok(Value::Object(out))
    }
}
