//! Writing images: 8-bit sRGB PNG for eyes, 32-bit float linear OpenEXR for measurements.

use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageFormat, Rgb32FImage, RgbImage};

use crate::render::film::Image;

/// sRGB opto-electronic transfer function (IEC 61966-2-1).
fn srgb_encode(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let v = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0 + 0.5) as u8
}

/// The 8-bit sRGB image of clamp(linear * 2^exposure).
pub fn to_srgb8(image: &Image, exposure: f32) -> RgbImage {
    let scale = exposure.exp2();
    let bytes = image
        .pixels
        .iter()
        .flat_map(|p| p.map(|c| srgb_encode(if c.is_finite() { c * scale } else { 0.0 })))
        .collect();
    RgbImage::from_raw(image.width, image.height, bytes).expect("buffer matches dimensions")
}

pub fn write_png(image: &Image, exposure: f32, path: &Path) -> image::ImageResult<()> {
    std::fs::write(path, encode_png(image, exposure)?)?;
    Ok(())
}

/// Linear radiance as 32-bit float RGB OpenEXR.
pub fn write_exr(image: &Image, path: &Path) -> image::ImageResult<()> {
    std::fs::write(path, encode_exr(image)?)?;
    Ok(())
}

/// The bytes of [`write_png`]'s file: every front end (a file, a farm's store) writes
/// these, so the same image is the same bytes everywhere.
pub fn encode_png(image: &Image, exposure: f32) -> image::ImageResult<Vec<u8>> {
    let mut out = std::io::Cursor::new(Vec::new());
    to_srgb8(image, exposure).write_to(&mut out, ImageFormat::Png)?;
    Ok(out.into_inner())
}

/// The bytes of [`write_exr`]'s file.
pub fn encode_exr(image: &Image) -> image::ImageResult<Vec<u8>> {
    let data: Vec<f32> = image.pixels.iter().flatten().copied().collect();
    let buf =
        Rgb32FImage::from_raw(image.width, image.height, data).expect("buffer matches dimensions");
    let mut out = std::io::Cursor::new(Vec::new());
    DynamicImage::ImageRgb32F(buf).write_to(&mut out, ImageFormat::OpenExr)?;
    Ok(out.into_inner())
}

/// Read a linear RGB image (OpenEXR or anything the image crate reads) as f32.
pub fn read_image(path: &Path) -> image::ImageResult<Image> {
    let img = image::open(path)?.into_rgb32f();
    let (width, height) = img.dimensions();
    let pixels = img.pixels().map(|p| p.0).collect();
    Ok(Image {
        width,
        height,
        pixels,
    })
}

/// A temporary name beside `path` that keeps its extension (image writers go by it).
fn partial_name(path: &Path) -> PathBuf {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("tmp");
    path.with_extension(format!("partial.{ext}"))
}

/// Whether `path` names something other than a regular file (`-o /dev/null`, a FIFO):
/// written in place, since renaming a file over it would replace the device itself (as
/// root, /dev/null became a regular file that way).
fn special_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Write `path` through a temporary file beside it: `write` fills the temporary file, which
/// is synced to disk and then renamed over `path`. A crash leaves the old file or the new
/// one, never a torn one. A device or FIFO is written in place ([`special_file`]).
pub fn write_atomically<E: From<std::io::Error>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), E> {
    if special_file(path) {
        return write(path);
    }
    let tmp = partial_name(path);
    write(&tmp)?;
    std::fs::File::open(&tmp)?.sync_all()?;
    std::fs::rename(&tmp, path)?;
    Ok(())
}

/// The PNG of `image` and, if asked, its EXR, each written atomically.
pub fn write_images(
    image: &Image,
    exposure: f32,
    png: &Path,
    exr: Option<&Path>,
) -> image::ImageResult<()> {
    write_atomically(png, |t| write_png(image, exposure, t))?;
    if let Some(exr) = exr {
        write_atomically(exr, |t| write_exr(image, t))?;
    }
    Ok(())
}

/// Read a linear OpenEXR (or any format `image` reads as float RGB) as an [`Image`].
pub fn read_exr(path: &Path) -> image::ImageResult<Image> {
    let hint = image::error::ImageFormatHint::PathExtension(path.to_path_buf());
    linear(image::open(path)?, hint)
}

/// A linear OpenEXR's bytes (a farm's stored image) as an [`Image`].
pub fn decode_exr(bytes: &[u8]) -> image::ImageResult<Image> {
    let img = image::load_from_memory_with_format(bytes, ImageFormat::OpenExr)?;
    linear(
        img,
        image::error::ImageFormatHint::Exact(ImageFormat::OpenExr),
    )
}

/// A decoded image as linear radiance, if it is float.
fn linear(img: DynamicImage, hint: image::error::ImageFormatHint) -> image::ImageResult<Image> {
    if !matches!(
        img,
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_)
    ) {
        // An 8-bit image is display-encoded, not radiance: comparing with it would mislead.
        return Err(image::ImageError::Unsupported(
            image::error::UnsupportedError::from_format_and_kind(
                hint,
                image::error::UnsupportedErrorKind::GenericFeature(
                    "not a linear float image (expected a 32-bit float EXR)".into(),
                ),
            ),
        ));
    }
    let img = img.into_rgb32f();
    let (width, height) = img.dimensions();
    let pixels = img
        .into_raw()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    Ok(Image {
        width,
        height,
        pixels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A FIFO (as a device would) is written in place, not replaced by a renamed file; a
    /// regular file, a missing one and a directory are not special.
    #[test]
    fn devices_and_fifos_are_written_in_place() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(made.unwrap().success(), "mkfifo");
        let file = dir.path().join("image.png");
        std::fs::write(&file, b"old").unwrap();
        assert!(special_file(&fifo));
        assert!(special_file(Path::new("/dev/null")));
        assert!(!special_file(&file));
        assert!(!special_file(&dir.path().join("missing.png")));
        assert!(!special_file(dir.path()));
        // In place: the writer gets the special path itself (never opened here, so a FIFO
        // without a reader cannot block the test).
        let mut given = None;
        write_atomically::<std::io::Error>(&fifo, |p| {
            given = Some(p.to_path_buf());
            Ok(())
        })
        .unwrap();
        assert_eq!(given.as_deref(), Some(fifo.as_path()));
        use std::os::unix::fs::FileTypeExt;
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    }

    #[test]
    fn srgb_curve_endpoints_and_midpoint() {
        assert_eq!(srgb_encode(0.0), 0);
        assert_eq!(srgb_encode(1.0), 255);
        assert_eq!(srgb_encode(2.0), 255);
        // Middle grey: 0.18 linear is 0.4613 in sRGB, 117.6 of 255.
        assert_eq!(srgb_encode(0.18), 118);
        // The linear toe below 0.0031308.
        assert_eq!(srgb_encode(0.001), 3);
    }

    #[test]
    fn exr_roundtrip_is_lossless() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let mut img = Image::new(3, 2);
        img.pixels[4] = [1.5, 0.001_234_5, 1e6];
        write_exr(&img, &path).unwrap();
        assert_eq!(read_image(&path).unwrap(), img);
    }
}
