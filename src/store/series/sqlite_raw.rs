//! Row-by-row reads on a pooled connection through the SQLite C API, for the one read that is too
//! large for sqlx's per-row cost: a point's whole displacement series (87 600 rows in ten years
//! hourly). sqlx copies every value of every row into a new allocation and hands each row across a
//! channel from its worker thread (≈ 6 µs a row); here the caller sees each row in place, borrowed
//! until the next step, on the calling (blocking) thread.
//!
//! SQLite only (what else differs between the backends: the module doc of [`crate::store`]). The
//! store's `unsafe` code lives here, behind [`query`]: the statement is finalized on every path,
//! text is copied out before the next step, and the connection is locked away from sqlx's worker
//! thread for the whole call. (The crate's other `unsafe` code: the AVX2 kernel of
//! `photogrammetry::solve::normals`, and the binary's malloc settings in `cli::heap`.)

use std::ffi::{c_char, c_int, CStr};
use std::ptr;

use libsqlite3_sys as ffi;
use sqlx::pool::PoolConnection;
use sqlx::Sqlite;

use crate::store::StoreError;

/// A value to bind to a `?` parameter.
#[derive(Debug, Clone, Copy)]
pub enum Param<'a> {
    /// Text.
    Text(&'a str),
    /// A 64-bit integer.
    Int(i64),
}

/// The current row of a running statement; valid until the next step.
pub struct Row {
    stmt: *mut ffi::sqlite3_stmt,
    columns: c_int,
}

impl Row {
    fn check(&self, i: usize) -> c_int {
        assert!((i as c_int) < self.columns, "column {i} out of range");
        i as c_int
    }

    /// Whether column `i` (from 0) is NULL.
    pub fn is_null(&self, i: usize) -> bool {
        let i = self.check(i);
        // SAFETY: `stmt` is a live statement positioned on a row (see `query`), `i` in range.
        unsafe { ffi::sqlite3_column_type(self.stmt, i) == ffi::SQLITE_NULL }
    }

    /// Column `i` as an integer (SQLite's conversion rules; NULL is 0).
    pub fn int(&self, i: usize) -> i64 {
        let i = self.check(i);
        // SAFETY: as in `is_null`.
        unsafe { ffi::sqlite3_column_int64(self.stmt, i) }
    }

    /// Column `i` as a float (NULL is 0.0).
    pub fn double(&self, i: usize) -> f64 {
        let i = self.check(i);
        // SAFETY: as in `is_null`.
        unsafe { ffi::sqlite3_column_double(self.stmt, i) }
    }

    /// Column `i` as a float, `None` when NULL.
    pub fn opt_double(&self, i: usize) -> Option<f64> {
        (!self.is_null(i)).then(|| self.double(i))
    }

    /// Column `i` as text (UTF-8 bytes as stored; empty when NULL), borrowed until the next step.
    pub fn text(&self, i: usize) -> &[u8] {
        let i = self.check(i);
        // SAFETY: `sqlite3_column_text` then `sqlite3_column_bytes` (the documented order) on a
        // live row; the pointer stays valid until the next step or finalize, which cannot happen
        // while `&self` is borrowed (the row is only lent to the callback of `query`).
        unsafe {
            let p = ffi::sqlite3_column_text(self.stmt, i);
            let n = ffi::sqlite3_column_bytes(self.stmt, i);
            if p.is_null() || n <= 0 {
                &[]
            } else {
                std::slice::from_raw_parts(p, n as usize)
            }
        }
    }
}

impl Row {
    /// Column `i` as a blob (bytes as stored; empty when NULL), borrowed until the next step.
    pub fn blob(&self, i: usize) -> &[u8] {
        let i = self.check(i);
        // SAFETY: as in `text`: `sqlite3_column_blob` then `sqlite3_column_bytes` on a live row,
        // the pointer valid while `&self` is borrowed.
        unsafe {
            let p = ffi::sqlite3_column_blob(self.stmt, i) as *const u8;
            let n = ffi::sqlite3_column_bytes(self.stmt, i);
            if p.is_null() || n <= 0 {
                &[]
            } else {
                std::slice::from_raw_parts(p, n as usize)
            }
        }
    }
}

/// Finalizes the statement on every path.
struct Statement(*mut ffi::sqlite3_stmt);

