//! Grey pictures (masks, textures, silhouettes) read from PGM or PNG files.

use std::path::{Path, PathBuf};

/// A 16-bit grey picture.
pub type Gray16 = image::ImageBuffer<image::Luma<u16>, Vec<u16>>;

/// A picture that could not be read, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file cannot be opened or its format sniffed.
    #[error("{}: {source}", path.display())]
    Open {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not a picture this reader decodes.
    #[error("{}: not a readable PGM or PNG image: {source}", path.display())]
    Decode {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
}

/// 16-bit samples of `bits` significant bits as 8-bit grey (the top 8
/// bits, saturating), into `dst` (as many as both hold).
pub fn gray8_from_u16(src: &[u16], bits: u8, dst: &mut [u8]) {
    let shift = bits.saturating_sub(8).min(8);
    for (d, &s) in dst.iter_mut().zip(src) {
        *d = (s >> shift).min(255) as u8;
    }
}

/// A PGM (P2 or P5, 8 or 16 bit) or PNG picture as 16-bit grey.
pub fn read_gray16(path: &Path) -> Result<Gray16, ImageError> {
    let bytes = std::fs::read(path).map_err(|source| ImageError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    decode_gray16(&bytes, path)
}

/// [`read_gray16`] of a picture's bytes; `path` names them in errors.
pub fn decode_gray16(bytes: &[u8], path: &Path) -> Result<Gray16, ImageError> {
    Ok(image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|source| ImageError::Open {
            path: path.to_path_buf(),
            source,
        })?
        .decode()
        .map_err(|source| ImageError::Decode {
            path: path.to_path_buf(),
            source,
        })?
        .into_luma16())
}
