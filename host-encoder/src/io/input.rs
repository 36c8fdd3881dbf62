//! Images in: any format the `image` crate reads here (PNG, JPEG, PNM, BMP, TIFF, WebP, GIF),
//! from a file or standard input, read within limits and converted to 8-bit luma.
//!
//! An image is looked at twice: first its header alone ([`ImageProbe::read`]: format,
//! dimensions, EXIF orientation, pages), so that a caller can refuse it before a pixel is
//! decoded; then its pixels ([`DecodedImage::decode`]), with the `image` crate's allocation
//! limit set, its orientation applied (a phone photo arrives the way it was shown) and, for a
//! TIFF of several pages or an animated GIF or WebP, the first page or frame taken.

use super::{input_name, is_std_stream, FileError};
use crate::encoder::{analyse, analyse_colour, Analysis, EncodeError, EncoderConfig, Plane};
use decoder_core::internal::model::SAMPLE_ONE;
use decoder_core::SampleRange;
use image::metadata::Orientation;
use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader};
use std::io::{Cursor, Read};
use std::path::Path;

/// Bounds on the images a caller accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageLimits {
    /// Largest `width * height`.
    pub max_pixels: u64,
    /// Most bytes the image decoder may allocate (its pixel buffer included).
    pub max_alloc: u64,
}

impl ImageLimits {
    /// The `image` crate's own defaults: any size, 512 MiB of allocations.
    pub const DEFAULT: ImageLimits = ImageLimits {
        max_pixels: u64::MAX,
        max_alloc: 512 << 20,
    };
}

/// Reads the whole of an input file, or standard input for `-`, refusing a directory and
/// anything longer than `max_bytes` (a regular file by its size, before reading it; any other
/// input once `max_bytes + 1` bytes have arrived). `expected` names what should be there, for
/// the errors ("an image").
pub fn read_input(
    path: &Path,
    expected: &'static str,
    max_bytes: u64,
) -> Result<Vec<u8>, FileError> {
    let name = input_name(path);
    let source: Box<dyn Read> = if is_std_stream(path) {
        Box::new(std::io::stdin().lock())
    } else {
        if path.is_dir() {
            return Err(FileError::IsDirectory {
                path: name,
                expected,
            });
        }
        let file = std::fs::File::open(path).map_err(|source| FileError::Open {
            path: name.clone(),
            source,
        })?;
        if let Ok(meta) = file.metadata() {
            if meta.is_file() && meta.len() > max_bytes {
                return Err(FileError::InputTooLong {
                    path: name,
                    limit: max_bytes,
                });
            }
        }
        Box::new(file)
    };
    let mut bytes = Vec::new();
    source
        .take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|source| FileError::Read {
            path: name.clone(),
            source,
        })?;
    if bytes.len() as u64 > max_bytes {
        return Err(FileError::InputTooLong {
            path: name,
            limit: max_bytes,
        });
    }
    Ok(bytes)
}

/// A reader of the image `bytes` whose format is known: `path`'s extension is the first
/// guess, the contents decide when they are recognised.
fn reader<'a>(bytes: &'a [u8], path: &Path) -> Result<ImageReader<Cursor<&'a [u8]>>, FileError> {
    let mut reader = ImageReader::new(Cursor::new(bytes));
    if let Ok(format) = ImageFormat::from_path(path) {
        reader.set_format(format);
    }
    let reader = reader
        .with_guessed_format()
        .map_err(|source| FileError::Read {
            path: path.to_path_buf(),
            source,
        })?;
    if reader.format().is_none() {
        return Err(if is_pifs(bytes) {
            FileError::AlreadyPifs {
                path: path.to_path_buf(),
            }
        } else {
            FileError::Format {
                path: path.to_path_buf(),
            }
        });
    }
    Ok(reader)
}

