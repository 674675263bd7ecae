//! The image messages of a bag as 8-bit grey images, what the tag detector takes.
//!
//! `sensor_msgs/Image` ([`image_to_gray`]): the encodings of [`SUPPORTED_ENCODINGS`].
//! - `mono8` and `8UC1` are taken as they are.
//! - `mono16` keeps the high byte of each pixel (the value divided by 256), in the byte order
//!   `is_bigendian` gives.
//! - `rgb8`, `bgr8`, `rgba8`, `bgra8` become luma by the `image` crate's own RGB-to-grey
//!   conversion (the sRGB weights 0.2126 R + 0.7152 G + 0.0722 B, computed in `f32` and
//!   rounded; alpha ignored), so that the pixels of a colour JPEG or PNG give the same grey
//!   whether they come as a file, a `CompressedImage` or a raw `Image`.
//! - `bayer_rggb8`, `bayer_bggr8`, `bayer_gbrg8`, `bayer_grbg8` (the name gives the colours of
//!   the top-left 2x2 block, row by row) are demosaiced bilinearly: each missing colour of a
//!   pixel is the mean (rounded) of the pixels of that colour in its 3x3 neighbourhood (at a
//!   red or blue pixel, green is the mean of the four direct neighbours and the other colour
//!   the mean of the four diagonal ones; at a green pixel each of red and blue is the mean of
//!   its two neighbours in a row or column). At the image border the neighbourhood is cut to
//!   the image; a colour absent from it (an image one pixel wide or high) takes the pixel's
//!   own value. The colour is then reduced to luma as above. A uniform raw image stays uniform
//!   with its own value.
//!
//! Rows may be padded: `step` bytes apart, at least `width` pixels' worth. Anything else
//! (an unknown encoding, a `step` shorter than a row, fewer bytes than `step * height`, an
//! empty image or a side above [`MAX_SIDE`]) is an error that says what is wrong.
//!
//! `sensor_msgs/CompressedImage` ([`compressed_to_gray`]): JPEG and PNG, recognised by the
//! data's first bytes whatever `format` says (`jpeg`, `png`, or image_transport's
//! `bgr8; jpeg compressed bgr8`), and decoded by [`crate::io::image`] exactly as the image
//! files of a dataset folder are, so the same file gives the same grey pixels either way.
//! `compressedDepth` (depth images) and any other data are errors.

use ::image::{DynamicImage, GrayImage, RgbImage};

use super::Serialization;
use super::cdr::{CompressedImage, CompressedImageView, Image, ImageView};
use crate::error::{Error, Result};
use crate::io::image::{MAX_SIDE, decode_compressed};

/// The `sensor_msgs/Image` encodings [`image_to_gray`] converts.
pub const SUPPORTED_ENCODINGS: &[&str] = &[
    "mono8",
    "8UC1",
    "mono16",
    "rgb8",
    "bgr8",
    "rgba8",
    "bgra8",
    "bayer_rggb8",
    "bayer_bggr8",
    "bayer_gbrg8",
    "bayer_grbg8",
];

/// The grey image of `width` x `height` RGB pixels (row by row, three bytes each), by the
/// `image` crate's conversion, the one a colour image file gets.
fn rgb_to_gray(width: u32, height: u32, rgb: Vec<u8>) -> Result<GrayImage> {
    let img = RgbImage::from_raw(width, height, rgb).ok_or_else(|| {
        Error::Input(format!(
            "{width}x{height} RGB pixels do not make an image (wrong pixel count)"
        ))
    })?;
    Ok(DynamicImage::ImageRgb8(img).into_luma8())
}

/// A colour channel of a Bayer mosaic.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Channel {
    Red,
    Green,
    Blue,
}

/// How the pixels of an encoding are laid out.
#[derive(Clone, Copy)]
enum Layout {
    /// One byte of grey.
    Mono8,
    /// Two bytes of grey.
    Mono16,
    /// `bytes` bytes per pixel, red, green and blue at the given offsets.
    Color {
        bytes: usize,
        r: usize,
        g: usize,
        b: usize,
    },
    /// One byte per pixel; the colours of the top-left 2x2 block, row by row.
    Bayer([Channel; 4]),
}

impl Layout {
    /// The layout of the encoding `enc` (compared without regard to case).
    fn of(enc: &str) -> Option<Layout> {
        use Channel::{Blue as B, Green as G, Red as R};
        Some(match enc.to_ascii_lowercase().as_str() {
            "mono8" | "8uc1" => Layout::Mono8,
            "mono16" => Layout::Mono16,
            "rgb8" => Layout::Color {
                bytes: 3,
                r: 0,
                g: 1,
                b: 2,
            },
            "bgr8" => Layout::Color {
                bytes: 3,
                r: 2,
                g: 1,
                b: 0,
            },
            "rgba8" => Layout::Color {
                bytes: 4,
                r: 0,
                g: 1,
                b: 2,
            },
            "bgra8" => Layout::Color {
                bytes: 4,
                r: 2,
                g: 1,
                b: 0,
            },
            "bayer_rggb8" => Layout::Bayer([R, G, G, B]),
            "bayer_bggr8" => Layout::Bayer([B, G, G, R]),
            "bayer_gbrg8" => Layout::Bayer([G, B, R, G]),
            "bayer_grbg8" => Layout::Bayer([G, R, B, G]),
            _ => return None,
        })
    }

