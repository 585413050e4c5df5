//! Typed errors of detection.

/// Why an image could not be decoded or searched for targets.
#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    /// The bytes are not a readable JPEG, PNG or TIFF image.
    #[error("cannot decode image: {0}")]
    Decode(String),
    /// The file ends before its image does (a JPEG without its end-of-image marker): a decoder
    /// would fill the rest with grey and report the targets of the part that arrived.
    #[error("truncated {format} file: the data ends before the image does")]
    Truncated {
        /// The file format.
        format: &'static str,
    },
    /// The image has no pixels.
    #[error("image is empty ({width}×{height} px)")]
    Empty {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// The image is too small to hold a target with the background around it.
    #[error(
        "image of {width}×{height} px is too small to hold a target (at least {min}×{min} px)"
    )]
    TooSmall {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// The least width and height (`detect::MIN_IMAGE_SIDE_PX`).
        min: u32,
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
