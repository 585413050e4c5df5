//! Start values from four known points per image, no camera positions or angles needed:
//! [`affine`] resection and intersection (eqs 1, 5, 10–14), then `start_values` refines each
//! image with the closed-form perspective model and intersects the rays of every other point.

pub mod affine;
pub(crate) mod start_values;
