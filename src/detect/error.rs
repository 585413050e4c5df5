//! Typed errors of detection.

/// Why an image could not be decoded or searched for targets.
#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    /// The bytes are not a readable JPEG, PNG or TIFF image.
    #[error("cannot decode image: {0}")]
    Decode(String),
    /// The image has no pixels.
    #[error("image is empty ({width}×{height} px)")]
    Empty {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// The image exceeds the pixel limit.
    #[error("image too large: {width}×{height} px exceeds {max_pixels} px")]
    TooLarge {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// The limit in pixels.
        max_pixels: u64,
    },
    /// The pixel buffer does not match the stated size.
    #[error("buffer of {len} values does not match {width}×{height} px")]
    BadBuffer {
        /// Buffer length.
        len: usize,
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// An option is out of range.
    #[error("invalid detection option: {0}")]
    InvalidOptions(String),
    /// The image holds far more bright (or dark) blobs than a photograph of targets can: noise,
    /// texture or a crafted file. Refused before the work grows with their number.
    #[error("{found} {what} above the threshold, more than the {limit} a target image can hold (noise, texture or a wrong polarity)")]
    TooManyBlobs {
        /// What was counted: "runs" (row segments) or "blobs" (candidate targets).
        what: &'static str,
        /// How many were found (at least).
        found: usize,
        /// The limit.
        limit: usize,
    },
}
