//! What the SQL text and the column types need from the backends' differences: which backend a
//! connection is on, the placeholders of multi-row inserts and their size, BOOLEAN columns, the
//! upper bound of text ranges.

use sqlx::{Any, AnyConnection};

/// A BOOLEAN column as the store selects it, `CAST(column AS INTEGER)`: sqlx's `Any` driver
/// reads no SQLite column declared BOOLEAN, and the cast is the same on both backends.
pub struct Flag(i64);

impl sqlx::Type<Any> for Flag {
    fn type_info() -> sqlx::any::AnyTypeInfo {
        <i64 as sqlx::Type<Any>>::type_info()
    }

    fn compatible(ty: &sqlx::any::AnyTypeInfo) -> bool {
        <i64 as sqlx::Type<Any>>::compatible(ty)
    }
}

impl<'r> sqlx::Decode<'r, Any> for Flag {
    fn decode(value: sqlx::any::AnyValueRef<'r>) -> Result<Self, sqlx::error::BoxDynError> {
        <i64 as sqlx::Decode<'r, Any>>::decode(value).map(Flag)
    }
}

impl From<Flag> for bool {
    fn from(f: Flag) -> bool {
        f.0 != 0
    }
}

/// Whether the connection `db` is to PostgreSQL (else SQLite): for the few statements whose
/// text differs between the backends.
pub(crate) fn is_postgres(db: &AnyConnection) -> bool {
    db.backend_name() == "PostgreSQL"
}

/// Placeholders of a multi-row `VALUES` list on the connection `db`: `rows` groups of `cols`,
/// bound in order. PostgreSQL numbers them from `$1`; SQLite gets anonymous `?`, because sqlx
/// looks up the name of every parameter it binds and SQLite finds a named one by walking a list,
/// which made binding a statement of n named parameters cost n² (6 M instructions per upload).
pub(crate) fn values_list(db: &AnyConnection, rows: usize, cols: usize) -> String {
    let numbered = is_postgres(db);
    let mut out = String::with_capacity(rows * cols * 5);
    for r in 0..rows {
        out.push_str(if r == 0 { "(" } else { ", (" });
        for c in 0..cols {
            if c > 0 {
                out.push_str(", ");
            }
            if numbered {
                out.push('$');
                out.push_str(&(r * cols + c + 1).to_string());
            } else {
                out.push('?');
            }
        }
        out.push(')');
    }
    out
}

/// Rows per multi-row `INSERT` of `cols` columns: at most 30 000 parameters per statement, below
/// SQLite's limit (32 766) and PostgreSQL's (65 535). One statement per batch instead of one per
/// row is what keeps an upload's ~200 rows cheap.
pub(crate) fn rows_per_insert(cols: usize) -> usize {
    (30_000 / cols.max(1)).max(1)
}

/// Above every stored text key under binary text order: the open upper bound of range queries.
pub const TEXT_MAX: &str = "\u{10FFFF}";
