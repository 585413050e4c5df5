//! Identification of a first epoch seen from several stations, from ≥ 4 seeds per station and
//! map-grade approximations (pure).
//!
//! The images agree with each other far better than the approximations agree with the truth, so the
//! approximations are used last:
//! 1. each seed (a hand measurement, ±1 px) is snapped to its detection;
//! 2. the targets seeded in every station fix the stations' affine cameras relative to each other
//!    (`multiview::factorize`); no object coordinates are used;
//! 3. detections are matched across stations by epipolar and third-view consistency
//!    (`multiview::match_tracks`); the cameras are refitted on every target found in all stations
//!    and the matching repeated with the tighter tolerance this allows;
//! 4. only then are the tracks named (`naming::name_tracks`): a global assignment to the
//!    approximations through a 3-D affine map fitted to all of them, accepting a name only when it
//!    wins by a clear margin. An ambiguous target is left out, not guessed.
//!
//! [`FirstEpoch::refusal`] says when the result is too thin to use, naming the stations, the likely
//! cause and what to add.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Vector3;

use super::identify::{Identified, Seed};
use super::multiview::{self, AffineCamera, Track};
use super::naming::{self, NamingOptions};

/// Why a first epoch could not be identified across stations.
#[derive(Debug, thiserror::Error)]
pub enum FirstEpochError {
    /// An input value is not finite.
    #[error("invalid identification input: {0}")]
    Invalid(String),
    /// Fewer than 2 stations.
    #[error("{0} station(s); multi-view identification needs at least 2")]
    TooFewStations(usize),
    /// A seed names a point without approximate coordinates.
    #[error("station {station}: seed {point} has no approximate coordinates")]
    UnknownSeedPoint {
        /// Station.
        station: String,
        /// Point.
        point: String,
    },
    /// A seed is not on a detected target.
    #[error(
        "station {station}: seed {point} is {distance_mm:.3} mm from the nearest detected target \
         (at most {limit_mm:.3} mm): measure the seed on the target's centre, or check that the \
         target is visible"
    )]
    SeedOffTarget {
        /// Station.
        station: String,
        /// Point.
        point: String,
        /// Distance to the nearest detection in mm.
        distance_mm: f64,
        /// The snapping limit in mm.
        limit_mm: f64,
    },
    /// Fewer than 4 targets are seeded in every station.
    #[error(
        "only {} target(s) are seeded in every station ({}); seed the same 4 well-spread targets, \
         not all at one depth, in every station (seeded: {})",
        common.len(),
        common.join(", "),
        per_station.iter().map(|(s, p)| format!("{s}: {}", p.join(" "))).collect::<Vec<_>>().join("; ")
    )]
    TooFewCommonSeeds {
        /// The targets seeded in every station.
        common: Vec<String>,
        /// Per station, its seeded targets.
        per_station: Vec<(String, Vec<String>)>,
    },
    /// The seeds do not fit one geometry.
    #[error("the seeds disagree: {0}")]
    SeedsDisagree(String),
    /// The bundle adjustment of the tentative names failed ([`super::convergent`]).
    #[error(
        "the adjustment of the names found from the seeds failed ({0}): check the seeds, the \
         camera's principal distance and the approximations"
    )]
    Adjustment(String),
}

/// One station's input.
#[derive(Debug, Clone, Copy)]
pub struct StationView<'a> {
    /// Station name.
    pub station: &'a str,
    /// Detections in image mm (x right, y up, from the image centre).
    pub blobs_mm: &'a [[f64; 2]],
    /// Seed observations (≥ 4; the same targets in every station).
    pub seeds: &'a [Seed],
}

/// Options of [`identify_first_epoch`].
#[derive(Debug, Clone, PartialEq)]
pub struct FirstEpochOptions {
    /// Largest distance from a seed to its detection in mm (default 0.1 mm: 10 px of 10 µm).
    pub seed_snap_mm: f64,
    /// Largest image misfit of a match in mm before the cameras are refitted; at most 0.3 × the
    /// median spacing of the detections is used (default 0.3 mm).
    pub tolerance_mm: f64,
    /// Least tolerance in mm after the refit (default 0.02 mm).
    pub min_tolerance_mm: f64,
    /// Naming options.
    pub naming: NamingOptions,
}

impl Default for FirstEpochOptions {
    fn default() -> Self {
        Self {
            seed_snap_mm: 0.1,
            tolerance_mm: 0.3,
            min_tolerance_mm: 0.02,
            naming: NamingOptions::default(),
        }
    }
}

/// One station's result.
#[derive(Debug, Clone, PartialEq)]
pub struct StationNames {
    /// Station name.
    pub station: String,
    /// Number of detections.
    pub detected: usize,
    /// Named detections (offset: the track's largest image misfit in mm).
    pub matched: Vec<Identified>,
    /// Detections of targets left out: matched across stations but not named with confidence, or
    /// fitting two tracks.
    pub ambiguous_blobs: Vec<usize>,
    /// Detections in no track (clutter, or targets seen by too few stations).
    pub unmatched_blobs: Vec<usize>,
}