/// Whether `bytes` are PIFS data rather than an image: a whole stream or packet of this
/// format version (its check passes), or a stream of format 21 or earlier.
fn is_pifs(bytes: &[u8]) -> bool {
    decoder_core::Decoder::new(bytes).is_ok()
        || decoder_core::Packet::parse(bytes).is_ok()
        || bytes.starts_with(&decoder_core::internal::format::LEGACY_MAGIC)
}

/// What an image's header says, read without decoding its pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageProbe {
    /// The format the contents are in.
    pub format: ImageFormat,
    /// Width as the image is shown (its EXIF orientation applied), pixels.
    pub width: u32,
    /// Height as the image is shown, pixels.
    pub height: u32,
    /// Bytes of the decoded pixel buffer, in the file's own colour type.
    pub decoded_bytes: u64,
    /// Whether that colour type has colour (RGB, RGBA, a palette): the encoder takes the
    /// image in colour unless every pixel turns out gray, which only its pixels tell.
    pub colour: bool,
    /// The orientation the file asks for (applied by [`DecodedImage::decode`]).
    pub orientation: Orientation,
    /// Pages: a TIFF's images, an animated GIF's or WebP's frames (1 for every other format).
    pub pages: usize,
}

impl ImageProbe {
    /// Reads the header of the image `bytes` (`path` names it in errors; its extension is the
    /// format's first guess).
    pub fn read(bytes: &[u8], path: &Path) -> Result<ImageProbe, FileError> {
        let mut reader = reader(bytes, path)?;
        let format = reader.format().unwrap_or(ImageFormat::Png);
        // The header is read whatever it announces: the caller's limits decide.
        reader.no_limits();
        let failed = |source| FileError::Decode {
            path: path.to_path_buf(),
            source,
        };
        let mut decoder = reader.into_decoder().map_err(failed)?;
        let orientation = decoder.orientation().unwrap_or(Orientation::NoTransforms);
        let (w, h) = decoder.dimensions();
        let (width, height) = if swaps_sides(orientation) {
            (h, w)
        } else {
            (w, h)
        };
        Ok(ImageProbe {
            format,
            width,
            height,
            decoded_bytes: decoder.total_bytes(),
            colour: decoder.color_type().has_color(),
            orientation,
            pages: match format {
                ImageFormat::Tiff => tiff_pages(bytes),
                ImageFormat::Gif => gif_frames(bytes),
                ImageFormat::WebP => webp_frames(bytes),
                _ => 1,
            },
        })
    }

    /// `width * height`.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }
}

/// Whether `orientation` turns the image by a quarter turn (width and height swap).
fn swaps_sides(orientation: Orientation) -> bool {
    matches!(
        orientation,
        Orientation::Rotate90
            | Orientation::Rotate270
            | Orientation::Rotate90FlipH
            | Orientation::Rotate270FlipH
    )
}

/// The number of images in a TIFF file (at least 1; counting stops at 65536). Only the image
/// directories are read, not the pixels.
fn tiff_pages(bytes: &[u8]) -> usize {
    let Ok(mut decoder) = tiff::decoder::Decoder::new(Cursor::new(bytes)) else {
        return 1;
    };
    let mut pages = 1;
    while pages < 1 << 16 && decoder.more_images() && decoder.next_image().is_ok() {
        pages += 1;
    }
    pages
}

/// The number of frames of a GIF file (at least 1; counting stops at 65536). The frames'
/// pixels are not decompressed.
fn gif_frames(bytes: &[u8]) -> usize {
    let mut options = gif::DecodeOptions::new();
    options.skip_frame_decoding(true);
    let Ok(mut decoder) = options.read_info(Cursor::new(bytes)) else {
        return 1;
    };
    let mut frames = 0;
    while frames < 1 << 16 && matches!(decoder.read_next_frame(), Ok(Some(_))) {
        frames += 1;
    }
    frames.max(1)
}

/// The number of frames of a WebP file (1 unless it is animated), from its headers.
fn webp_frames(bytes: &[u8]) -> usize {
    image_webp::WebPDecoder::new(Cursor::new(bytes))
        .map_or(1, |decoder| decoder.num_frames().max(1) as usize)
}

