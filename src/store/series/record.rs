//! The binary form of one row of a point's displacement series, as packed into the blocks of
//! [`super::blocks`] and into the batches [`super`] formats: the served values
//! exactly as stored (the time as its stored text, floats as their IEEE bits), nothing derived.
//!
//! Layout, little-endian, self-delimiting (no padding):
//! `flags: u8` (bit 0 significant; bits 1–6 present: velocity, time to failure, cov(dx, dy),
//! cov(dx, dz), cov(dy, dz), σ of the time to failure; bit 7 filtered values), `len: u8` and the
//! `len` bytes of `observed_at` (store form), `epoch: i64`, `reference: i64`, 8 × `f64` (dx, dy,
//! dz, d, σdx, σdy, σdz, σd in mm), then one `f64` per present optional value in that order; then,
//! with bit 7, the filtered values ([`Filtered`]): `fflags: u8` (bits 0–3 present: acceleration,
//! its σ, time to failure, its σ), 10 × `f64` (f_dx, f_dy, f_dz, f_d, their σ, f_velocity and its
//! σ) and one `f64` per present value. A block is [`FORMAT`] followed by records. Format 1 had no
//! bits 6 and 7; its records read the same.
//!
//! Pure: no I/O. Rows whose stored time is longer than 255 bytes cannot be packed ([`encode`]
//! says so); the store writes 27.

/// First byte of a packed block: the version of this layout.
pub const FORMAT: u8 = 2;

/// Whether a block's first byte is a format this reader decodes (1 is 2 without filtered values).
pub fn readable(format: u8) -> bool {
    format == 1 || format == FORMAT
}

/// The Kalman filter's values of a row and the raw forecast's σ (see
/// [`cliffwatch_core::analysis::FilteredValues`]): mm, mm/day, mm/day², hours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Filtered {
    /// f_dx, f_dy, f_dz, f_d, σ of each, f_velocity (mm/day) and its σ.
    pub v: [f64; 10],
    /// f_acceleration (mm/day²), its σ, f_time_to_failure (h) and its σ.
    pub opt: [Option<f64>; 4],
}

/// One row of the series as stored, the time borrowed from its buffer. Lengths in mm, covariances
/// in mm², velocity in mm/day, time to failure in hours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record<'a> {
    /// Epoch id.
    pub epoch: i64,
    /// observed_at as stored (`YYYY-MM-DDTHH:MM:SS.ffffffZ`).
    pub observed_at: &'a [u8],
    /// The reference epoch's id.
    pub reference: i64,
    /// dx, dy, dz, d, σdx, σdy, σdz, σd in mm.
    pub v: [f64; 8],
    /// Significant at the site's confidence.
    pub significant: bool,
    /// Rate of d in mm/day (NULL: `None`).
    pub velocity: Option<f64>,
    /// Time to failure in hours (NULL: `None`).
    pub ttf: Option<f64>,
    /// Covariances of (dx, dy), (dx, dz), (dy, dz) in mm² (NULL: `None`).
    pub cov: [Option<f64>; 3],
    /// σ of the time to failure in hours (NULL: `None`).
    pub ttf_sigma: Option<f64>,
    /// The filtered values (NULL: `None`).
    pub filtered: Option<Filtered>,
}

const FILTERED_FLAG: u8 = 0x80;

const FIXED: usize = 2 + 8 + 8 + 8 * 8;

/// Appends `r` to `out`; `false` (nothing written) when its time is longer than 255 bytes.
pub fn encode(r: &Record<'_>, out: &mut Vec<u8>) -> bool {
    let Ok(len) = u8::try_from(r.observed_at.len()) else {
        return false;
    };
    let optional = [r.velocity, r.ttf, r.cov[0], r.cov[1], r.cov[2], r.ttf_sigma];
    let mut flags = u8::from(r.significant);
    for (k, v) in optional.iter().enumerate() {
        if v.is_some() {
            flags |= 2 << k;
        }
    }
    if r.filtered.is_some() {
        flags |= FILTERED_FLAG;
    }
    out.reserve(FIXED + r.observed_at.len() + 40 + 130);
    out.push(flags);
    out.push(len);
    out.extend_from_slice(r.observed_at);
    out.extend_from_slice(&r.epoch.to_le_bytes());
    out.extend_from_slice(&r.reference.to_le_bytes());
    for v in r.v {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in optional.into_iter().flatten() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    if let Some(f) = &r.filtered {
        let mut fflags = 0u8;
        for (k, v) in f.opt.iter().enumerate() {
            if v.is_some() {
                fflags |= 1 << k;
            }
        }
        out.push(fflags);
        for v in f.v.into_iter().chain(f.opt.into_iter().flatten()) {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    true
}

/// The stored time and total length of the record at the start of `bytes`, without decoding the
/// rest; `None` when `bytes` is shorter than the record.
pub fn peek(bytes: &[u8]) -> Option<(&[u8], usize)> {
    let flags = *bytes.first()?;
    let len = *bytes.get(1)? as usize;
    let mut total = FIXED + len + 8 * (flags >> 1 & 0x3f).count_ones() as usize;
    if flags & FILTERED_FLAG != 0 {
        let fflags = *bytes.get(total)?;
        total += 1 + 80 + 8 * (fflags & 0x0f).count_ones() as usize;
    }
    (bytes.len() >= total).then(|| (&bytes[2..2 + len], total))
}

/// The little-endian f64 at byte `at` of `bytes` (panics when fewer than 8 bytes follow).
pub(crate) fn f64_at(bytes: &[u8], at: usize) -> f64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&bytes[at..at + 8]);
    f64::from_le_bytes(b)
}

fn i64_at(bytes: &[u8], at: usize) -> i64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&bytes[at..at + 8]);
    i64::from_le_bytes(b)
}

