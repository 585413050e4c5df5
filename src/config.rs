//! Layered configuration: the embedded `config/default.toml`, an optional file (`--config FILE`),
//! environment variables `CLIFFWATCH_<OPTION>`, then command-line flags.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use figment::providers::{Env, Format, Serialized, Toml};
use figment::Figment;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::store::sites::NewSite;

/// The embedded defaults (`config/default.toml`).
pub const DEFAULT_TOML: &str = include_str!("../config/default.toml");

/// Name of the database file inside the data directory.
pub const DATABASE_FILE: &str = "cliffwatch.db";

/// Everything the service can be configured with (see `config/default.toml`).
///
/// Neither this nor [`TokenConfig`] or [`WebhookConfig`] implements `Debug`: they hold secrets
/// (bearer tokens, webhook signing secrets, the database password), so none can reach a log
/// through `{:?}` by accident.
///
/// ```compile_fail
/// fn loggable<T: std::fmt::Debug>() {}
/// loggable::<cliffwatch::config::Config>();
/// ```
///
/// ```compile_fail
/// fn loggable<T: std::fmt::Debug>() {}
/// loggable::<cliffwatch::config::TokenConfig>();
/// ```
#[derive(Clone, Serialize, Deserialize)]
pub struct Config {
    /// Address and port of the HTTP API, e.g. `127.0.0.1:8080`.
    pub listen: String,
    /// Directory of the database.
    pub data_dir: PathBuf,
    /// Database URL: `sqlite://PATH` or `postgres://USER:PASSWORD@HOST:PORT/DB`; `None`: the
    /// SQLite file `cliffwatch.db` in `data_dir`.
    #[serde(default)]
    pub database_url: Option<String>,
    /// Watched directory; `None`: no watching.
    #[serde(default)]
    pub watch_dir: Option<PathBuf>,
    /// Largest request body in bytes (larger: 413).
    pub body_limit_bytes: usize,
    /// Time limit of one request in seconds.
    pub request_timeout_secs: u64,
    /// Uploads this node processes at once (0: twice its cores, at least 2); the others wait.
    #[serde(default)]
    pub max_concurrent_uploads: usize,
    /// How long an upload waits for one of those slots before it is turned away with 503 and
    /// `Retry-After`, in seconds.
    #[serde(default = "default_upload_queue_secs")]
    pub upload_queue_secs: f64,
    /// Time in-flight requests get to finish after SIGTERM / ctrl-c, in seconds.
    pub shutdown_grace_secs: u64,
    /// Longest an upload's adjustment may compute, in seconds; past it the upload is answered
    /// 503 `compute_budget_exceeded` and nothing is stored. An upload whose client is answered
    /// or gone (request time limit, closed connection) stops computing at once.
    #[serde(default = "default_compute_budget_secs")]
    pub compute_budget_secs: u64,
    /// Most points (targets) one epoch may hold; a larger epoch is refused (413) before any
    /// computation.
    #[serde(default = "default_max_epoch_points")]
    pub max_epoch_points: usize,
    /// Most image observations one epoch may hold, over all its images; a larger epoch is
    /// refused (413) before any computation.
    #[serde(default = "default_max_epoch_observations")]
    pub max_epoch_observations: usize,
    /// Log format.
    pub log_format: LogFormat,
    /// Connections of the read pool.
    pub read_connections: u32,
    /// SQLite busy timeout in milliseconds.
    pub busy_timeout_ms: u64,
    /// PostgreSQL: connections of the write pool (sites written at once by this node).
    #[serde(default = "default_write_connections")]
    pub database_write_connections: u32,
    /// The node's name: label `node` of every `/metrics` series; `None`: host name and port.
    #[serde(default)]
    pub node_name: Option<String>,
    /// Bearer tokens; empty: no authentication, loopback only.
    #[serde(default)]
    pub tokens: Vec<TokenConfig>,
    /// Sites created or updated at start.
    #[serde(default)]
    pub sites: Vec<NewSite>,
    /// Webhook endpoints registered at start.
    #[serde(default)]
    pub webhooks: Vec<WebhookConfig>,
    /// How often the webhook delivery worker looks for due deliveries, in milliseconds.
    #[serde(default = "default_webhook_poll_ms")]
    pub webhook_poll_ms: u64,
    /// Time limit of one webhook POST in seconds.
    #[serde(default = "default_webhook_timeout_secs")]
    pub webhook_timeout_secs: u64,
    /// Backoff of webhook retries (`base_seconds`, `max_delay_seconds`, `max_attempts`,
    /// `max_retry_after_seconds`).
    #[serde(default)]
    pub webhook_retry: crate::webhooks::RetryPolicy,
    /// How often every open alert is posted again to each `alertmanager_api_v2` endpoint, in
    /// seconds (1 to 3600; Alertmanager holds a posted alert for 4 periods).
    #[serde(default = "default_alertmanager_resend_secs")]
    pub alertmanager_resend_secs: f64,
    /// How often sites with `schedule_hours` are checked for an overdue campaign, in seconds.
    #[serde(default = "default_overdue_check_secs")]
    pub overdue_check_secs: u64,
    /// Days a finished webhook delivery (delivered or given up) is kept after its last attempt,
    /// then deleted; 0 keeps every one. Pending deliveries and the alerts' events are never
    /// deleted.
    #[serde(default = "default_webhook_delivery_retention_days")]
    pub webhook_delivery_retention_days: u64,
    /// Days an epoch's raw observations (image coordinates and residuals) are kept after its
    /// observation time, then deleted (checked hourly); 0 (default) keeps them for ever. The
    /// epoch, its report, coordinates, covariances and displacements are never deleted.
    #[serde(default)]
    pub observation_retention_days: u64,
    /// Days a folder the watched directory took (`<site>/.done/<folder>`: its images and the
    /// watcher's files) is kept after it was last written, then deleted (checked hourly); 0
    /// (default) keeps them for ever. `.failed/` folders are never deleted.
    #[serde(default)]
    pub watch_done_retention_days: u64,
    /// The CAP feed's `sender` (no spaces, commas, `<` or `&`), e.g. `cliffwatch@agency.example`.
    #[serde(default = "default_cap_sender")]
    pub cap_sender: String,
    /// The CAP feed's `status`: `Actual` (default), `Exercise`, `System`, `Test` or `Draft`.
    #[serde(default = "default_cap_status")]
    pub cap_status: String,
    /// The address people reach the dashboard at, e.g. `https://cliffwatch.agency.example`
    /// (absolute links in the CAP messages and feed, the session cookie's `Secure` flag, and an
    /// `Origin` accepted besides the request's `Host`); `None`: links relative to the server.
    #[serde(default)]
    pub public_url: Option<String>,
    /// A dashboard session ends after this many minutes without a request (default 720: 12
    /// hours); fractions allowed. Sessions are kept in the database ([`crate::http::session`]).
    #[serde(default = "default_session_idle_minutes")]
    pub session_idle_minutes: f64,
    /// A dashboard session ends this many hours after its sign-in, however active (default
    /// 168: a week); fractions allowed.
    #[serde(default = "default_session_lifetime_hours")]
    pub session_lifetime_hours: f64,
}

