//! Which detected target is which point, in every station of a folder.

use std::collections::BTreeMap;

use super::stations::{StationCounts, StationData, StationNamed};
use super::{WatchError, WatchOptions};
use crate::detect::first_epoch::{identify_first_epoch, FirstEpochError, StationView};
use crate::detect::identify::{identify, Prior};
use crate::photogrammetry::ImageOrientation;

/// Names the detections of every station: stations with ≥ 4 seeds together by multi-view matching
/// ([`identify_first_epoch`]) when there are at least 2 of them and they share 4 seeded targets,
/// otherwise each from its seeds; stations without seeds from their previous orientation. Returns
/// per station the (point, detection index) pairs and the counts.
pub(super) fn name_targets(
    stations: &[StationData],
    known: &BTreeMap<String, [f64; 3]>,
    previous: &BTreeMap<String, ImageOrientation>,
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
        match identify_first_epoch(&views, known, &opts.first_epoch) {
            Ok(first) => {
                if let Some(msg) = first.refusal() {
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
                        "multi-view from seeds",
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
    Ok((names, counts.into_iter().flatten().collect()))
}
