//! Pure displacement analysis and alert rules (to be written).