fn default_session_idle_minutes() -> f64 {
    720.0
}
fn default_session_lifetime_hours() -> f64 {
    168.0
}

/// Default of [`Config::compute_budget_secs`], seconds.
pub const DEFAULT_COMPUTE_BUDGET_SECS: u64 = 120;
/// Default of [`Config::max_epoch_points`].
pub const DEFAULT_MAX_EPOCH_POINTS: usize = 20_000;
/// Default of [`Config::max_epoch_observations`].
pub const DEFAULT_MAX_EPOCH_OBSERVATIONS: usize = 200_000;

fn default_compute_budget_secs() -> u64 {
    DEFAULT_COMPUTE_BUDGET_SECS
}
fn default_max_epoch_points() -> usize {
    DEFAULT_MAX_EPOCH_POINTS
}
fn default_max_epoch_observations() -> usize {
    DEFAULT_MAX_EPOCH_OBSERVATIONS
}
fn default_upload_queue_secs() -> f64 {
    30.0
}
fn default_write_connections() -> u32 {
    4
}
fn default_webhook_poll_ms() -> u64 {
    1000
}
fn default_webhook_timeout_secs() -> u64 {
    10
}
fn default_alertmanager_resend_secs() -> f64 {
    crate::webhooks::DEFAULT_RESEND_SECS as f64
}
fn default_overdue_check_secs() -> u64 {
    300
}
fn default_webhook_delivery_retention_days() -> u64 {
    90
}
fn default_cap_sender() -> String {
    "cliffwatch@localhost".into()
}
fn default_cap_status() -> String {
    "Actual".into()
}