/// The outcome of [`identify_first_epoch`].
#[derive(Debug, Clone, PartialEq)]
pub struct FirstEpoch {
    /// Per station, in the input's order.
    pub stations: Vec<StationNames>,
    /// Targets matched across stations.
    pub tracks: usize,
    /// Named targets.
    pub named: Vec<String>,
    /// Targets left unnamed: (the assignment's choice, its closest rival).
    pub ambiguous: Vec<(String, String)>,
    /// Scatter σ per coordinate of the approximations about the images' geometry, m.
    pub approx_sigma_m: f64,
    /// The targets' median spacing as the images show it (`naming::Naming::spacing_m`), m.
    pub spacing_m: f64,
    /// The scatter beyond which no target is named (`naming::Naming::max_sigma_m`), m.
    pub max_sigma_m: f64,
    /// rms misfit of the affine cameras per image coordinate in mm (perspective and noise).
    pub camera_misfit_mm: f64,
}

impl FirstEpoch {
    /// One line per station: detected, identified, ambiguous, unmatched.
    pub fn summary(&self) -> String {
        self.stations
            .iter()
            .map(|s| {
                format!(
                    "{}: {} detected, {} identified, {} ambiguous, {} unmatched",
                    s.station,
                    s.detected,
                    s.matched.len(),
                    s.ambiguous_blobs.len(),
                    s.unmatched_blobs.len()
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    }

    /// Why the result is too thin to use (a station with fewer than 4 named targets, or fewer than half
    /// of the matched targets named), with the stations' counts, the likely cause and what to add;
    /// None when it can be used.
    pub fn refusal(&self) -> Option<String> {
        let thin = self.stations.iter().any(|s| s.matched.len() < 4);
        let detected = self.stations.iter().map(|s| s.detected).max().unwrap_or(0);
        if !thin && 2 * self.named.len() >= self.tracks && self.tracks > 0 {
            return None;
        }
        let mut msg = format!("identification failed ({}). ", self.summary());
        if 2 * self.tracks < detected {
            msg.push_str(&format!(
                "Only {} of about {detected} targets could be matched between the stations: a seed \
                 may be measured on the wrong target, or the stations see different parts of the \
                 face. Check the seeds, or seed 2 to 4 more targets spread over the face in every \
                 station.",
                self.tracks
            ));
        } else {
            let (sigma, spacing, bound) = (self.approx_sigma_m, self.spacing_m, self.max_sigma_m);
            msg.push_str(&format!(
                "The approximate coordinates scatter ±{sigma:.2} m about the images' geometry \
                 while the targets are about {spacing:.2} m apart: "
            ));
            msg.push_str(&if sigma > bound {
                format!(
                    "beyond ±{bound:.2} m no target is named. Give approximations better than \
                     ±{bound:.2} m per coordinate, or more seeds."
                )
            } else {
                format!(
                    "too many targets lie between two candidates. Give approximations better \
                     than ±{sigma:.2} m per coordinate (names are refused beyond ±{bound:.2} m), \
                     or more seeds."
                )
            });
            if !self.ambiguous.is_empty() {
                let names: BTreeSet<&str> = self.ambiguous.iter().map(|a| a.0.as_str()).collect();
                msg.push_str(&format!(
                    " Seed these targets by hand in every station: {}.",
                    names.into_iter().collect::<Vec<_>>().join(", ")
                ));
            }
        }
        Some(msg)
    }
}

fn finite2(v: [f64; 2]) -> bool {
    v[0].is_finite() && v[1].is_finite()
}

/// Per station, the detection of each seeded point: the nearest detection within `limit_mm`,
/// refused when another lies within that limit and within 3 × the distance of the nearest (two
/// detections on one target; a code ring's segments around a coded target lie much farther).
pub(super) fn snap_seeds(
    views: &[StationView<'_>],
    known: &BTreeMap<String, [f64; 3]>,
    limit_mm: f64,
) -> Result<Vec<BTreeMap<String, usize>>, FirstEpochError> {
    let mut out = Vec::with_capacity(views.len());
    for v in views {
        let mut snapped = BTreeMap::new();
        for s in v.seeds {
            if !known.contains_key(&s.point) {
                return Err(FirstEpochError::UnknownSeedPoint {
                    station: v.station.into(),
                    point: s.point.clone(),
                });
            }
            let mut by_distance: Vec<(f64, usize)> = v
                .blobs_mm
                .iter()
                .enumerate()
                .map(|(j, b)| ((b[0] - s.xy_mm[0]).hypot(b[1] - s.xy_mm[1]), j))
                .collect();
            by_distance.sort_by(|a, b| a.0.total_cmp(&b.0));
            let nearest = by_distance.first().copied().unwrap_or((f64::INFINITY, 0));
            let second = by_distance.get(1).map_or(f64::INFINITY, |d| d.0);
            if nearest.0 > limit_mm || second <= limit_mm.min(3.0 * nearest.0) {
                return Err(FirstEpochError::SeedOffTarget {
                    station: v.station.into(),
                    point: s.point.clone(),
                    distance_mm: if nearest.0 > limit_mm {
                        nearest.0
                    } else {
                        second
                    },
                    limit_mm,
                });
            }
            if let Some(prev) = snapped.insert(s.point.clone(), nearest.1) {
                if prev != nearest.1 {
                    return Err(FirstEpochError::SeedsDisagree(format!(
                        "station {}: seed {} is measured twice on different targets",
                        v.station, s.point
                    )));
                }
            }
        }
        if snapped.values().collect::<BTreeSet<_>>().len() != snapped.len() {
            return Err(FirstEpochError::SeedsDisagree(format!(
                "station {}: two seeds are measured on the same target",
                v.station
            )));
        }
        out.push(snapped);
    }
    Ok(out)
}

/// Tracks of the targets seeded in ≥ 2 stations.
fn seed_tracks(snapped: &[BTreeMap<String, usize>]) -> Vec<Vec<Option<usize>>> {
    let names: BTreeSet<&String> = snapped.iter().flat_map(|s| s.keys()).collect();
    names
        .into_iter()
        .map(|n| {
            snapped
                .iter()
                .map(|s| s.get(n).copied())
                .collect::<Vec<_>>()
        })
        .filter(|t| t.iter().flatten().count() >= 2)
        .collect()
}

/// Cameras from the points found in every view (the common seeds, or later every complete track).
fn cameras_from(
    blobs: &[&[[f64; 2]]],
    complete: &[Vec<Option<usize>>],
) -> Option<(Vec<AffineCamera>, f64)> {
    let views: Vec<Vec<[f64; 2]>> = (0..blobs.len())
        .map(|v| {
            complete
                .iter()
                .filter_map(|t| t[v].map(|j| blobs[v][j]))
                .collect()
        })
        .collect();
    multiview::factorize(&views).map(|(c, _, rms)| (c, rms))
}

/// Identifies the detections of `views` (one per station, ≥ 2, with ≥ 4 targets seeded in every one)
/// as the `known` points (name → approximate [X, Y, Z] m, site frame). Never guesses: see
/// [`FirstEpoch`].
pub fn identify_first_epoch(
    views: &[StationView<'_>],
    known: &BTreeMap<String, [f64; 3]>,
    opts: &FirstEpochOptions,
) -> Result<FirstEpoch, FirstEpochError> {
    if views.len() < 2 {
        return Err(FirstEpochError::TooFewStations(views.len()));
    }
    for v in views {
        if let Some(b) = v.blobs_mm.iter().find(|b| !finite2(**b)) {
            return Err(FirstEpochError::Invalid(format!(
                "station {}: detection {b:?} not finite",
                v.station
            )));
        }
        if let Some(s) = v.seeds.iter().find(|s| !finite2(s.xy_mm)) {
            return Err(FirstEpochError::Invalid(format!(
                "station {}: seed {} not finite",
                v.station, s.point
            )));
        }
    }
    if let Some((n, _)) = known.iter().find(|(_, x)| !x.iter().all(|c| c.is_finite())) {
        return Err(FirstEpochError::Invalid(format!("point {n} not finite")));
    }
    let snapped = snap_seeds(views, known, opts.seed_snap_mm)?;
    let common: Vec<String> = snapped[0]
        .keys()
        .filter(|n| snapped.iter().all(|s| s.contains_key(*n)))
        .cloned()
        .collect();
    if common.len() < 4 {
        return Err(FirstEpochError::TooFewCommonSeeds {
            common,
            per_station: views
                .iter()
                .zip(&snapped)
                .map(|(v, s)| (v.station.to_string(), s.keys().cloned().collect()))
                .collect(),
        });
    }
    let blobs: Vec<&[[f64; 2]]> = views.iter().map(|v| v.blobs_mm).collect();
    let common_tracks: Vec<Vec<Option<usize>>> = common
        .iter()
        .map(|n| snapped.iter().map(|s| s.get(n).copied()).collect())
        .collect();
    let (mut cams, mut misfit) = cameras_from(&blobs, &common_tracks).ok_or_else(|| {
        FirstEpochError::SeedsDisagree(format!(
            "the seeded targets {} lie on one line or plane in the images: seed targets at \
             different depths",
            common.join(", ")
        ))
    })?;
    let spacing = blobs
        .iter()
        .map(|b| multiview::median_spacing(b))
        .fold(f64::INFINITY, f64::min);
    let mut tol = opts.tolerance_mm.min(0.3 * spacing);
    let given = seed_tracks(&snapped);
    let min_views = views.len().min(3);
    let mut matching = multiview::match_tracks(&cams, &blobs, &given, tol, min_views);
    // refit the cameras on every target seen by all stations, and match again
    for _ in 0..2 {
        let complete: Vec<Vec<Option<usize>>> = matching
            .tracks
            .iter()
            .filter(|t| t.views() == views.len())
            .map(|t| t.blobs.clone())
            .collect();
        let Some((c, rms)) = cameras_from(&blobs, &complete) else {
            break;
        };
        if complete.len() <= common.len() {
            break;
        }
        cams = c;
        misfit = rms;
        tol = (6.0 * rms).clamp(opts.min_tolerance_mm, tol);
        matching = multiview::match_tracks(&cams, &blobs, &given, tol, min_views);
    }
    name_and_report(views, known, &snapped, &matching, misfit, opts)
}

fn name_and_report(
    views: &[StationView<'_>],
    known: &BTreeMap<String, [f64; 3]>,
    snapped: &[BTreeMap<String, usize>],
    matching: &multiview::Matching,
    misfit_mm: f64,
    opts: &FirstEpochOptions,
) -> Result<FirstEpoch, FirstEpochError> {
    let names: Vec<&String> = known.keys().collect();
    let approx: Vec<Vector3<f64>> = known.values().map(|x| Vector3::from(*x)).collect();
    let index: BTreeMap<&String, usize> = names.iter().enumerate().map(|(i, n)| (*n, i)).collect();
    let tracks: &[Track] = &matching.tracks;
    // a seeded detection names its track
    let mut fixed: Vec<Option<usize>> = vec![None; tracks.len()];
    for (k, t) in tracks.iter().enumerate() {
        for (v, b) in t.blobs.iter().enumerate() {
            let Some(j) = b else { continue };
            if let Some((p, _)) = snapped[v].iter().find(|(_, bj)| *bj == j) {
                let a = index[p];
                if fixed[k].is_some_and(|f| f != a) {
                    return Err(FirstEpochError::SeedsDisagree(format!(
                        "one target is seeded as {} and as {} in different stations",
                        names[fixed[k].unwrap_or(a)],
                        p
                    )));
                }
                fixed[k] = Some(a);
            }
        }
    }
    let mut seen = BTreeSet::new();
    for f in fixed.iter().flatten() {
        if !seen.insert(*f) {
            return Err(FirstEpochError::SeedsDisagree(format!(
                "seed {} is measured on different targets in different stations",
                names[*f]
            )));
        }
    }
    let xyz: Vec<Vector3<f64>> = tracks.iter().map(|t| t.xyz).collect();
    let named = naming::name_tracks(&xyz, &fixed, &approx, &opts.naming).ok_or_else(|| {
        FirstEpochError::SeedsDisagree(
            "the seeded targets do not span the face in 3-D: seed targets at different depths"
                .into(),
        )
    })?;
    let mut stations = Vec::with_capacity(views.len());
    for (v, view) in views.iter().enumerate() {
        let mut matched = Vec::new();
        let mut ambiguous: BTreeSet<usize> = matching.ambiguous[v].iter().copied().collect();
        let mut in_track = BTreeSet::new();
        for (k, t) in tracks.iter().enumerate() {
            let Some(j) = t.blobs[v] else { continue };
            in_track.insert(j);
            match named.names[k] {
                Some(a) => matched.push(Identified {
                    point: names[a].clone(),
                    blob: j,
                    x_mm: view.blobs_mm[j][0],
                    y_mm: view.blobs_mm[j][1],
                    offset_mm: t.misfit_mm,
                }),
                None => {
                    ambiguous.insert(j);
                }
            }
        }
        matched.sort_by(|a, b| a.point.cmp(&b.point));
        let unmatched = (0..view.blobs_mm.len())
            .filter(|j| !in_track.contains(j) && !ambiguous.contains(j))
            .collect();
        stations.push(StationNames {
            station: view.station.to_string(),
            detected: view.blobs_mm.len(),
            matched,
            ambiguous_blobs: ambiguous.into_iter().collect(),
            unmatched_blobs: unmatched,
        });
    }
    Ok(FirstEpoch {
        stations,
        tracks: tracks.len(),
        named: named
            .names
            .iter()
            .flatten()
            .map(|a| names[*a].clone())
            .collect(),
        ambiguous: named
            .ambiguous
            .iter()
            .map(|a| (names[a.best].clone(), names[a.rival].clone()))
            .collect(),
        approx_sigma_m: named.sigma_m,
        spacing_m: named.spacing_m,
        max_sigma_m: named.max_sigma_m,
        camera_misfit_mm: misfit_mm,
    })
}
