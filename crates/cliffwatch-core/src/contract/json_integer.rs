//! Integers of JSON bodies as JSON Schema counts them: `4` and `4.0` are both the integer 4 (an
//! OpenAPI `integer` admits any number with a zero fraction), while serde's own integers refuse
//! `4.0`. Used with `#[serde(deserialize_with = …)]` on the integer fields of request bodies.

use serde::{Deserialize, Deserializer};

/// A JSON number with a zero fraction inside `T`'s range, as `T`.
fn integral<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
where
    D: Deserializer<'de>,
    T: TryFrom<i64>,
{
    let Some(n) = Option::<serde_json::Number>::deserialize(d)? else {
        return Ok(None);
    };
    let whole = match (n.as_i64(), n.as_f64()) {
        (Some(i), _) => Some(i),
        (None, Some(f)) if f.fract() == 0.0 && f.abs() < 9.0e18 => Some(f as i64),
        _ => None,
    };
    whole
        .and_then(|i| T::try_from(i).ok())
        .map(Some)
        .ok_or_else(|| serde::de::Error::custom(format!("{n}: not an integer in range")))
}

/// An optional integer (`null` or absent: `None`); `4.0` reads as 4.
pub fn optional_i64<'de, D: Deserializer<'de>>(d: D) -> Result<Option<i64>, D::Error> {
    integral(d)
}

/// An optional non-negative 32-bit integer; `4.0` reads as 4.
pub fn optional_u32<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    integral(d)
}

#[cfg(test)]
mod tests {
    use serde::Deserialize;

    #[derive(Deserialize)]
    struct Body {
        #[serde(default, deserialize_with = "super::optional_i64")]
        n: Option<i64>,
        #[serde(default, deserialize_with = "super::optional_u32")]
        k: Option<u32>,
    }

    fn read(s: &str) -> Result<(Option<i64>, Option<u32>), String> {
        serde_json::from_str::<Body>(s)
            .map(|b| (b.n, b.k))
            .map_err(|e| e.to_string())
    }

    #[test]
    fn integral_floats_are_integers_and_fractions_are_not() {
        assert_eq!(read(r#"{"n": 4, "k": 2}"#).unwrap(), (Some(4), Some(2)));
        assert_eq!(
            read(r#"{"n": -4472.0, "k": 3.0}"#).unwrap(),
            (Some(-4472), Some(3))
        );
        assert_eq!(read(r#"{"n": null}"#).unwrap(), (None, None));
        assert_eq!(read("{}").unwrap(), (None, None));
        assert!(read(r#"{"n": 4.5}"#).is_err());
        assert!(read(r#"{"k": -1}"#).is_err());
        assert!(read(r#"{"k": 5e9}"#).is_err());
        assert!(read(r#"{"n": "4"}"#).is_err());
    }
}