/// The record at the start of `bytes` and its length; `None` when `bytes` is shorter than it.
pub fn decode(bytes: &[u8]) -> Option<(Record<'_>, usize)> {
    let (observed_at, total) = peek(bytes)?;
    let flags = bytes[0];
    let mut at = 2 + observed_at.len();
    let epoch = i64_at(bytes, at);
    let reference = i64_at(bytes, at + 8);
    at += 16;
    let v = std::array::from_fn(|k| f64_at(bytes, at + 8 * k));
    at += 64;
    let mut optional = [None; 6];
    for (k, slot) in optional.iter_mut().enumerate() {
        if flags & (2 << k) != 0 {
            *slot = Some(f64_at(bytes, at));
            at += 8;
        }
    }
    let filtered = (flags & FILTERED_FLAG != 0).then(|| {
        let fflags = bytes[at];
        at += 1;
        let v = std::array::from_fn(|k| f64_at(bytes, at + 8 * k));
        at += 80;
        let mut opt = [None; 4];
        for (k, slot) in opt.iter_mut().enumerate() {
            if fflags & (1 << k) != 0 {
                *slot = Some(f64_at(bytes, at));
                at += 8;
            }
        }
        Filtered { v, opt }
    });
    Some((
        Record {
            epoch,
            observed_at,
            reference,
            v,
            significant: flags & 1 != 0,
            velocity: optional[0],
            ttf: optional[1],
            cov: [optional[2], optional[3], optional[4]],
            ttf_sigma: optional[5],
            filtered,
        },
        total,
    ))
}

/// The records packed one after another in `bytes` (a block without its format byte, or a
/// batch), in order; stops at the first incomplete one.
pub fn records(mut bytes: &[u8]) -> impl Iterator<Item = Record<'_>> {
    std::iter::from_fn(move || {
        let (r, n) = decode(bytes)?;
        bytes = &bytes[n..];
        Some(r)
    })
}