    /// Bytes per pixel.
    fn bytes(self) -> usize {
        match self {
            Layout::Mono8 | Layout::Bayer(_) => 1,
            Layout::Mono16 => 2,
            Layout::Color { bytes, .. } => bytes,
        }
    }
}

/// Converts a `sensor_msgs/Image` to an 8-bit grey image (see the module documentation for
/// the encodings and the conversion of each).
pub fn image_to_gray(msg: &Image) -> Result<GrayImage> {
    image_view_to_gray(&msg.view())
}

/// [`image_to_gray`] of an image whose pixels are borrowed from its message.
pub fn image_view_to_gray(msg: &ImageView<'_>) -> Result<GrayImage> {
    let Some(layout) = Layout::of(&msg.encoding) else {
        return Err(Error::Input(format!(
            "image encoding {:?} is not supported (supported: {})",
            msg.encoding,
            SUPPORTED_ENCODINGS.join(", ")
        )));
    };
    let (width, height) = (msg.width, msg.height);
    if width == 0 || height == 0 {
        return Err(Error::Input(format!(
            "the {} image is {width}x{height}: an image without pixels",
            msg.encoding
        )));
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(Error::Input(format!(
            "the {} image is {width}x{height}: larger than {MAX_SIDE} pixels a side, which no \
             camera makes",
            msg.encoding
        )));
    }
    let (w, h) = (width as usize, height as usize);
    let row = w * layout.bytes();
    let step = msg.step as usize;
    if step < row {
        return Err(Error::Input(format!(
            "the {} image is {width}x{height} but its step (bytes per row) is {step}, less than \
             the {row} bytes of a row",
            msg.encoding
        )));
    }
    // step <= u32::MAX and h <= MAX_SIDE: no overflow in u64.
    let need = msg.step as u64 * u64::from(height);
    if (msg.data.len() as u64) < need {
        return Err(Error::Input(format!(
            "the {} image is {width}x{height} with a step of {step} bytes, which needs {need} \
             bytes of data; the message has {}",
            msg.encoding,
            msg.data.len()
        )));
    }
    // Each row's pixel bytes, the padding after them left out.
    let rows = msg
        .data
        .chunks(step)
        .take(h)
        .map(|r| r.get(..row).unwrap_or_default());
    let gray = match layout {
        Layout::Mono8 => {
            let mut out = Vec::with_capacity(w * h);
            rows.for_each(|r| out.extend_from_slice(r));
            out
        }
        Layout::Mono16 => {
            let hi = usize::from(msg.is_bigendian == 0);
            let mut out = Vec::with_capacity(w * h);
            for r in rows {
                out.extend(r.chunks_exact(2).map(|p| p.get(hi).copied().unwrap_or(0)));
            }
            out
        }
        Layout::Color { bytes, r, g, b } => {
            let mut rgb = Vec::with_capacity(3 * w * h);
            for row in rows {
                for p in row.chunks_exact(bytes) {
                    let c = |i: usize| p.get(i).copied().unwrap_or(0);
                    rgb.extend_from_slice(&[c(r), c(g), c(b)]);
                }
            }
            return rgb_to_gray(width, height, rgb);
        }
        Layout::Bayer(pattern) => {
            let mut raw = Vec::with_capacity(w * h);
            rows.for_each(|r| raw.extend_from_slice(r));
            return rgb_to_gray(width, height, demosaic(&raw, w, h, pattern));
        }
    };
    GrayImage::from_raw(width, height, gray).ok_or_else(|| {
        Error::Input(format!(
            "the {} image: {width}x{height} pixels do not make an image",
            msg.encoding
        ))
    })
}