/// The CAP statuses `cap_status` may take.
pub const CAP_STATUSES: [&str; 5] = ["Actual", "Exercise", "System", "Test", "Draft"];

/// Log output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LogFormat {
    /// Human-readable lines.
    Human,
    /// One JSON object per line.
    Json,
}

/// Roles of a bearer token, ordered: each includes the ones before.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Read everything.
    Read,
    /// Read, upload epochs, acknowledge alerts.
    Upload,
    /// Everything: sites, points, reference, webhooks.
    Admin,
}

/// One bearer token and its role.
#[derive(Clone, Serialize, Deserialize)]
pub struct TokenConfig {
    /// The secret token as sent in `Authorization: Bearer <token>`.
    pub token: String,
    /// What it may do.
    pub role: Role,
}

/// A webhook endpoint from the configuration file.
#[derive(Clone, Serialize, Deserialize)]
pub struct WebhookConfig {
    /// Target URL.
    pub url: String,
    /// Signing secret, `whsec_<base64>`.
    pub secret: String,
    /// Lowest alert level delivered (`watch`, `warning`, `alarm`).
    #[serde(default = "default_min_level")]
    pub min_level: cliffwatch_core::analysis::AlertLevel,
    /// Body format: `standard` (default, the contract body), `alertmanager_webhook` or
    /// `alertmanager_api_v2` ([`crate::webhooks::PayloadFormat`]).
    #[serde(default)]
    pub format: crate::webhooks::PayloadFormat,
}

fn default_min_level() -> cliffwatch_core::analysis::AlertLevel {
    cliffwatch_core::analysis::AlertLevel::Warning
}

/// Values given on the command line; `None` leaves the lower layers in force.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Overrides {
    /// `--listen`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub listen: Option<String>,
    /// `--data-dir`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data_dir: Option<PathBuf>,
    /// `--watch-dir`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub watch_dir: Option<PathBuf>,
    /// `--database-url`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub database_url: Option<String>,
}

/// The configuration cannot be loaded or is inconsistent.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// A layer could not be read or parsed.
    #[error("configuration: {0}")]
    Load(#[from] Box<figment::Error>),
    /// `listen` is not `ADDR:PORT`.
    #[error("listen address '{0}' is not ADDR:PORT")]
    BadListen(String),
    /// Non-loopback address without tokens.
    #[error(
        "refusing to listen on non-loopback address {0} without [[tokens]] in the configuration"
    )]
    OpenWithoutTokens(SocketAddr),
    /// A token appears twice or is empty.
    #[error("tokens must be non-empty and distinct")]
    BadTokens,
    /// An option has a value it cannot take; the message names it.
    #[error("configuration: {0}")]
    Invalid(String),
}

impl Config {
    /// Loads the layers: defaults, `file` (when given), `CLIFFWATCH_*` environment, `overrides`.
    pub fn load(file: Option<&Path>, overrides: &Overrides) -> Result<Config, ConfigError> {
        let mut figment = Figment::from(Toml::string(DEFAULT_TOML));
        if let Some(file) = file {
            if !file.exists() {
                return Err(ConfigError::Load(Box::new(figment::Error::from(format!(
                    "configuration file {} does not exist",
                    file.display()
                )))));
            }
            figment = figment.merge(Toml::file(file));
        }
        figment = figment
            .merge(Env::prefixed("CLIFFWATCH_").ignore(&["config"]))
            .merge(Serialized::defaults(overrides));
        let config: Config = figment.extract().map_err(Box::new)?;
        config.check()?;
        Ok(config)
    }

