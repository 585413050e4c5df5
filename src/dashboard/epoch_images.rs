//! The images of an epoch taken from the watched directory, with the detected targets drawn over
//! them: on the epoch page each station's preview (a lazily loaded JPEG) under an SVG of circles,
//! coloured by how the target was identified and labelled with the point's name; and
//! `GET /sites/{site}/epochs/{epoch}/images/{station}`, the preview itself, made on request from
//! the image kept in `<watch_dir>/<site>/.done/<folder>/` ([`super::image_preview`], in
//! `spawn_blocking`).
//!
//! The report's `identification` (written by [`crate::watch`]) names the folder, the file, the
//! image size and every detection; nothing else of the request reaches the file system.

use std::path::PathBuf;

use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use maud::{html, Markup};
use serde_json::Value;

use super::image_preview::{preview, PREVIEW_MAX_SIDE};
use super::layout::seg;
use super::page::PageError;
use crate::http::AppState;
use crate::store::epoch_report::EpochReport;
use crate::watch::image_file::{read_image_file, ImageFileError};

/// One station of a watched epoch as its report keeps it.
#[derive(Debug, Clone, PartialEq)]
pub struct StationImage {
    /// Station id.
    pub station: String,
    /// The folder relative to the site's directory (`.done/<name>`).
    pub folder: String,
    /// The image's file name.
    pub image: String,
    /// Image size in px.
    pub width_px: u32,
    /// Image height in px.
    pub height_px: u32,
    /// Counts: detected, identified, ambiguous, unmatched.
    pub counts: [u64; 4],
    /// Detections: (col, row, diameter px, point, status).
    pub targets: Vec<(f64, f64, f64, Option<String>, String)>,
}

impl StationImage {
    /// Reads a station entry of the report's `identification`; `None` for entries without an image
    /// (reports from before images were kept) or with a folder or file name that is not one plain
    /// path component under `.done/`.
    pub fn from_report(v: &Value) -> Option<StationImage> {
        let s = |k: &str| v.get(k).and_then(Value::as_str).map(str::to_string);
        let folder = s("folder")?;
        let image = s("image")?;
        let name = folder.strip_prefix(".done/")?;
        if !plain_component(name) || !plain_component(&image) {
            return None;
        }
        let u = |k: &str| v.get(k).and_then(Value::as_u64);
        let targets = v
            .get("targets")?
            .as_array()?
            .iter()
            .filter_map(|t| {
                let f = |k: &str| t.get(k).and_then(Value::as_f64);
                Some((
                    f("col")?,
                    f("row")?,
                    f("diameter_px").unwrap_or(8.0),
                    t.get("point").and_then(Value::as_str).map(str::to_string),
                    t.get("status")
                        .and_then(Value::as_str)
                        .unwrap_or("unmatched")
                        .to_string(),
                ))
            })
            .collect();
        Some(StationImage {
            station: s("station")?,
            folder,
            image,
            width_px: u32::try_from(u("width_px")?).ok()?.max(1),
            height_px: u32::try_from(u("height_px")?).ok()?.max(1),
            counts: [
                u("detected").unwrap_or(0),
                u("identified").unwrap_or(0),
                u("ambiguous").unwrap_or(0),
                u("unmatched").unwrap_or(0),
            ],
            targets,
        })
    }

    /// The image file under `watch_dir`, when the site id is a plain directory name.
    fn path(&self, watch_dir: &std::path::Path, site: &str) -> Option<PathBuf> {
        plain_component(site).then(|| watch_dir.join(site).join(&self.folder).join(&self.image))
    }
}

/// A file or directory name that stays where it is put: not empty, no separator, not starting with
/// a dot (so neither `.` nor `..`).
fn plain_component(s: &str) -> bool {
    !s.is_empty() && !s.starts_with('.') && !s.contains(['/', '\\', '\0'])
}

/// The stations of a report that have an image.
pub fn stations(report: &EpochReport) -> Vec<StationImage> {
    report
        .identification
        .as_deref()
        .map(|a| a.iter().filter_map(StationImage::from_report).collect())
        .unwrap_or_default()
}

/// Whether the image of `st` is still in the watched directory.
pub fn available(state: &AppState, site: &str, st: &StationImage) -> bool {
    state
        .config
        .watch_dir
        .as_deref()
        .and_then(|d| st.path(d, site))
        .is_some_and(|p| p.is_file())
}

/// The station's figure: the preview with the detections drawn over it (circles: identified green
/// and labelled, ambiguous orange, unmatched red), or the detections alone on a dark ground when
/// the image is no longer in the watched directory.
pub fn station_figure(site: &str, epoch: i64, st: &StationImage, image_available: bool) -> Markup {
    let (w, h) = (st.width_px as f64, st.height_px as f64);
    let r_min = w.max(h) / 250.0;
    let font = w.max(h) / 90.0;
    let url = format!(
        "/sites/{}/epochs/{epoch}/images/{}",
        seg(site),
        seg(&st.station)
    );
    let [detected, identified, ambiguous, unmatched] = st.counts;
    html! {
        figure.station-image {
            figcaption {
                strong { "station " (st.station) } ": " (detected) " detected, "
                span.identified { (identified) " identified" } ", "
                span.ambiguous { (ambiguous) " ambiguous" } ", "
                span.unmatched { (unmatched) " unmatched" }
                @if !image_available { " · the image is no longer in the watched directory" }
            }
            div.overlay style=(format!("aspect-ratio: {} / {}", st.width_px, st.height_px)) {
                @if image_available {
                    img src=(url) loading="lazy" alt=(format!("image of station {}", st.station));
                }
                svg viewBox=(format!("0 0 {w} {h}")) preserveAspectRatio="none" xmlns="http://www.w3.org/2000/svg" {
                    @for (col, row, d, point, status) in &st.targets {
                        @let r = (0.9 * d).max(r_min);
                        circle class=(format!("target {status}")) cx=(format!("{col:.1}")) cy=(format!("{row:.1}")) r=(format!("{r:.1}")) {
                            title { (point.as_deref().unwrap_or(status)) " (" (format!("{col:.2}")) ", " (format!("{row:.2}")) " px)" }
                        }
                        @if let Some(p) = point {
                            text x=(format!("{:.1}", col + r + 0.3 * font)) y=(format!("{:.1}", row + 0.35 * font)) font-size=(format!("{font:.1}")) { (p) }
                        }
                    }
                }
            }
        }
    }
}

