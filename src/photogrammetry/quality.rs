//! Quality indexes of the paper (§4.1) (to be written).