/// The records of a block (`block`: [`FORMAT`] and its records) a coarse plot must keep, as a
/// block of the same layout: the first, the last, and those where dx, dy, dz and d (mm) take
/// their minimum and maximum (NaN ignored), each once, in order. At most 10 of the block's
/// records; a plot whose buckets span a block or more reads these instead of the block
/// ([`super`]). `None` when the block is not readable.
pub fn extremes(block: &[u8]) -> Option<Vec<u8>> {
    let (&format, body) = block.split_first()?;
    if !readable(format) {
        return None;
    }
    // (start, end) of each record and, per column, the record index of its min and max
    let mut spans = Vec::new();
    let mut best: [[Option<(usize, f64)>; 2]; 4] = [[None; 2]; 4];
    let mut at = 0;
    while at < body.len() {
        let (r, n) = decode(&body[at..])?;
        let i = spans.len();
        for (k, e) in best.iter_mut().enumerate() {
            let v = r.v[k];
            if !v.is_finite() {
                continue;
            }
            if e[0].is_none_or(|m| v < m.1) {
                e[0] = Some((i, v));
            }
            if e[1].is_none_or(|m| v > m.1) {
                e[1] = Some((i, v));
            }
        }
        spans.push((at, at + n));
        at += n;
    }
    let mut keep: Vec<usize> = best.iter().flatten().flatten().map(|m| m.0).collect();
    keep.extend([0, spans.len().saturating_sub(1)]);
    keep.sort_unstable();
    keep.dedup();
    let mut out = vec![format];
    for i in keep {
        if let Some(&(a, b)) = spans.get(i) {
            out.extend_from_slice(&body[a..b]);
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_bit_for_bit() {
        let rows = [
            Record {
                epoch: 7,
                observed_at: b"2026-01-02T03:04:05.000006Z",
                reference: -1,
                v: [0.1, -0.0, 1e-300, f64::MAX, 3.0, 2.5e-9, -7.25, 1.0 / 3.0],
                significant: true,
                velocity: Some(-0.0055),
                ttf: None,
                cov: [None, Some(-2.1e-3), Some(0.0)],
                ttf_sigma: None,
                filtered: Some(Filtered {
                    v: [1.5, -2.0, 0.25, 2.5, 0.1, 0.2, 0.3, 0.4, 0.05, 0.01],
                    opt: [Some(0.002), None, Some(96.5), Some(7.0)],
                }),
            },
            Record {
                epoch: i64::MAX,
                observed_at: b"",
                reference: i64::MIN,
                v: [f64::MIN_POSITIVE; 8],
                significant: false,
                velocity: None,
                ttf: Some(48.0),
                cov: [Some(1.0), None, None],
                ttf_sigma: Some(12.0),
                filtered: None,
            },
        ];
        let mut out = Vec::new();
        for r in &rows {
            assert!(encode(r, &mut out));
        }
        let back: Vec<Record> = records(&out).collect();
        assert_eq!(back.len(), 2);
        for (a, b) in back.iter().zip(&rows) {
            assert_eq!(a.epoch, b.epoch);
            assert_eq!(a.observed_at, b.observed_at);
            assert_eq!(a.reference, b.reference);
            assert_eq!(a.v.map(f64::to_bits), b.v.map(f64::to_bits));
            assert_eq!(a.significant, b.significant);
            assert_eq!(a.velocity.map(f64::to_bits), b.velocity.map(f64::to_bits));
            assert_eq!(a.ttf, b.ttf);
            assert_eq!(
                a.cov.map(|c| c.map(f64::to_bits)),
                b.cov.map(|c| c.map(f64::to_bits))
            );
            assert_eq!(a.ttf_sigma, b.ttf_sigma);
            assert_eq!(a.filtered, b.filtered);
        }
        // a cut record is not read
        assert_eq!(records(&out[..out.len() - 1]).count(), 1);
        let long = vec![b'x'; 256];
        let r = Record {
            observed_at: &long,
            ..rows[0]
        };
        assert!(!encode(&r, &mut Vec::new()));
    }

    /// A block's extremes: the first, the last and the min/max rows of dx, dy, dz, d, once
    /// each and in order, bit for bit.
    #[test]
    fn extremes_keep_ends_and_each_columns_min_and_max() {
        let times: Vec<String> = (0..128)
            .map(|k| format!("2026-01-01T00:00:{:02}.{k:06}Z", k % 60))
            .collect();
        let mut block = vec![FORMAT];
        for (k, t) in times.iter().enumerate() {
            let x = k as f64;
            let v = [
                (x * 0.3).sin(),
                if k == 77 { f64::NAN } else { -(x - 50.0).abs() },
                x * 0.01,
                if k == 90 { 9.0 } else { (x * 0.7).cos() },
                0.1,
                0.1,
                0.1,
                0.1,
            ];
            let r = Record {
                epoch: k as i64,
                observed_at: t.as_bytes(),
                reference: 1,
                v,
                significant: false,
                velocity: None,
                ttf: None,
                cov: [None; 3],
                ttf_sigma: None,
                filtered: None,
            };
            assert!(encode(&r, &mut block));
        }
        let all: Vec<Record> = records(&block[1..]).collect();
        let ext = extremes(&block).expect("readable");
        assert_eq!(ext[0], FORMAT);
        let kept: Vec<Record> = records(&ext[1..]).collect();
        let epochs: Vec<i64> = kept.iter().map(|r| r.epoch).collect();
        assert!(epochs.windows(2).all(|w| w[0] < w[1]), "{epochs:?}");
        assert!(kept.len() <= 10);
        assert_eq!((epochs[0], *epochs.last().unwrap()), (0, 127));
        assert!(epochs.contains(&90) && epochs.contains(&50));
        for k in 0..4 {
            let col = |rs: &[Record]| -> (f64, f64) {
                rs.iter()
                    .map(|r| r.v[k])
                    .filter(|v| v.is_finite())
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                        (a.min(v), b.max(v))
                    })
            };
            assert_eq!(col(&kept), col(&all), "column {k}");
        }
        for r in &kept {
            assert_eq!(
                r.v.map(f64::to_bits),
                all[r.epoch as usize].v.map(f64::to_bits)
            );
        }
        assert!(extremes(&[9]).is_none());
        assert_eq!(extremes(&[FORMAT]), Some(vec![FORMAT]));
    }
}