/// `GET /sites/{site}/epochs/{epoch}/images/{station}`: the station's preview as JPEG (longer side
/// ≤ 1280 px), cached by the browser for a day (an epoch's images do not change). 404 when the
/// site, epoch or station is unknown, the epoch did not come from the watched directory, or the
/// image has left it.
pub async fn image(
    State(state): State<AppState>,
    Path((site_id, epoch, station)): Path<(String, String, String)>,
) -> Result<Response, PageError> {
    let (site, id, _, report) =
        super::page::load_epoch(state.store.reader(), &site_id, &epoch).await?;
    let Some(st) = stations(&report).into_iter().find(|s| s.station == station) else {
        return Err(PageError::not_found(format!(
            "epoch {id} has no image of station '{station}' from the watched directory"
        )));
    };
    let path = state
        .config
        .watch_dir
        .as_deref()
        .and_then(|d| st.path(d, &site.id))
        .filter(|p| p.is_file())
        .ok_or_else(|| {
            PageError::not_found(format!(
                "the image of station '{station}' is no longer in the watched directory"
            ))
        })?;
    let bytes = read_image_file(&path).await.map_err(|e| match e {
        ImageFileError::TooLarge { .. } => PageError::not_found(format!(
            "the image of station '{station}' is too large to show"
        )),
        ImageFileError::Io(e) => {
            tracing::warn!(path = %path.display(), error = %e, "dashboard: image unreadable");
            PageError::not_found(format!("the image of station '{station}' cannot be read"))
        }
    })?;
    let made = tokio::task::spawn_blocking(move || preview(&bytes, PREVIEW_MAX_SIDE))
        .await
        .map_err(|e| PageError::internal(format!("preview task failed: {e}")))?
        .map_err(|e| PageError::internal(format!("station '{station}': {e}")))?;
    Ok((
        [
            (header::CONTENT_TYPE, "image/jpeg"),
            (header::CACHE_CONTROL, "private, max-age=86400"),
        ],
        made.jpeg,
    )
        .into_response())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn entry(folder: &str, image: &str) -> Value {
        json!({"station": "S1", "method": "seeds", "detected": 3, "identified": 1, "ambiguous": 1,
               "unmatched": 1, "folder": folder, "image": image, "width_px": 2160, "height_px": 1440,
               "targets": [{"col": 10.5, "row": 20.25, "diameter_px": 7.0, "point": "T<1>", "status": "identified"},
                           {"col": 30.0, "row": 40.0, "diameter_px": 7.0, "status": "ambiguous"},
                           {"col": 50.0, "row": 60.0, "diameter_px": 7.0, "status": "unmatched"}]})
    }

    /// Only a plain folder under `.done/` and a plain file name are accepted.
    #[test]
    fn paths_outside_the_done_folder_are_refused() {
        assert!(StationImage::from_report(&entry(".done/e1", "S1.png")).is_some());
        for (folder, image) in [
            (".done/..", "S1.png"),
            (".done/../../etc", "passwd"),
            (".done/e1/x", "S1.png"),
            ("e1", "S1.png"),
            (".failed/e1", "S1.png"),
            (".done/e1", "../S1.png"),
            (".done/e1", ".hidden"),
            (".done/e1", "a\\b.png"),
        ] {
            assert!(
                StationImage::from_report(&entry(folder, image)).is_none(),
                "{folder} {image}"
            );
        }
        let st = StationImage::from_report(&entry(".done/e1", "S1.png")).unwrap();
        assert!(st.path(std::path::Path::new("/w"), "..").is_none());
        assert_eq!(
            st.path(std::path::Path::new("/w"), "kamo").unwrap(),
            PathBuf::from("/w/kamo/.done/e1/S1.png")
        );
    }

    /// The figure draws one circle per detection, labels only the identified ones (escaped), and
    /// links the preview only when the image is there.
    #[test]
    fn figure_marks_every_detection() {
        let st = StationImage::from_report(&entry(".done/e1", "S1.png")).unwrap();
        let html = station_figure("kamo", 3, &st, true).into_string();
        assert_eq!(html.matches("<circle").count(), 3, "{html}");
        assert_eq!(html.matches("<text").count(), 1, "{html}");
        assert!(html.contains("T&lt;1&gt;"), "{html}");
        assert!(html.contains("class=\"target ambiguous\""), "{html}");
        assert!(
            html.contains("src=\"/sites/kamo/epochs/3/images/S1\""),
            "{html}"
        );
        assert!(html.contains("viewBox=\"0 0 2160 1440\""), "{html}");
        let gone = station_figure("kamo", 3, &st, false).into_string();
        assert!(!gone.contains("<img"), "{gone}");
        assert!(
            gone.contains("no longer in the watched directory"),
            "{gone}"
        );
    }
}
