//! What steers one adjustment: the projection model, prior coordinates, which joint covariance
//! to return, and the data snooping and iteration settings (COLMAP's `BundleAdjustmentOptions`).

use super::cancel::Cancel;
use crate::photogrammetry::input::epoch::PriorCoordinates;
use crate::photogrammetry::model::Model;

/// Options of one adjustment.
#[derive(Debug, Clone)]
pub struct AdjustOptions {
    /// Projection model.
    pub model: Model,
    /// Coordinates (m, site frame) of points from earlier epochs: start values where the epoch has no
    /// `approx`/`control` for a point.
    pub prior: PriorCoordinates,
    /// Points whose joint 3n × 3n covariance is wanted (e.g. the site's stable points).
    pub joint_covariance_of: Vec<String>,
    /// Run data snooping (Baarda, |w| > `critical_w`, one observation at a time). Without it every
    /// observation is kept; those beyond `critical_w` are named in a warning, and a solution that
    /// fails the global test with more than a tenth of them is refused as inconsistent, as with it.
    pub snooping: bool,
    /// Critical value of the normalized residual w.
    pub critical_w: f64,
    /// Iteration limit of one Levenberg–Marquardt run.
    pub max_iterations: usize,
    /// With the central model: adjust the orthogonal model first and start collinearity from its
    /// solution (default). Off, collinearity starts from the start values directly (model comparisons).
    pub central_from_orthogonal: bool,
    /// Report each camera's variance component (its share of vᵀPv and of the redundancy; one
    /// more pass over the observations' cofactors).
    pub variance_components: bool,
    /// Scale the covariances and the calibrated parameters' σ by the a-priori variance (variance
    /// factor 1) rather than the a-posteriori one: the pre-analysis of a planned network, whose
    /// noise-free image coordinates leave zero residuals (`photogrammetry::plan`). Off by default.
    pub apriori_precision: bool,
    /// Return the design statistics ([`Adjustment::design`](crate::photogrammetry::Adjustment)):
    /// each image coordinate's redundancy number and the self-calibrated parameters'
    /// correlations (one more pass over the observations' cofactors). Off by default.
    pub design_statistics: bool,
    /// Stops the adjustment early (at its next iteration) when cancelled or past its deadline;
    /// never by default.
    pub cancel: Cancel,
}

impl Default for AdjustOptions {
    fn default() -> Self {
        AdjustOptions {
            model: Model::Orthogonal,
            prior: PriorCoordinates::new(),
            joint_covariance_of: Vec::new(),
            snooping: true,
            critical_w: 3.29,
            max_iterations: 100,
            central_from_orthogonal: true,
            variance_components: false,
            apriori_precision: false,
            design_statistics: false,
            cancel: Cancel::default(),
        }
    }
}
