//! Encoded images to the 8-bit grey images the tag detector takes: image files (PNG, JPEG,
//! PGM/PPM) and the JPEG or PNG data of a bag's `CompressedImage`, decoded by the `image` crate
//! in the same way, so that the same picture gives the same grey pixels whichever way it came.
//! A JPEG cut short (no end-of-image marker) is refused rather than decoded half grey. The raw
//! pixel layouts of a bag's `sensor_msgs/Image` are converted by `io::bag::image`.

use std::io::Cursor;
use std::path::Path;

use ::image::{GrayImage, ImageFormat, ImageReader, Limits};

use crate::error::{Error, Result};

/// The largest image width or height accepted from a bag's messages, in pixels.
pub const MAX_SIDE: u32 = 20_000;

/// The first bytes of a JPEG file.
const JPEG_MAGIC: &[u8] = &[0xFF, 0xD8, 0xFF];
/// The first bytes of a PNG file.
const PNG_MAGIC: &[u8] = b"\x89PNG\r\n\x1a\n";

/// Reads an image file (PNG, JPEG, PGM/PPM; the format is guessed from the content) as 8-bit grey.
/// Colour images are converted to luma, 16-bit ones scaled to 8 bits. A JPEG cut short (no
/// end-of-image marker: a copy or a write that did not finish) is refused rather than decoded
/// half grey. Errors name the file.
pub fn load_gray(path: &Path) -> Result<GrayImage> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    decode_gray(&bytes, path)
}

/// Decodes the bytes of an image file as [`load_gray`] does; `path` names the image in errors.
pub fn decode_gray(bytes: &[u8], path: &Path) -> Result<GrayImage> {
    if bytes.starts_with(&[0xFF, 0xD8]) && !jpeg_complete(bytes) {
        return Err(Error::Input(format!(
            "{}: the JPEG is cut short (no end-of-image marker after {} bytes): the file was \
             not written or copied whole",
            path.display(),
            bytes.len()
        )));
    }
    let img = ::image::load_from_memory(bytes)
        .map_err(|e| Error::Input(format!("{}: cannot decode the image: {e}", path.display())))?;
    Ok(img.into_luma8())
}

/// Decodes the data of a `sensor_msgs/CompressedImage` whose `format` field says `format`: a
/// JPEG or PNG file, recognised by its first bytes whatever `format` says, decoded as an image
/// file is, at most [`MAX_SIDE`] pixels a side. Depth images (`compressedDepth`) and any other
/// data are errors that say what the data is.
pub fn decode_compressed(data: &[u8], format: &str) -> Result<GrayImage> {
    if format.to_ascii_lowercase().contains("compresseddepth") {
        return Err(Error::Input(format!(
            "compressed image format {format:?}: depth images (compressedDepth) are not \
             supported, only JPEG and PNG camera images"
        )));
    }
    let kind = if data.starts_with(JPEG_MAGIC) {
        if !jpeg_complete(data) {
            return Err(Error::Input(format!(
                "compressed image ({format:?}): the JPEG is cut short (no end-of-image marker \
                 after {} bytes)",
                data.len()
            )));
        }
        ImageFormat::Jpeg
    } else if data.starts_with(PNG_MAGIC) {
        ImageFormat::Png
    } else {
        let head: Vec<String> = data.iter().take(8).map(|b| format!("{b:02x}")).collect();
        return Err(Error::Input(format!(
            "compressed image format {format:?}: the data ({} bytes, starting {}) is neither a \
             JPEG nor a PNG file, the formats supported",
            data.len(),
            if head.is_empty() {
                "with nothing".to_string()
            } else {
                head.join(" ")
            }
        )));
    };
    let mut reader = ImageReader::with_format(Cursor::new(data), kind);
    let mut limits = Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| {
        Error::Input(format!(
            "compressed image ({format:?}): cannot decode the {kind:?} data: {e}"
        ))
    })?;
    Ok(img.into_luma8())
}

/// Whether a JPEG ends with its end-of-image marker (`FF D9`), allowing the zero or `FF`
/// padding some cameras write after it.
fn jpeg_complete(bytes: &[u8]) -> bool {
    let end = bytes
        .iter()
        .rposition(|&b| b != 0x00 && b != 0xFF)
        .map_or(0, |k| k + 1);
    // The marker's D9 is the last byte that is not padding, preceded by FF.
    end >= 2 && bytes.get(end - 2..end) == Some(&[0xFF, 0xD9][..])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jpeg_end_marker() {
        assert!(jpeg_complete(&[0xFF, 0xD8, 0xFF, 0xD9]));
        assert!(jpeg_complete(&[0xFF, 0xD8, 0xFF, 0xD9, 0, 0xFF]));
        assert!(!jpeg_complete(&[0xFF, 0xD8, 0xFF, 0xE0]));
        assert!(!jpeg_complete(&[]));
    }
}