/// A decoded image as 8-bit luma (and RGB when it has colour), and what was done to get it.
#[derive(Debug, Clone)]
pub struct DecodedImage {
    /// The pixels, as shown (orientation applied), by the rule of [`to_luma`].
    pub plane: Plane,
    /// The same pixels as 8-bit RGB ([`to_rgb`]) when the image has colour: a colour type with
    /// some pixel whose channels differ.
    pub rgb: Option<Vec<u8>>,
    /// The orientation that was applied.
    pub orientation: Orientation,
    /// The format the file was in.
    pub format: ImageFormat,
    /// The file's pages (a TIFF's) or frames (a GIF's or a WebP's): only the first was decoded.
    pub pages: usize,
    /// A 16-bit grayscale image's samples (a heightmap, often), which [`to_luma`] maps to 8
    /// bits from the type's full range: what a 16-bit stream codes.
    pub surface: Option<Surface>,
}

/// A 16-bit grayscale image as a surface: its samples and the smallest and largest of them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Surface {
    /// Width in samples.
    pub width: u32,
    /// Height in samples.
    pub height: u32,
    /// Row-major samples.
    pub values: Vec<u16>,
    /// The smallest sample.
    pub min: u16,
    /// The largest sample.
    pub max: u16,
}

/// How far a decoded surface is from its samples, in their units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceError {
    /// Root-mean-square error.
    pub rmse: f64,
    /// Largest absolute error.
    pub max: u16,
    /// PSNR relative to the surface's range (`20 log10(range / rmse)`), as the thesis measures
    /// terrain.
    pub psnr: f64,
}

impl Surface {
    /// The surface of a 16-bit grayscale image (with or without alpha); `None` for any other.
    pub fn of_gray16(img: &DynamicImage) -> Option<Surface> {
        let values: Vec<u16> = match img {
            DynamicImage::ImageLuma16(g) => g.pixels().map(|p| p[0]).collect(),
            DynamicImage::ImageLumaA16(g) => g.pixels().map(|p| p[0]).collect(),
            _ => return None,
        };
        Some(Surface {
            width: img.width(),
            height: img.height(),
            min: values.iter().copied().min()?,
            max: values.iter().copied().max()?,
            values,
        })
    }

    /// The value range of its streams' headers: from its smallest sample, the smallest step
    /// that reaches its largest at grey 255.
    pub fn range(&self) -> SampleRange {
        SampleRange::covering(self.min, self.max)
    }

    /// The samples as the encoder takes them: mapped onto grey by [`Surface::range`], to the
    /// nearest 1/16 of a grey level (the decoder's resolution; at most 255).
    pub fn plane(&self) -> Plane {
        let SampleRange { low, step } = self.range();
        let one = u64::from(SampleRange::STEP_ONE) * u64::from(SAMPLE_ONE as u32);
        let step = u64::from(step);
        let samples = self
            .values
            .iter()
            .map(|&v| ((2 * one * u64::from(v - low) + step) / (2 * step)) as u16)
            .collect();
        Plane::with_samples(self.width, self.height, samples)
    }

    /// The error of `decoded` (the same number of samples) against this surface.
    pub fn error(&self, decoded: &[u16]) -> SurfaceError {
        let mut sum = 0.0;
        let mut max = 0;
        for (&a, &b) in self.values.iter().zip(decoded) {
            let d = a.abs_diff(b);
            sum += f64::from(d) * f64::from(d);
            max = max.max(d);
        }
        let rmse = (sum / self.values.len().max(1) as f64).sqrt();
        let span = f64::from(self.max - self.min).max(1.0);
        SurfaceError {
            rmse,
            max,
            psnr: 20.0 * (span / rmse.max(1e-9)).log10(),
        }
    }
}

/// A box an image is scaled to fit in, keeping its shape: the size of the display it is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fit {
    /// Width of the box in pixels.
    pub width: u32,
    /// Height of the box in pixels.
    pub height: u32,
}