impl Drop for Statement {
    fn drop(&mut self) {
        // SAFETY: the statement came from `sqlite3_prepare_v2` and is finalized once.
        unsafe {
            ffi::sqlite3_finalize(self.0);
        }
    }
}

fn error(db: *mut ffi::sqlite3, rc: c_int, what: &str) -> StoreError {
    // SAFETY: `db` is the open connection; `sqlite3_errmsg` returns a NUL-terminated string owned
    // by SQLite, copied at once.
    let message = unsafe { CStr::from_ptr(ffi::sqlite3_errmsg(db)) }
        .to_string_lossy()
        .into_owned();
    StoreError::Sqlite {
        code: rc,
        message: format!("{what}: {message}"),
    }
}

/// Runs one `SELECT` (`sql` with `?` parameters bound from `params` in order) on `conn` and calls
/// `each` with every row in order; `each` returns `false` to stop early. Blocking: call on a
/// blocking thread inside the tokio runtime (`spawn_blocking`), since taking the connection from
/// sqlx's worker thread awaits.
pub fn query(
    conn: &mut PoolConnection<Sqlite>,
    sql: &str,
    params: &[Param<'_>],
    mut each: impl FnMut(&Row) -> bool,
) -> Result<(), StoreError> {
    query_each(conn, sql, &[params], |_, row| each(row))
}

/// [`query`] of one statement, prepared once, run with each of `param_sets` in turn; `each`
/// gets the index of the parameter set and the row, and returns `false` to stop that run (the
/// next set runs).
pub fn query_each(
    conn: &mut PoolConnection<Sqlite>,
    sql: &str,
    param_sets: &[&[Param<'_>]],
    mut each: impl FnMut(usize, &Row) -> bool,
) -> Result<(), StoreError> {
    let runtime = tokio::runtime::Handle::current();
    let mut locked = runtime.block_on(conn.lock_handle())?;
    let db = locked.as_raw_handle().as_ptr();
    let mut raw: *mut ffi::sqlite3_stmt = ptr::null_mut();
    let len = c_int::try_from(sql.len()).map_err(|_| StoreError::Sqlite {
        code: ffi::SQLITE_TOOBIG,
        message: "statement too long".into(),
    })?;
    // SAFETY: `db` is the connection, locked away from sqlx's worker for the life of `locked`;
    // `sql` is valid for `len` bytes; `raw` receives the statement (or NULL).
    let rc = unsafe {
        ffi::sqlite3_prepare_v2(
            db,
            sql.as_ptr() as *const c_char,
            len,
            &mut raw,
            ptr::null_mut(),
        )
    };
    if rc != ffi::SQLITE_OK {
        return Err(error(db, rc, "prepare"));
    }
    if raw.is_null() {
        return Ok(()); // empty statement
    }
    let stmt = Statement(raw);
    // SAFETY: live statement.
    let columns = unsafe { ffi::sqlite3_column_count(stmt.0) };
    let row = Row {
        stmt: stmt.0,
        columns,
    };
    for (set, params) in param_sets.iter().enumerate() {
        // SAFETY: live statement, not stepping (fresh, or reset after its last run).
        unsafe {
            ffi::sqlite3_reset(stmt.0);
            ffi::sqlite3_clear_bindings(stmt.0);
        }
        for (k, p) in params.iter().enumerate() {
            let i = k as c_int + 1;
            // SAFETY: live statement; text is copied by SQLite (`SQLITE_TRANSIENT`).
            let rc = unsafe {
                match *p {
                    Param::Text(s) => ffi::sqlite3_bind_text(
                        stmt.0,
                        i,
                        s.as_ptr() as *const c_char,
                        c_int::try_from(s.len()).unwrap_or(c_int::MAX),
                        ffi::SQLITE_TRANSIENT(),
                    ),
                    Param::Int(v) => ffi::sqlite3_bind_int64(stmt.0, i, v),
                }
            };
            if rc != ffi::SQLITE_OK {
                return Err(error(db, rc, "bind"));
            }
        }
        loop {
            // SAFETY: live statement, stepped only here, on this thread.
            let rc = unsafe { ffi::sqlite3_step(stmt.0) };
            match rc {
                ffi::SQLITE_ROW => {
                    if !each(set, &row) {
                        break;
                    }
                }
                ffi::SQLITE_DONE => break,
                _ => return Err(error(db, rc, "step")),
            }
        }
    }
    drop(stmt);
    drop(locked);
    Ok(())
}
