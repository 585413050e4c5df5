//! The adjustments' health on the site page (issue 61, item 8; a pure renderer): each epoch's
//! variance factor against the global test's acceptance band, and when the test failed on most
//! of the recent epochs, a sentence that says so with the cameras' a-priori σ estimated from
//! their variance components ([`cliffwatch_core::photogrammetry::statistics::variance_components`]) and
//! whether the site applies it.

use maud::{html, Markup};

use super::layout::num;
use crate::store::epochs::EpochListItem;
use crate::store::sites::AprioriSigma;
use cliffwatch_core::photogrammetry::statistics::variance_components::PooledSigma;
use cliffwatch_core::photogrammetry::statistics::GlobalTest;

/// The recent epochs the verdict reads.
pub const RECENT: usize = 10;

const W: f64 = 640.0;
const H: f64 = 150.0;
const PAD: f64 = 34.0;

/// What the health section shows.
pub struct Health<'a> {
    /// Epochs newest first (those with a variance factor are drawn).
    pub epochs: &'a [EpochListItem],
    /// The cameras' σ pooled from the recent epochs' variance components.
    pub estimate: &'a [PooledSigma],
    /// The σ each camera used at the latest epoch (camera, mm).
    pub used: &'a [(String, f64)],
    /// The site's setting.
    pub setting: AprioriSigma,
    /// The estimate is a first step ([`crate::service::apriori_sigma::SiteSigma::first_step`]).
    pub first_step: bool,
}

/// The global tests of the epochs that report a variance factor, newest first.
fn tests(epochs: &[EpochListItem]) -> Vec<(&EpochListItem, GlobalTest)> {
    epochs
        .iter()
        .filter_map(|e| Some((e, GlobalTest::of(e.dof?, e.variance_factor?))))
        .collect()
}

/// The section: the series, and the verdict on the last [`RECENT`] epochs.
pub fn section(h: &Health<'_>) -> Markup {
    let tested = tests(h.epochs);
    let recent: Vec<&GlobalTest> = tested.iter().take(RECENT).map(|(_, t)| t).collect();
    let failed: Vec<&&GlobalTest> = recent.iter().filter(|t| !t.accepted).collect();
    let most_fail = recent.len() >= 3 && 2 * failed.len() > recent.len();
    let high = failed
        .iter()
        .filter(|t| t.variance_factor > t.upper)
        .count();
    html! {
        section #health {
            h2 { "Adjustment health" }
            @if tested.is_empty() {
                p.note { "No epoch reports its variance factor yet." }
            } @else {
                p.verdict.(if most_fail { "failing" } else { "passing" }) {
                    @if most_fail {
                        strong { "The global test failed on " (failed.len()) " of the last " (recent.len()) " epochs" }
                        " (variance factor " (range(failed.iter().map(|t| t.variance_factor))) "; it passes within "
                        (num(Some(recent[0].lower), 2)) "–" (num(Some(recent[0].upper), 2)) "): "
                        @if 2 * high >= failed.len() { "the a-priori σ of the images is too optimistic, or a model error remains." }
                        @else { "the a-priori σ of the images is too pessimistic." }
                    } @else {
                        "The global test passed on " (recent.len() - failed.len()) " of the last " (recent.len()) " epochs."
                    }
                }
                @if !h.estimate.is_empty() && (most_fail || h.setting == AprioriSigma::Estimated) {
                    p.estimate {
                        "A-priori σ of an image coordinate estimated from the variance components of the last "
                        (h.estimate.iter().map(|e| e.epochs).max().unwrap_or(0)) " epochs: "
                        @for (i, e) in h.estimate.iter().enumerate() {
                            @if i > 0 { "; " }
                            "camera " (e.camera) " " (num(Some(e.sigma_mm * 1000.0), 2)) " µm ± " (num(Some(100.0 * e.relative_sigma), 1)) " %"
                            @if let Some((_, u)) = h.used.iter().find(|(c, _)| *c == e.camera) { " (used at the last epoch: " (num(Some(u * 1000.0), 2)) " µm)" }
                        }
                        ". "
                        @if h.first_step {
                            "This is a first step: the σ used weights the cameras in another ratio, which shifts part of one camera's noise onto the others, so each value may be off by more than its ±. Applied, the estimate converges over the next epochs. "
                        }
                        @match h.setting {
                            AprioriSigma::Estimated => { "The site applies it to its next epochs (" code { "apriori_sigma: estimated" } ")." },
                            AprioriSigma::Upload => { "The site uses the uploaded σ; set its " code { "apriori_sigma" } " to " code { "estimated" } " to apply the estimate to the next epochs." },
                        }
                    }
                }
                (plot(&tested))
            }
        }
    }
}

