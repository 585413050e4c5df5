//! Which detected target is which point, in every station of a folder.

use std::collections::BTreeMap;

use super::stations::{StationCounts, StationData, StationNamed};
use super::{WatchError, WatchOptions};
use cliffwatch_core::detect::convergent::{identify_convergent, ConvergentOptions, ConvergentSite};
use cliffwatch_core::detect::first_epoch::{identify_first_epoch, FirstEpochError, StationView};
use cliffwatch_core::detect::identify::{identify, Prior};
use cliffwatch_core::photogrammetry::ImageOrientation;

/// What a refusal of the affine identification adds: the set-up it assumes, and the way out.
const AFFINE_HINT: &str = " This site is on the orthogonal model, whose first epoch is matched \
     through affine cameras: that holds for long-range, near-parallel views. If the stations are \
     near the targets or view them convergently or rolled, put the site on the central model \
     (\"model\": \"central\"): its first epoch is then identified through collinearity and the \
     camera's self-calibrating adjustment.";

/// Names the detections of every station: stations with ≥ 4 seeds together when there are at least
/// 2 of them — on a site of the central model (`central` given) through its self-calibrating
/// adjustment ([`identify_convergent`]), else by affine multi-view matching
/// ([`identify_first_epoch`]) when they share 4 seeded targets — otherwise each from its seeds;
/// stations without seeds from their previous orientation. Returns per station the (point,
/// detection index) pairs and the counts.
pub(super) fn name_targets(
    stations: &[StationData],
    known: &BTreeMap<String, [f64; 3]>,
    previous: &BTreeMap<String, ImageOrientation>,
    central: Option<&ConvergentSite<'_>>,
    opts: &WatchOptions,
) -> Result<(Vec<StationNamed>, Vec<StationCounts>), WatchError> {
    let mut names: Vec<StationNamed> = vec![Vec::new(); stations.len()];
    let mut counts: Vec<Option<StationCounts>> = vec![None; stations.len()];
    let seeded: Vec<usize> = (0..stations.len())
        .filter(|&k| stations[k].seeds.len() >= 4)
        .collect();
    if seeded.len() >= 2 {
        let views: Vec<StationView> = seeded
            .iter()
            .map(|&k| StationView {
                station: &stations[k].station,
                blobs_mm: &stations[k].blobs,
                seeds: &stations[k].seeds,
            })
            .collect();
        let (identified, method) = match central {
            Some(site) => {
                let cameras: Vec<_> = seeded.iter().map(|&k| &stations[k].camera).collect();
                let convergent = ConvergentOptions {
                    seed_snap_mm: opts.first_epoch.seed_snap_mm,
                    ..ConvergentOptions::default()
                };
                (
                    identify_convergent(&views, &cameras, known, site, &convergent),
                    "central model from seeds",
                )
            }
            None => (
                identify_first_epoch(&views, known, &opts.first_epoch),
                "multi-view from seeds",
            ),
        };
        match identified {
            Ok(first) => {
                if let Some(mut msg) = first.refusal() {
                    if central.is_none() {
                        msg.push_str(AFFINE_HINT);
                    }
                    return Err(WatchError::Unidentified(msg));
                }
                for (r, &k) in first.stations.iter().zip(&seeded) {
                    names[k] = r
                        .matched
                        .iter()
                        .map(|m| (m.point.clone(), m.blob))
                        .collect();
                    counts[k] = Some(StationCounts::new(
                        &stations[k],
                        method,
                        &names[k],
                        &r.ambiguous_blobs,
                        &r.unmatched_blobs,
                    ));
                }
            }
            Err(FirstEpochError::TooFewCommonSeeds { .. }) => {
                tracing::info!(
                    "stations seed different targets; each is identified from its own seeds"
                );
            }
            Err(e) => return Err(WatchError::FirstEpoch(e)),
        }
    }
    for (k, s) in stations.iter().enumerate() {
        if counts[k].is_some() {
            continue;
        }
        let (prior, method) = if s.seeds.len() >= 4 {
            (Prior::Seeds(&s.seeds), "seeds")
        } else if let Some(o) = previous.get(&s.station) {
            (Prior::Orientation(o), "previous orientation")
        } else {
            return Err(WatchError::NoPrior(s.station.clone()));
        };
        let id = identify(&s.blobs, known, &s.camera, prior, &opts.identify).map_err(|source| {
            WatchError::Identify {
                station: s.station.clone(),
                source,
            }
        })?;
        names[k] = id
            .matched
            .iter()
            .map(|m| (m.point.clone(), m.blob))
            .collect();
        counts[k] = Some(StationCounts::new(
            s,
            method,
            &names[k],
            &id.ambiguous_blobs,
            &id.unmatched_blobs,
        ));
    }
    let mut counts: Vec<StationCounts> = counts.into_iter().flatten().collect();
    if let Some(msg) = lost_orientations(&counts) {
        return Err(WatchError::Unidentified(msg));
    }
    leave_out_single_views(&mut names, &mut counts);
    Ok((names, counts))
}

/// Leaves out the points named in one station only (a target the other cameras no longer see
/// after a re-aim): one ray cannot place them. Each station's counts list those it named.
fn leave_out_single_views(names: &mut [StationNamed], counts: &mut [StationCounts]) {
    let mut stations_of: BTreeMap<String, usize> = BTreeMap::new();
    for named in names.iter() {
        for (p, _) in named {
            *stations_of.entry(p.clone()).or_default() += 1;
        }
    }
    for (named, c) in names.iter_mut().zip(counts.iter_mut()) {
        let (single, kept): (StationNamed, StationNamed) =
            named.drain(..).partition(|(p, _)| stations_of[p] < 2);
        *named = kept;
        c.in_one_station_only = single.into_iter().map(|(p, _)| p).collect();
        if !c.in_one_station_only.is_empty() {
            tracing::info!(
                station = c.station,
                points = ?c.in_one_station_only,
                "named in this station only: left out of the epoch"
            );
        }
    }
}

/// Fewest targets a station must name from its previous orientation; fewer means the camera no
/// longer stands or points where it did.
const MIN_NAMED: usize = 4;

/// The refusal when stations named from their previous orientation found almost none of their
/// targets: names the stations and what to add.
fn lost_orientations(counts: &[StationCounts]) -> Option<String> {
    let lost: Vec<String> = counts
        .iter()
        .filter(|c| {
            c.method == "previous orientation"
                && c.identified < MIN_NAMED
                && c.detected >= MIN_NAMED
        })
        .map(|c| {
            format!(
                "{} ({} of {} detected targets named)",
                c.station, c.identified, c.detected
            )
        })
        .collect();
    (!lost.is_empty()).then(|| {
        format!(
            "stations {} could not be identified from their orientation of the previous epoch: \
             the camera was probably set up again or re-aimed. In epoch.json, give each of these \
             stations at least {MIN_NAMED} seed observations (point with col and row) of targets \
             spread over the face.",
            lost.join(", ")
        )
    })
}
