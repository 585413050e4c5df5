//! Enums known by their contract names (`"watch"`, `"alert.raised"`, `"orthogonal"`): one table
//! per enum gives its name in the API, the webhooks and the database, and the way back, so store
//! rows hold the domain's enums rather than strings.

/// A name that is not one of an enum's contract names: bad input, or a stored row the code does
/// not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} '{}' (one of {expected})", super::truncate_for_message(.value))]
pub struct UnknownName {
    /// What was being named, e.g. `alert level`.
    pub what: &'static str,
    /// The name given.
    pub value: String,
    /// The names known, comma-separated.
    pub expected: &'static str,
}

/// Implements, for a field-less enum, `as_str` (its contract name), `Display`, `FromStr` and
/// `TryFrom<String>` (for sqlx's `try_from` row fields), all from one table of
/// `Variant => "name"`.
#[macro_export]
macro_rules! contract_names {
    ($ty:ident, $what:literal { $first:ident => $first_name:literal $(, $variant:ident => $name:literal)* $(,)? }) => {
        impl $ty {
            /// Every value, in declaration order.
            pub const ALL: &'static [$ty] = &[$ty::$first $(, $ty::$variant)*];

            /// The contract name.
            pub fn as_str(self) -> &'static str {
                match self {
                    $ty::$first => $first_name,
                    $($ty::$variant => $name,)*
                }
            }
        }

        impl ::std::fmt::Display for $ty {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl ::std::str::FromStr for $ty {
            type Err = $crate::contract::names::UnknownName;

            fn from_str(s: &str) -> ::std::result::Result<Self, Self::Err> {
                match s {
                    $first_name => Ok($ty::$first),
                    $($name => Ok($ty::$variant),)*
                    _ => Err($crate::contract::names::UnknownName {
                        what: $what,
                        value: s.to_string(),
                        expected: concat!($first_name $(, ", ", $name)*),
                    }),
                }
            }
        }

        impl ::std::convert::TryFrom<String> for $ty {
            type Error = $crate::contract::names::UnknownName;

            fn try_from(s: String) -> ::std::result::Result<Self, Self::Error> {
                s.parse()
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use crate::analysis::alerts::{Metric, Source};
    use crate::analysis::{AlertEventType, AlertLevel, AlertStatus, PointRole};
    use crate::photogrammetry::Model;

    /// Every name parses back to its value and equals the serde name the API and webhooks carry.
    fn round_trip<T>(all: &[T])
    where
        T: Copy
            + std::fmt::Debug
            + PartialEq
            + std::str::FromStr
            + serde::Serialize
            + std::fmt::Display,
    {
        for &v in all {
            let name = v.to_string();
            assert_eq!(name.parse::<T>().ok(), Some(v));
            assert_eq!(
                serde_json::to_value(v).unwrap(),
                serde_json::Value::String(name)
            );
        }
        assert!("no such name".parse::<T>().is_err());
    }

    #[test]
    fn names_round_trip_and_match_serde() {
        round_trip(AlertLevel::ALL);
        round_trip(AlertStatus::ALL);
        round_trip(AlertEventType::ALL);
        round_trip(PointRole::ALL);
        round_trip(Model::ALL);
        round_trip(Metric::ALL);
        round_trip(Source::ALL);
    }

    #[test]
    fn an_unknown_name_says_what_is_known() {
        let e = "loud".parse::<AlertLevel>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown alert level 'loud' (one of watch, warning, alarm)"
        );
    }
}