impl Fit {
    /// The size an image of `width x height` takes in the box: scaled by the larger factor that
    /// keeps both sides within it (enlarging too), each side rounded, at least 1.
    pub fn size_of(self, width: u32, height: u32) -> (u32, u32) {
        let scale = (f64::from(self.width) / f64::from(width.max(1)))
            .min(f64::from(self.height) / f64::from(height.max(1)));
        let side = |v: u32, most: u32| ((f64::from(v) * scale).round() as u32).clamp(1, most);
        (side(width, self.width), side(height, self.height))
    }

    /// Parses `WxH` (both from 1 to 65535).
    pub fn parse(text: &str) -> Result<Fit, String> {
        let bad = || format!("not a size: {text} (WIDTHxHEIGHT, such as 240x240)");
        let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
        let side = |v: &str| {
            v.trim()
                .parse::<u16>()
                .ok()
                .filter(|&v| v > 0)
                .ok_or_else(bad)
        };
        Ok(Fit {
            width: u32::from(side(w)?),
            height: u32::from(side(h)?),
        })
    }
}

impl DecodedImage {
    /// Decodes the image `bytes` (`path` names it in errors) within `limits`: more pixels
    /// than `limits.max_pixels` are refused on the header
    /// ([`image::error::LimitErrorKind::DimensionError`]), and the decoder fails rather than
    /// allocate more than `limits.max_alloc` bytes
    /// ([`image::error::LimitErrorKind::InsufficientMemory`]); both come back as
    /// [`FileError::Decode`] with an [`image::ImageError::Limits`] source.
    pub fn decode(bytes: &[u8], path: &Path, limits: &ImageLimits) -> Result<Self, FileError> {
        Self::decode_fitted(bytes, path, limits, None)
    }

    /// [`DecodedImage::decode`], then the image scaled to fit `fit` (orientation applied first;
    /// Catmull-Rom resampling, on the image's own samples: 16-bit ones stay 16-bit).
    pub fn decode_fitted(
        bytes: &[u8],
        path: &Path,
        limits: &ImageLimits,
        fit: Option<Fit>,
    ) -> Result<Self, FileError> {
        let probe = ImageProbe::read(bytes, path)?;
        let failed = |source| FileError::Decode {
            path: path.to_path_buf(),
            source,
        };
        let limit = |kind| {
            failed(image::ImageError::Limits(
                image::error::LimitError::from_kind(kind),
            ))
        };
        if probe.pixels() > limits.max_pixels {
            return Err(limit(image::error::LimitErrorKind::DimensionError));
        }
        // The pixel buffer, checked here: not every decoder counts it against its limit.
        if probe.decoded_bytes > limits.max_alloc {
            return Err(limit(image::error::LimitErrorKind::InsufficientMemory));
        }
        let mut reader = reader(bytes, path)?;
        let mut image_limits = image::Limits::default();
        image_limits.max_alloc = Some(limits.max_alloc);
        reader.limits(image_limits);
        let decoder = reader.into_decoder().map_err(failed)?;
        let mut img = DynamicImage::from_decoder(decoder).map_err(failed)?;
        img.apply_orientation(probe.orientation);
        if let Some(fit) = fit {
            let (w, h) = fit.size_of(img.width(), img.height());
            if (w, h) != (img.width(), img.height()) {
                img = img.resize_exact(w, h, image::imageops::FilterType::CatmullRom);
            }
        }
        let rgb = img
            .color()
            .has_color()
            .then(|| to_rgb(&img))
            .filter(|rgb| rgb.chunks_exact(3).any(|p| p[0] != p[1] || p[1] != p[2]));
        Ok(DecodedImage {
            plane: to_luma(&img),
            rgb,
            orientation: probe.orientation,
            format: probe.format,
            pages: probe.pages,
            surface: Surface::of_gray16(&img),
        })
    }
}

