//! The upload form of an epoch: [`epoch`] checks it and builds the problem the adjustment solves;
//! [`epoch_csv`] reads the same from CSV; [`plausible`] checks its units by orders of magnitude.

pub mod epoch;
pub mod epoch_csv;
pub mod plausible;