/// Bilinear demosaic of the `w` x `h` mosaic `raw` (colours of the top-left 2x2 block in
/// `pattern`): RGB pixels, row by row.
fn demosaic(raw: &[u8], w: usize, h: usize, pattern: [Channel; 4]) -> Vec<u8> {
    let at = |x: usize, y: usize| raw.get(y * w + x).copied().unwrap_or(0);
    let colour = |x: usize, y: usize| pattern[(y % 2) * 2 + x % 2];
    let mut out = Vec::with_capacity(3 * w * h);
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(1), (y + 1).min(h - 1));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
            let own = at(x, y);
            // Sum and count of each colour (red, green, blue) in the neighbourhood.
            let mut sum = [0u32; 3];
            let mut n = [0u32; 3];
            for yy in y0..=y1 {
                for xx in x0..=x1 {
                    let c = colour(xx, yy) as usize;
                    sum[c] += u32::from(at(xx, yy));
                    n[c] += 1;
                }
            }
            let mine = colour(x, y) as usize;
            let value = |c: usize| {
                if c == mine || n[c] == 0 {
                    own
                } else {
                    // A mean of u8 values is a u8.
                    u8::try_from((sum[c] + n[c] / 2) / n[c]).unwrap_or(u8::MAX)
                }
            };
            out.extend_from_slice(&[
                value(Channel::Red as usize),
                value(Channel::Green as usize),
                value(Channel::Blue as usize),
            ]);
        }
    }
    out
}

/// Converts a `sensor_msgs/CompressedImage` holding a JPEG or PNG file to an 8-bit grey image,
/// decoded as the image files of a dataset folder are ([`crate::io::image::decode_compressed`]).
pub fn compressed_to_gray(msg: &CompressedImage) -> Result<GrayImage> {
    compressed_view_to_gray(&msg.view())
}

/// [`compressed_to_gray`] of an image whose bytes are borrowed from its message.
pub fn compressed_view_to_gray(msg: &CompressedImageView<'_>) -> Result<GrayImage> {
    decode_compressed(msg.data, &msg.format)
}

/// Decodes a serialised image message of type `type_name` (`sensor_msgs/Image` or
/// `sensor_msgs/CompressedImage`, either ROS version's spelling) and converts it to grey,
/// reading the pixels where they lie in `data`.
pub fn message_to_gray(data: &[u8], ser: Serialization, type_name: &str) -> Result<GrayImage> {
    match super::normalize_type(type_name).as_str() {
        "sensor_msgs/Image" => image_view_to_gray(&ImageView::decode(data, ser)?),
        "sensor_msgs/CompressedImage" => {
            compressed_view_to_gray(&CompressedImageView::decode(data, ser)?)
        }
        other => Err(Error::Input(format!(
            "messages of type {other} are not images (sensor_msgs/Image or \
             sensor_msgs/CompressedImage are)"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(w: u32, h: u32, enc: &str, step: u32, data: Vec<u8>) -> Image {
        Image {
            width: w,
            height: h,
            encoding: enc.into(),
            step,
            data,
            ..Image::default()
        }
    }

    #[test]
    fn luma_has_the_srgb_weights() {
        for (r, g, b) in [
            (0, 0, 0),
            (255, 255, 255),
            (255, 0, 0),
            (10, 200, 30),
            (1, 2, 3),
        ] {
            let got = rgb_to_gray(1, 1, vec![r, g, b]).unwrap().as_raw()[0];
            let want = 0.2126 * f64::from(r) + 0.7152 * f64::from(g) + 0.0722 * f64::from(b);
            assert!(
                (f64::from(got) - want).abs() <= 0.5 + 1e-3,
                "{r} {g} {b}: {got}"
            );
        }
    }

    #[test]
    fn mono16_takes_the_high_byte() {
        let le = raw(2, 1, "mono16", 4, vec![0x34, 0x12, 0xff, 0xab]);
        assert_eq!(image_to_gray(&le).unwrap().as_raw(), &[0x12, 0xab]);
        let be = Image {
            is_bigendian: 1,
            ..raw(2, 1, "mono16", 4, vec![0x12, 0x34, 0xab, 0xff])
        };
        assert_eq!(image_to_gray(&be).unwrap().as_raw(), &[0x12, 0xab]);
    }

    #[test]
    fn uniform_bayer_stays_uniform() {
        for enc in ["bayer_rggb8", "bayer_bggr8", "bayer_gbrg8", "bayer_grbg8"] {
            for (w, h) in [(1, 1), (1, 3), (4, 1), (5, 4)] {
                let g = image_to_gray(&raw(w, h, enc, w, vec![77; (w * h) as usize])).unwrap();
                assert!(g.as_raw().iter().all(|&v| v == 77), "{enc} {w}x{h}");
            }
        }
    }

    #[test]
    fn bad_sizes_are_errors() {
        let e = image_to_gray(&raw(3, 2, "rgb8", 8, vec![0; 16]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("step") && e.contains("9 bytes of a row"), "{e}");
        let e = image_to_gray(&raw(3, 2, "mono8", 4, vec![0; 7]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs 8 bytes"), "{e}");
        assert!(image_to_gray(&raw(0, 2, "mono8", 0, vec![])).is_err());
        assert!(image_to_gray(&raw(20_001, 1, "mono8", 20_001, vec![0; 20_001])).is_err());
        let e = image_to_gray(&raw(1, 1, "32FC1", 4, vec![0; 4]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"32FC1\"") && e.contains("bayer_grbg8"), "{e}");
    }
}
