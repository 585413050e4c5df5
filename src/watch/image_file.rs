//! Reading a station's image file whole, within [`MAX_IMAGE_FILE_BYTES`]: for detection (the
//! watcher) and for the dashboard's preview. The limit is checked before reading and held while
//! reading, so a file that grows in between is refused too. A link, a file with several hard links
//! and a special file are refused unread ([`super::inside::open_inside`]).

use std::path::Path;

use tokio::io::AsyncReadExt;

use cliffwatch_core::detect::MAX_IMAGE_FILE_BYTES;

/// Why an image file was not read.
#[derive(Debug, thiserror::Error)]
pub enum ImageFileError {
    /// The file is larger than [`MAX_IMAGE_FILE_BYTES`] (`bytes`: its size, or what was read
    /// before the limit was passed).
    #[error("{bytes} bytes, more than the {max} bytes an image file may have")]
    TooLarge {
        /// Size in bytes.
        bytes: u64,
        /// The limit in bytes.
        max: u64,
    },
    /// The file cannot be opened or read.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// The bytes of the image file at `path`, when it has at most [`MAX_IMAGE_FILE_BYTES`].
pub async fn read_image_file(path: &Path) -> Result<Vec<u8>, ImageFileError> {
    let max = MAX_IMAGE_FILE_BYTES;
    let to_open = path.to_path_buf();
    let file = tokio::task::spawn_blocking(move || super::inside::open_inside(&to_open))
        .await
        .map_err(std::io::Error::other)??;
    let file = tokio::fs::File::from_std(file);
    let size = file.metadata().await?.len();
    if size > max {
        return Err(ImageFileError::TooLarge { bytes: size, max });
    }
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(max + 1).read_to_end(&mut bytes).await?;
    if bytes.len() as u64 > max {
        return Err(ImageFileError::TooLarge {
            bytes: bytes.len() as u64,
            max,
        });
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn reads_a_small_file_and_refuses_a_sparse_giant_unread() {
        let dir = tempfile::tempdir().unwrap();
        let small = dir.path().join("a.png");
        std::fs::write(&small, b"abc").unwrap();
        assert_eq!(read_image_file(&small).await.unwrap(), b"abc");
        let giant = dir.path().join("b.png");
        let f = std::fs::File::create(&giant).unwrap();
        f.set_len(MAX_IMAGE_FILE_BYTES + 1).unwrap();
        match read_image_file(&giant).await {
            Err(ImageFileError::TooLarge { bytes, max }) => {
                assert_eq!(
                    (bytes, max),
                    (MAX_IMAGE_FILE_BYTES + 1, MAX_IMAGE_FILE_BYTES)
                )
            }
            other => panic!("{other:?}"),
        }
        let missing = dir.path().join("c.png");
        assert!(matches!(
            read_image_file(&missing).await,
            Err(ImageFileError::Io(_))
        ));
    }
}