    /// The embedded defaults with a data directory of its own (tests, tools).
    pub fn with_data_dir(data_dir: impl Into<PathBuf>) -> Config {
        let overrides = Overrides {
            data_dir: Some(data_dir.into()),
            ..Overrides::default()
        };
        let figment =
            Figment::from(Toml::string(DEFAULT_TOML)).merge(Serialized::defaults(overrides));
        figment.extract().expect("embedded defaults parse")
    }

    /// The parsed listen address.
    pub fn listen_addr(&self) -> Result<SocketAddr, ConfigError> {
        self.listen
            .parse()
            .map_err(|_| ConfigError::BadListen(self.listen.clone()))
    }

    /// Path of the default SQLite database file (in `data_dir`).
    pub fn database_path(&self) -> PathBuf {
        self.data_dir.join(DATABASE_FILE)
    }

    /// The database URL in force: `database_url`, else `sqlite://<data_dir>/cliffwatch.db`.
    pub fn database_url(&self) -> String {
        match &self.database_url {
            Some(url) => url.clone(),
            None => format!("sqlite://{}", self.database_path().display()),
        }
    }

    /// The node's name (`node_name`, else `<host name>:<port>`): label `node` in `/metrics`.
    pub fn node_name(&self, port: u16) -> String {
        if let Some(name) = &self.node_name {
            return name.clone();
        }
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .ok()
            .or_else(|| std::env::var("HOSTNAME").ok())
            .map(|h| h.trim().to_string())
            .filter(|h| !h.is_empty())
            .unwrap_or_else(|| "cliffwatch".into());
        format!("{host}:{port}")
    }