impl DecodedImage {
    /// The image as the encoder takes it: colour when it has colour, unless `gray`; a 16-bit
    /// grayscale image as a surface, unless `depth` is [`Depth::Eight`].
    pub fn into_loaded(self, gray: bool, depth: Depth) -> Loaded {
        match (self.rgb, self.surface) {
            (Some(data), _) if !gray => Loaded::Rgb {
                width: self.plane.width,
                height: self.plane.height,
                data,
            },
            (_, Some(surface)) if depth == Depth::Auto => Loaded::Surface(surface),
            _ => Loaded::Gray(self.plane),
        }
    }
}

/// The bit depth of the streams made from an image.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Depth {
    /// The image's: 16 for a 16-bit grayscale image, else 8.
    #[default]
    Auto,
    /// 8, a 16-bit image's samples mapped to 8 bits from their type's full range.
    Eight,
}

/// An image as the encoder takes it: grayscale, colour, or a 16-bit surface.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Loaded {
    /// 8-bit luma ([`to_luma`]).
    Gray(Plane),
    /// 16-bit grayscale samples, for a 16-bit stream.
    Surface(Surface),
    /// 8-bit RGB ([`to_rgb`]).
    Rgb {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// Row-major RGB, 3 bytes a pixel.
        data: Vec<u8>,
    },
}

impl Loaded {
    /// Width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        match self {
            Loaded::Gray(plane) => (plane.width, plane.height),
            Loaded::Surface(surface) => (surface.width, surface.height),
            Loaded::Rgb { width, height, .. } => (*width, *height),
        }
    }

    /// The configuration [`Loaded::analyse`] runs with `config`: a surface's range set in it
    /// (16-bit streams), `config` as it is for any other image.
    pub fn config(&self, config: &EncoderConfig) -> EncoderConfig {
        match self {
            Loaded::Surface(surface) => EncoderConfig {
                range: Some(surface.range()),
                ..config.clone()
            },
            _ => config.clone(),
        }
    }

    /// Analyses the image for the streams it makes ([`crate::analyse`] for grayscale,
    /// [`crate::analyse_colour`] for colour, a surface under [`Loaded::config`] for 16-bit
    /// streams). `progress` as theirs.
    pub fn analyse(
        self,
        config: &EncoderConfig,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Analysis, EncodeError> {
        let config = &self.config(config);
        match self {
            Loaded::Gray(plane) => analyse(plane, config, progress),
            Loaded::Surface(surface) => analyse(surface.plane(), config, progress),
            Loaded::Rgb {
                width,
                height,
                data,
            } => analyse_colour(width, height, data, config, progress),
        }
    }
}

/// Loads an image file as the encoder takes it ([`DecodedImage::into_loaded`]), its
/// orientation applied, within the `image` crate's default limits.
pub fn load_image(path: &Path) -> Result<Loaded, FileError> {
    let bytes = read_input(path, "an image", u64::MAX)?;
    DecodedImage::decode(&bytes, path, &ImageLimits::DEFAULT)
        .map(|d| d.into_loaded(false, Depth::Auto))
}

/// Converts a decoded image to 8-bit row-major RGB: any bit depth from its full range,
/// rounded; palettes through their palette; transparency composited over white, channel by
/// channel (as [`to_luma`] does for luma); a band of rows at a time.
pub fn to_rgb(img: &DynamicImage) -> Vec<u8> {
    let (w, h) = (img.width(), img.height());
    let mut data = Vec::with_capacity(3 * w as usize * h as usize);
    let rows = (CONVERSION_PIXELS / (w as usize).max(1)).clamp(1, h.max(1) as usize) as u32;
    let mut y = 0;
    while y < h {
        let n = rows.min(h - y);
        let band = img.crop_imm(0, y, w, n).to_rgba32f();
        for p in band.pixels() {
            let a = p[3].clamp(0.0, 1.0);
            for c in 0..3 {
                let v = a * p[c] + (1.0 - a);
                data.push((v * 255.0).round().clamp(0.0, 255.0) as u8);
            }
        }
        y += n;
    }
    data
}

