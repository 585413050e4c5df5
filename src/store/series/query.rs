//! What a series read asks for ([`SeriesQuery`]), and the statements both backends run for it
//! with their parameters: the point's packed blocks that overlap the range, then its unpacked
//! tail rows, in one statement.

use super::sqlite_raw::Param;

/// What to read: one point, `from ≤ observed_at ≤ to`, after the cursor `after` (store format),
/// at most `limit` rows.
#[derive(Debug, Clone, Default)]
pub struct SeriesQuery {
    /// Site id.
    pub site: String,
    /// Point name.
    pub point: String,
    /// Earliest observed_at, inclusive (store format).
    pub from: Option<String>,
    /// Latest observed_at, inclusive (store format).
    pub to: Option<String>,
    /// Only rows after this observed_at (store format): the page cursor.
    pub after: Option<String>,
    /// At most this many rows (`None`: all); one more is read to tell whether there are more.
    pub limit: Option<i64>,
    /// The point's direction of interest (site frame, any length): gives `d_along_mm`.
    pub direction: Option<[f64; 3]>,
    /// Read each packed block's extremes instead of all its rows ([`EXTREMES_SQL`]) when the
    /// whole series holds more than this many records: for a plot whose buckets span a block or
    /// more ([`series_columns::fold`](columns::fold)). `None`: every row.
    pub extremes_above: Option<usize>,
}

/// The 31 empty columns of a block row (where a tail row has its values).
macro_rules! block_row_nulls {
    () => {
        "NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, \
         NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL"
    };
}

/// The point's packed blocks that overlap the range, with their column `$col`: a block row has
/// its last time and `$col`.
macro_rules! blocks_in_range {
    ($($col:tt)+) => {
        concat!(
            "SELECT last_at, ", $($col)+, ", ", block_row_nulls!(), " FROM series_blocks \
             WHERE site_id = $1 AND point = $2 AND last_at >= $3 AND last_at > $4 AND first_at <= $5"
        )
    };
}

/// [`blocks_in_range`] but only the blocks that can hold the first `$13` records: those with
/// fewer than `$13` records in the blocks before them (PostgreSQL: a window over the blocks' row
/// counts, read from the index and the small heap rows, not from the blocks' data).
macro_rules! blocks_in_range_cut {
    ($($col:tt)+) => {
        concat!(
            "SELECT last_at, ", $($col)+, ", ", block_row_nulls!(), " FROM (SELECT last_at, extremes, data, \
             SUM(n_rows) OVER (ORDER BY last_at) - n_rows AS records_before FROM series_blocks \
             WHERE site_id = $1 AND point = $2 AND last_at >= $3 AND last_at > $4 AND first_at <= $5) AS blocks \
             WHERE records_before < $13"
        )
    };
}

/// The series: the block rows of `$blocks`, then the tail rows in the range, in time order (one
/// statement: one snapshot). A tail row has its time and values. The union is merged on the two
/// primary keys (`EXPLAIN QUERY PLAN`: `MERGE (UNION ALL)`, no sort).
macro_rules! series_sql {
    ($($blocks:tt)+) => {
        concat!(
            $($blocks)+,
            " UNION ALL \
            SELECT observed_at, NULL, epoch_id, reference_epoch, dx_mm, dy_mm, dz_mm, d_mm, \
            sigma_dx_mm, sigma_dy_mm, sigma_dz_mm, sigma_mm, significant, velocity_mm_per_day, \
            time_to_failure_hours, cov_dxdy_mm2, cov_dxdz_mm2, cov_dydz_mm2, time_to_failure_sigma_hours, \
            f_dx_mm, f_dy_mm, f_dz_mm, f_d_mm, sigma_f_dx_mm, sigma_f_dy_mm, sigma_f_dz_mm, sigma_f_d_mm, \
            f_velocity_mm_per_day, sigma_f_velocity_mm_per_day, f_acceleration_mm_per_day2, \
            sigma_f_acceleration_mm_per_day2, f_time_to_failure_hours, sigma_f_time_to_failure_hours \
            FROM displacements \
            WHERE site_id = $6 AND point = $7 \
            AND observed_at > COALESCE((SELECT sealed_until FROM series_seals WHERE site_id = $8), '') \
            AND observed_at >= $9 AND observed_at <= $10 AND observed_at > $11 ORDER BY 1"
        )
    };
}

/// The blocks' column of [`EXTREMES_SQL`]: each block's extremes, the point's last block whole.
macro_rules! extremes_column {
    () => {
        "CASE WHEN last_at = (SELECT MAX(b.last_at) FROM series_blocks b \
         WHERE b.site_id = $1 AND b.point = $2) THEN data ELSE extremes END"
    };
}

/// Every row of the series: each block's packed rows, then the tail rows.
pub(super) const SQL: &str = series_sql!(blocks_in_range!("data"));

/// The series as a coarse plot reads it: each block's extremes
/// ([`record::extremes`]) but the point's last block whole, then the tail rows, so the
/// last epochs are all there.
pub(super) const EXTREMES_SQL: &str = series_sql!(blocks_in_range!(extremes_column!()));

/// [`SQL`] for a page, on PostgreSQL, which sends every row of a statement before the writers
/// see one ([`postgres`]): the blocks that can hold the first `$13` records
/// ([`blocks_in_range_cut`]), and at most `$12` rows. Each row gives at least one record in the
/// range (a block is read only when its last record is after the cursor and `from`), and only
/// the first block can hold records before them, so a page of `limit` records needs `limit + 1`
/// rows and the blocks before which fewer than `limit + 1 + BLOCK_EPOCHS` records lie, however
/// long the rest of the series.
pub(super) const SQL_LIMITED: &str =
    concat!(series_sql!(blocks_in_range_cut!("data")), " LIMIT $12");

/// [`EXTREMES_SQL`] for a page (see [`SQL_LIMITED`]).
pub(super) const EXTREMES_SQL_LIMITED: &str = concat!(
    series_sql!(blocks_in_range_cut!(extremes_column!())),
    " LIMIT $12"
);

/// The number of records of the whole series of `q.site`/`q.point` (its range is not applied):
/// the packed blocks' row counts and the tail rows.
/// (PostgreSQL's SUM of a BIGINT is a NUMERIC: cast back.)
pub(super) const COUNT_SQL: &str = "SELECT CAST(COALESCE((SELECT SUM(n_rows) FROM series_blocks WHERE site_id = $1 AND point = $2), 0) \
    + (SELECT COUNT(*) FROM displacements WHERE site_id = $3 AND point = $4 \
    AND observed_at > COALESCE((SELECT sealed_until FROM series_seals WHERE site_id = $5), '')) AS BIGINT)";

/// The parameters of [`COUNT_SQL`] for `q` (site, point, site, point, site; both backends bind
/// these).
pub(super) fn count_params(q: &SeriesQuery) -> [Param<'_>; 5] {
    let (site, point) = (Param::Text(&q.site), Param::Text(&q.point));
    [site, point, site, point, site]
}

/// The parameters of [`SQL`] for `q`, in order (both backends bind these).
pub(super) fn params(q: &SeriesQuery) -> [Param<'_>; 11] {
    let from = Param::Text(q.from.as_deref().unwrap_or(""));
    let to = Param::Text(q.to.as_deref().unwrap_or(crate::store::TEXT_MAX));
    let after = Param::Text(q.after.as_deref().unwrap_or(""));
    let site = Param::Text(&q.site);
    let point = Param::Text(&q.point);
    [
        site, point, from, after, to, site, point, site, from, to, after,
    ]
}
