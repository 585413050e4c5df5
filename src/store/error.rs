//! The store's one error type.

use thiserror::Error;

/// A database error.
#[derive(Debug, Error)]
pub enum StoreError {
    /// The database failed.
    #[error("database: {0}")]
    Sql(#[from] sqlx::Error),
    /// A migration failed.
    #[error("migration: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
    /// A stored JSON column does not parse.
    #[error("stored JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// A direct SQLite call failed (the series reader, [`super::series::sqlite_raw`]).
    #[error("sqlite ({code}): {message}")]
    Sqlite {
        /// SQLite result code (0: the reader thread itself failed).
        code: i32,
        /// What failed and SQLite's message.
        message: String,
    },
    /// A packed series block cannot be written or read ([`super::series::blocks`], [`super::series::record`]).
    #[error("series block: {0}")]
    Block(String),
    /// The data directory cannot be created.
    #[error("data directory: {0}")]
    Io(#[from] std::io::Error),
    /// A stored value is not one this version knows.
    #[error("stored value: {0}")]
    Corrupt(String),
    /// The stored body of one of an alert's outbox events does not parse as the contract body
    /// it was written as ([`crate::webhooks::WebhookPayload`]).
    #[error("stored event body of alert '{alert}': {source}")]
    EventBody {
        /// The alert's id.
        alert: String,
        /// Why the body does not parse.
        source: serde_json::Error,
    },
    /// A stored name (level, state, role, model…) is not one this version knows.
    #[error("stored value: {0}")]
    Name(#[from] cliffwatch_core::contract::names::UnknownName),
    /// The database URL names no backend this version has.
    #[error("database URL '{0}': want sqlite://PATH or postgres://…")]
    Url(String),
}

impl StoreError {
    /// The database refused a value of the request, not the request's moment: PostgreSQL's
    /// SQLSTATE class 22, "data exception" (e.g. 22021, text holding the NUL character, which
    /// SQLite stores). Sending the same value again fails the same way.
    pub fn is_data_exception(&self) -> bool {
        match self {
            StoreError::Sql(sqlx::Error::Database(e)) => e
                .code()
                // A SQLSTATE has five characters; SQLite's result codes are at most four digits.
                .is_some_and(|c| c.len() == 5 && c.starts_with("22")),
            _ => false,
        }
    }
}