    /// Checks what does not depend on the network: the listen address parses, tokens are sane,
    /// and a non-loopback address has tokens.
    pub fn check(&self) -> Result<(), ConfigError> {
        let addr = self.listen_addr()?;
        let mut seen = std::collections::HashSet::new();
        if self
            .tokens
            .iter()
            .any(|t| t.token.is_empty() || !seen.insert(t.token.as_str()))
        {
            return Err(ConfigError::BadTokens);
        }
        if self.tokens.is_empty() && !addr.ip().is_loopback() {
            return Err(ConfigError::OpenWithoutTokens(addr));
        }
        if self.cap_sender.is_empty()
            || self
                .cap_sender
                .chars()
                .any(|c| c.is_whitespace() || c == ',' || c == '<' || c == '&')
        {
            return Err(ConfigError::Invalid(format!(
                "cap_sender '{}': not empty, without spaces, commas, '<' or '&'",
                self.cap_sender
            )));
        }
        if !CAP_STATUSES.contains(&self.cap_status.as_str()) {
            return Err(ConfigError::Invalid(format!(
                "cap_status '{}': one of {}",
                self.cap_status,
                CAP_STATUSES.join(", ")
            )));
        }
        self.webhook_retry.check().map_err(ConfigError::Invalid)?;
        if !(0.0..=self.request_timeout_secs as f64).contains(&self.upload_queue_secs) {
            return Err(ConfigError::Invalid(format!(
                "upload_queue_secs {}: 0 to request_timeout_secs ({})",
                self.upload_queue_secs, self.request_timeout_secs
            )));
        }
        if !(1..=86_400).contains(&self.compute_budget_secs) {
            return Err(ConfigError::Invalid(format!(
                "compute_budget_secs {}: 1 to 86400 seconds",
                self.compute_budget_secs
            )));
        }
        if self.max_epoch_points == 0 || self.max_epoch_observations == 0 {
            return Err(ConfigError::Invalid(
                "max_epoch_points and max_epoch_observations: at least 1".into(),
            ));
        }
        if !(1.0..=3600.0).contains(&self.alertmanager_resend_secs) {
            return Err(ConfigError::Invalid(format!(
                "alertmanager_resend_secs {}: 1 to 3600 seconds",
                self.alertmanager_resend_secs
            )));
        }
        // Up to ten years; a longer one is a mistake (and would overflow a duration).
        let ten_years_minutes = 10.0 * 366.0 * 24.0 * 60.0;
        if !(self.session_idle_minutes > 0.0 && self.session_idle_minutes <= ten_years_minutes) {
            return Err(ConfigError::Invalid(format!(
                "session_idle_minutes {}: more than 0, at most ten years",
                self.session_idle_minutes
            )));
        }
        if !(self.session_lifetime_hours > 0.0
            && self.session_lifetime_hours * 60.0 <= ten_years_minutes)
        {
            return Err(ConfigError::Invalid(format!(
                "session_lifetime_hours {}: more than 0, at most ten years",
                self.session_lifetime_hours
            )));
        }
        if let Some(u) = &self.public_url {
            if !(u.starts_with("http://") || u.starts_with("https://"))
                || u.contains(char::is_whitespace)
            {
                return Err(ConfigError::Invalid(format!(
                    "public_url '{u}': an absolute http(s) URL"
                )));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_zero_configuration() {
        let c = Config::load(None, &Overrides::default()).unwrap();
        assert_eq!(c.listen_addr().unwrap().port(), 8080);
        assert_eq!(c.body_limit_bytes, 16 * 1024 * 1024);
        assert!(c.tokens.is_empty());
    }

    #[test]
    fn flags_override_and_open_address_needs_tokens() {
        let o = Overrides {
            listen: Some("0.0.0.0:9000".into()),
            ..Overrides::default()
        };
        assert!(matches!(
            Config::load(None, &o),
            Err(ConfigError::OpenWithoutTokens(_))
        ));
    }

    #[test]
    fn cap_sender_status_and_public_url_are_checked() {
        let mut c = Config::load(None, &Overrides::default()).unwrap();
        assert_eq!(c.cap_status, "Actual");
        c.cap_sender = "cliff watch".into();
        assert!(matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("cap_sender")));
        c.cap_sender = "cliffwatch@agency.example".into();
        c.cap_status = "Live".into();
        assert!(matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("cap_status")));
        c.cap_status = "Test".into();
        c.public_url = Some("cliffwatch.example".into());
        assert!(matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("public_url")));
        c.public_url = Some("https://cliffwatch.example".into());
        assert!(c.check().is_ok());
        for bad in [-1.0, f64::NAN, 121.0] {
            c.upload_queue_secs = bad;
            assert!(
                matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("upload_queue_secs")),
                "{bad}"
            );
        }
        c.upload_queue_secs = 0.0;
        assert!(c.check().is_ok());
        c.webhook_retry.max_retry_after_seconds = -1.0;
        assert!(
            matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("max_retry_after_seconds"))
        );
        c.webhook_retry = Default::default();
        c.webhook_retry.max_delay_seconds = 1e300;
        assert!(
            matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("max_delay_seconds"))
        );
        c.webhook_retry = Default::default();
        c.webhook_retry.max_attempts = 0;
        assert!(matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("max_attempts")));
        c.webhook_retry = Default::default();
        assert!(c.check().is_ok());
        assert_eq!(c.session_idle_minutes, 720.0);
        assert_eq!(c.session_lifetime_hours, 168.0);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            c.session_idle_minutes = bad;
            assert!(
                matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("session_idle_minutes")),
                "{bad}"
            );
            c.session_idle_minutes = 1.0;
            c.session_lifetime_hours = bad;
            assert!(
                matches!(c.check(), Err(ConfigError::Invalid(m)) if m.contains("session_lifetime_hours")),
                "{bad}"
            );
            c.session_lifetime_hours = 1.0;
        }
        assert!(c.check().is_ok());
    }

    #[test]
    fn example_file_parses() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/example.toml");
        let c = Config::load(Some(&path), &Overrides::default()).unwrap();
        assert_eq!(c.tokens.len(), 3);
        assert_eq!(c.log_format, LogFormat::Json);
        assert_eq!(c.session_idle_minutes, 60.0);
        assert_eq!(c.session_lifetime_hours, 12.0);
    }
}