/// Loads an image file as 8-bit luma, by the rule of [`to_luma`], its orientation applied,
/// within the `image` crate's default limits.
pub fn load_luma(path: &Path) -> Result<Plane, FileError> {
    let bytes = read_input(path, "an image", u64::MAX)?;
    decode_luma(&bytes, path)
}

/// Decodes an image file's contents `bytes` as 8-bit luma, by the rule of [`to_luma`], its
/// orientation applied, within the `image` crate's default limits. `path` names the file in
/// errors, and its extension is the format's first guess (the contents decide when they are
/// recognised).
pub fn decode_luma(bytes: &[u8], path: &Path) -> Result<Plane, FileError> {
    DecodedImage::decode(bytes, path, &ImageLimits::DEFAULT).map(|d| d.plane)
}

/// Pixels converted at a time by [`to_luma`] (as 32-bit float RGBA, 16 bytes each): the
/// conversion's own memory stays small whatever the image.
const CONVERSION_PIXELS: usize = 1 << 18;

/// Converts a decoded image to 8-bit luma:
/// - colour by the BT.601 weights, `Y = 0.299 R + 0.587 G + 0.114 B` (grey stays grey);
/// - any bit depth (16-bit, float) from its full range to 0..=255, rounded;
/// - palette images through their palette;
/// - transparency composited over white, `Y' = a Y + (1 - a)` with `a` the alpha in 0..=1, as
///   an image viewer shows it on a white page (a fully transparent pixel becomes white,
///   whatever colour it carries).
///
/// Converted a band of rows at a time, so the conversion needs no copy of the whole image.
pub fn to_luma(img: &DynamicImage) -> Plane {
    let (w, h) = (img.width(), img.height());
    let mut data = Vec::with_capacity(w as usize * h as usize);
    let rows = (CONVERSION_PIXELS / (w as usize).max(1)).clamp(1, h.max(1) as usize) as u32;
    let mut y = 0;
    while y < h {
        let n = rows.min(h - y);
        let band = img.crop_imm(0, y, w, n).to_rgba32f();
        data.extend(band.pixels().map(|p| {
            let luma = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
            let a = p[3].clamp(0.0, 1.0);
            let luma = a * luma + (1.0 - a);
            (luma * 255.0).round().clamp(0.0, 255.0) as u8
        }));
        y += n;
    }
    Plane::new(w, h, data)
}