/// The date part of a displayed time ("2026-11-20" of "2026-11-20T09:00:00Z").
fn date_of(t: &str) -> &str {
    t.get(..10).unwrap_or(t)
}

/// "1.41–1.96" (or one value).
fn range(values: impl Iterator<Item = f64>) -> String {
    let (lo, hi) = values.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if (hi - lo).abs() < 0.005 {
        format!("{lo:.2}")
    } else {
        format!("{lo:.2}–{hi:.2}")
    }
}

/// The variance factors oldest to newest, epoch by epoch, the acceptance band shaded.
fn plot(tested: &[(&EpochListItem, GlobalTest)]) -> Markup {
    let pts: Vec<&(&EpochListItem, GlobalTest)> = tested.iter().rev().collect();
    let n = pts.len();
    let y_max = pts
        .iter()
        .map(|(_, t)| t.variance_factor.max(t.upper))
        .fold(1.0f64, f64::max)
        * 1.1;
    let sx = |i: usize| {
        if n > 1 {
            PAD + (W - 2.0 * PAD) * i as f64 / (n - 1) as f64
        } else {
            W / 2.0
        }
    };
    let sy = |v: f64| H - PAD + (PAD * 2.0 - H) * (v / y_max);
    let upper: Vec<String> = pts
        .iter()
        .enumerate()
        .map(|(i, (_, t))| format!("{:.1},{:.1}", sx(i), sy(t.upper)))
        .collect();
    let lower: Vec<String> = pts
        .iter()
        .enumerate()
        .rev()
        .map(|(i, (_, t))| format!("{:.1},{:.1}", sx(i), sy(t.lower)))
        .collect();
    let band = format!("{} {}", upper.join(" "), lower.join(" "));
    html! {
        figure.health {
            svg.health viewBox={ "0 0 " (W) " " (H) } role="img" aria-label="variance factor per epoch" xmlns="http://www.w3.org/2000/svg" {
                polygon.band points=(band) {}
                line.axis x1=(PAD) y1=(format!("{:.1}", sy(0.0))) x2=(W - PAD) y2=(format!("{:.1}", sy(0.0))) {}
                line.one x1=(PAD) y1=(format!("{:.1}", sy(1.0))) x2=(W - PAD) y2=(format!("{:.1}", sy(1.0))) {}
                text.tick x="2" y=(format!("{:.1}", sy(0.0) + 5.0)) { "0" }
                text.tick x="2" y=(format!("{:.1}", sy(1.0) + 5.0)) { "1.0" }
                @if y_max / 1.1 > 1.4 {
                    text.tick x="2" y=(format!("{:.1}", sy(y_max / 1.1) + 5.0)) { (num(Some(y_max / 1.1), 1)) }
                }
                @if let (Some((first, _)), Some((last, _))) = (pts.first(), pts.last()) {
                    text.tick x=(PAD) y=(H - 6.0) { (date_of(&first.observed_at)) }
                    @if n > 1 {
                        text.tick x=(W - PAD) y=(H - 6.0) text-anchor="end" { (date_of(&last.observed_at)) }
                    }
                }
                @for (i, (e, t)) in pts.iter().enumerate() {
                    circle class={ "vf " (if t.accepted { "passed" } else { "failed" }) } cx=(format!("{:.1}", sx(i))) cy=(format!("{:.1}", sy(t.variance_factor))) r="3" {
                        title { (e.observed_at) ": variance factor " (num(Some(t.variance_factor), 2)) (if t.accepted { ", passed" } else { ", failed" }) }
                    }
                }
            }
            figcaption {
                ul.legend {
                    li { span.swatch.band {} "the global test's acceptance band (" (num(Some(100.0 * tested[0].1.confidence), 1)) " %)" }
                    li { span.dot.passed {} "passed" }
                    li { span.dot.failed {} "failed" }
                    li { "variance factor (σ̂0 / a-priori σ)² of each epoch, oldest left; the last " (n) " epochs" }
                }
            }
        }
    }
}