/// Whether `path`'s extension names an image format (`.png`, `.jpg`, `.tiff`, …: any the
/// `image` crate knows, enabled or not), where a PIFS stream does not belong.
pub fn has_image_extension(path: &Path) -> bool {
    ImageFormat::from_path(path).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fit_keeps_the_shape_within_the_box() {
        let fit = Fit::parse("240x240").unwrap();
        assert_eq!(fit.size_of(768, 512), (240, 160));
        assert_eq!(fit.size_of(512, 768), (160, 240));
        assert_eq!(fit.size_of(60, 40), (240, 160));
        assert_eq!(Fit::parse("10X10").unwrap().size_of(1, 1000), (1, 10));
        assert_eq!(Fit::parse("128x64").unwrap().size_of(768, 512), (96, 64));
        for bad in ["240", "0x5", "5x0", "x5", "65536x1", "ax2", ""] {
            assert!(Fit::parse(bad).is_err(), "{bad}");
        }
    }

    /// A 16-bit gray image is a surface whose range starts at its smallest sample and reaches
    /// its largest at (or just before) grey 255; a flat one steps by 1/128; an 8-bit image is
    /// none.
    #[test]
    fn sixteen_bit_gray_images_are_surfaces() {
        let ramp = image::ImageBuffer::from_fn(4, 1, |x, _| image::Luma([300 + 100 * x as u16]));
        let surface = Surface::of_gray16(&DynamicImage::ImageLuma16(ramp)).unwrap();
        assert_eq!((surface.min, surface.max), (300, 600));
        // 300 * 128 / 255 = 150.6: a step of 151 / 128 = 1.18 a grey level.
        assert_eq!(
            surface.range(),
            SampleRange {
                low: 300,
                step: 151
            }
        );
        assert_eq!(surface.plane().data, vec![0, 85, 170, 254]);
        let error = surface.error(&[300, 402, 498, 600]);
        assert_eq!(error.max, 2);
        assert!((error.rmse - 2f64.sqrt()).abs() < 1e-12);
        assert!((error.psnr - 20.0 * (300.0 / 2f64.sqrt()).log10()).abs() < 1e-9);
        for v in [7, u16::MAX] {
            let flat = image::ImageBuffer::from_pixel(3, 2, image::Luma([v]));
            let surface = Surface::of_gray16(&DynamicImage::ImageLuma16(flat)).unwrap();
            assert_eq!(surface.range(), SampleRange { low: v, step: 1 });
            assert_eq!(surface.plane().data, vec![0; 6]);
        }
        let eight =
            DynamicImage::ImageLuma8(image::ImageBuffer::from_pixel(2, 2, image::Luma([9])));
        assert_eq!(Surface::of_gray16(&eight), None);
    }

    fn png(img: &DynamicImage) -> Vec<u8> {
        let mut out = Vec::new();
        img.write_to(&mut Cursor::new(&mut out), ImageFormat::Png)
            .unwrap();
        out
    }

    /// WebP (lossless here) and GIF files read as their pixels, as PNG does; a GIF's first
    /// frame.
    #[test]
    fn webp_and_gif_inputs_are_read() {
        let gray = image::GrayImage::from_fn(9, 7, |x, y| image::Luma([(x * 25 + y * 3) as u8]));
        let rgb = DynamicImage::ImageLuma8(gray.clone()).to_rgb8();
        for (format, name) in [(ImageFormat::WebP, "a.webp"), (ImageFormat::Gif, "a.gif")] {
            let mut bytes = Vec::new();
            DynamicImage::ImageRgb8(rgb.clone())
                .write_to(&mut Cursor::new(&mut bytes), format)
                .unwrap();
            // Named as another format: the contents decide.
            for path in [name, "misnamed.png"] {
                let plane = decode_luma(&bytes, Path::new(path)).unwrap();
                assert_eq!((plane.width, plane.height), (9, 7), "{path}");
                assert_eq!(plane.data, gray.as_raw().as_slice(), "{path}");
            }
        }
    }

    /// An animated WebP of two 2x2 frames, red then green (Pillow: `Image.new("RGB", (2, 2),
    /// (200, 20, 30)).save("a.webp", save_all=True, append_images=[Image.new("RGB", (2, 2),
    /// (20, 200, 30))], duration=100, lossless=True)`): two frames, the first decoded.
    #[test]
    fn an_animated_webp_is_its_first_frame() {
        const WEBP: [u8; 144] = [
            0x52, 0x49, 0x46, 0x46, 0x88, 0x00, 0x00, 0x00, 0x57, 0x45, 0x42, 0x50, 0x56, 0x50,
            0x38, 0x58, 0x0a, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x01,
            0x00, 0x00, 0x41, 0x4e, 0x49, 0x4d, 0x06, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            0x00, 0x00, 0x41, 0x4e, 0x4d, 0x46, 0x2a, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            0x00, 0x00, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00, 0x64, 0x00, 0x00, 0x02, 0x56, 0x50,
            0x38, 0x4c, 0x11, 0x00, 0x00, 0x00, 0x2f, 0x01, 0x40, 0x00, 0x00, 0x07, 0x50, 0x8a,
            0x22, 0xd7, 0xa3, 0xff, 0x81, 0x88, 0xe8, 0x7f, 0x00, 0x00, 0x41, 0x4e, 0x4d, 0x46,
            0x2a, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x01,
            0x00, 0x00, 0x64, 0x00, 0x00, 0x00, 0x56, 0x50, 0x38, 0x4c, 0x11, 0x00, 0x00, 0x00,
            0x2f, 0x01, 0x40, 0x00, 0x00, 0x07, 0x50, 0xe4, 0x52, 0xd4, 0xa3, 0xff, 0x81, 0x88,
            0xe8, 0x7f, 0x00, 0x00,
        ];
        let path = Path::new("a.webp");
        let probe = ImageProbe::read(&WEBP, path).unwrap();
        assert_eq!((probe.format, probe.pages), (ImageFormat::WebP, 2));
        let decoded = DecodedImage::decode(&WEBP, path, &ImageLimits::DEFAULT).unwrap();
        assert_eq!(decoded.pages, 2);
        assert_eq!(decoded.rgb.unwrap(), [200, 20, 30].repeat(4));
    }

    #[test]
    fn image_extensions_are_recognised() {
        for p in [
            "a.png", "a.JPG", "a.jpeg", "a.tif", "a.bmp", "a.pgm", "a.webp", "a.gif",
        ] {
            assert!(has_image_extension(Path::new(p)), "{p}");
        }
        for p in ["a.pifs", "a", "a.bin", "a.svg"] {
            assert!(!has_image_extension(Path::new(p)), "{p}");
        }
    }

    #[test]
    fn the_conversion_by_bands_is_the_conversion_of_the_whole() {
        // Wider than one band's worth of rows, and a height that is not a multiple of it.
        let (w, h) = (700u32, 1000u32);
        let img = DynamicImage::ImageRgba8(image::RgbaImage::from_fn(w, h, |x, y| {
            image::Rgba([(x * 7) as u8, (y * 3) as u8, (x ^ y) as u8, (x + y) as u8])
        }));
        let whole: Vec<u8> = img
            .to_rgba32f()
            .pixels()
            .map(|p| {
                let luma = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
                let a = p[3].clamp(0.0, 1.0);
                ((a * luma + (1.0 - a)) * 255.0).round().clamp(0.0, 255.0) as u8
            })
            .collect();
        assert_eq!(to_luma(&img).data, whole);
    }

    /// An `image` crate limit refusal.
    fn is_limit(err: &FileError) -> bool {
        matches!(
            err,
            FileError::Decode {
                source: image::ImageError::Limits(_),
                ..
            }
        )
    }

    #[test]
    fn the_header_is_read_before_the_pixels_and_limits_hold() {
        let img =
            DynamicImage::ImageLuma8(image::GrayImage::from_pixel(300, 200, image::Luma([9])));
        let bytes = png(&img);
        let probe = ImageProbe::read(&bytes, Path::new("x.png")).unwrap();
        assert_eq!((probe.width, probe.height, probe.pages), (300, 200, 1));
        assert_eq!(probe.decoded_bytes, 60_000);
        let small = ImageLimits {
            max_pixels: 59_999,
            ..ImageLimits::DEFAULT
        };
        let err = DecodedImage::decode(&bytes, Path::new("x.png"), &small)
            .err()
            .unwrap();
        assert!(is_limit(&err), "{err}");
        let tight = ImageLimits {
            max_alloc: 1000,
            ..ImageLimits::DEFAULT
        };
        let err = DecodedImage::decode(&bytes, Path::new("x.png"), &tight)
            .err()
            .unwrap();
        assert!(is_limit(&err), "{err}");
        let ok = DecodedImage::decode(&bytes, Path::new("x.png"), &ImageLimits::DEFAULT).unwrap();
        assert_eq!((ok.plane.width, ok.plane.height), (300, 200));
    }

    #[test]
    fn input_longer_than_the_limit_is_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.png");
        std::fs::write(&path, vec![0u8; 1000]).unwrap();
        let err = read_input(&path, "an image", 999).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "{} is longer than 999 bytes, the most this command reads",
                path.display()
            )
        );
        assert_eq!(read_input(&path, "an image", 1000).unwrap().len(), 1000);
    }
}
