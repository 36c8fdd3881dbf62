//! [`embedded-graphics`](https://docs.rs/embedded-graphics) support (cargo feature
//! `embedded-graphics`): a PIFS stream as an [`ImageDrawable`].
//!
//! ```
//! use decoder_core::{graphics::PifsImage, DrawError};
//! use embedded_graphics::{image::Image, pixelcolor::Rgb565, prelude::*};
//!
//! fn show<D>(stream: &[u8], display: &mut D) -> Result<(), DrawError<D::Error>>
//! where
//!     D: DrawTarget<Color = Rgb565>,
//! {
//!     // Checks the header, the length and the checksum once; drawing never panics.
//!     let logo = PifsImage::new(stream)?;
//!     Image::new(&logo, Point::new(10, 20))
//!         .draw(display)
//!         .map_err(DrawError::Sink)
//! }
//! # let mut display = embedded_graphics::mock_display::MockDisplay::<Rgb565>::new();
//! # assert!(show(b"not a stream", &mut display).is_err());
//! ```
//!
//! Pixels reach the display as whole tiles (at most [`TILE`](crate::TILE) x
//! [`TILE`](crate::TILE)) through [`DrawTarget::fill_contiguous`], never pixel by pixel.
//! Only tiles that are visible are synthesised: the area drawn is cut to the target's
//! [`bounding_box`](embedded_graphics_core::geometry::Dimensions::bounding_box) (an image partly off-screen) and, for
//! [`ImageDrawable::draw_sub_image`], to the sub-image. The payload is always entropy-decoded in
//! full, since the arithmetic decoder must see every bit; what is skipped is the pixel synthesis.
//! When nothing at all is visible, the stream is not read.
//!
//! # Errors while drawing
//!
//! [`PifsImage::new`] validates the header, so an image that exists has a sane size. A damaged
//! payload can still fail mid-way: the [`ImageDrawable`] methods then **stop drawing** and return
//! `Ok(())` (the [`ImageDrawable`] signature has no room for a [`DecodeError`]); the pixels of the
//! leaves decoded before the error have been drawn. They never panic. To see the error, use
//! [`PifsImage::draw_checked`] / [`PifsImage::draw_sub_image_checked`], which return a
//! [`DrawError`], or check the whole payload once with [`PifsImage::decoder`] and
//! [`Decoder::verify`] (entropy decoding only, no pixels).
//!
//! # Colours
//!
//! A grayscale stream decodes to 8-bit luma, a colour stream to 8-bit RGB (converted from
//! YCbCr as it is drawn, integer BT.601). [`FromGray`] turns either into the colour type of the
//! display: it is implemented for every colour type of embedded-graphics, and a colour stream
//! on a gray display is drawn as its luma. Everything is integer arithmetic.
//!
//! Where the display has fewer than 8 bits a channel (a 1-bit OLED as [`BinaryColor`], a
//! 4-grey e-paper as [`Gray2`], an RGB565 panel), the pixels are **dithered** by default
//! ([`Dither::Ordered`]: a 4 x 4 Bayer matrix anchored at the image's top-left pixel, see
//! [`Threshold`]): each channel takes the level below or above it in proportion, so a photo
//! stays a photo on a 1-bit display and a smooth sky keeps its shade instead of breaking into
//! bands on RGB565. [`PifsImage::with_dither`]`(`[`Dither::Nearest`]`)` draws the nearest level
//! instead (the same levels as embedded-graphics' conversions from [`Gray8`] and [`Rgb888`];
//! [`BinaryColor`] `On` for luma `>= 128`). Displays of 8 bits a channel ([`Gray8`],
//! [`Rgb888`], [`Bgr888`]) take the pixels as they are either way.
//!
//! # Packets as they arrive
//!
//! [`DrawSink`] draws any decode of one's own, such as radio packets ([`crate::Packet`]) as
//! they come in, each region where it lies in the image and a preview around the regions
//! already shown, dithered as the whole picture would be:
//!
//! ```
//! use decoder_core::graphics::DrawSink;
//! use decoder_core::{DrawError, Packet, PacketKind, Rect};
//! use embedded_graphics::pixelcolor::BinaryColor;
//! use embedded_graphics::prelude::*;
//!
//! /// Draws one received packet on a 1-bit OLED; `drawn` holds the regions shown so far.
//! fn on_packet<D: DrawTarget<Color = BinaryColor>>(
//!     display: &mut D,
//!     received: &[u8],
//!     drawn: &mut [Rect; 32],
//!     shown: &mut usize,
//! ) -> Result<(), DrawError<D::Error>> {
//!     let packet = Packet::parse(received)?; // its CRC first: a damaged packet is lost
//!     let mut sink = DrawSink::new(display);
//!     match packet.kind {
//!         PacketKind::Preview => packet.decode_around(&drawn[..*shown], &mut sink),
//!         PacketKind::Region => {
//!             packet.decode(&mut sink)?;
//!             if let Some(slot) = drawn.get_mut(*shown) {
//!                 *slot = packet.region;
//!                 *shown += 1;
//!             }
//!             Ok(())
//!         }
//!     }
//! }
//! # let mut display = embedded_graphics::mock_display::MockDisplay::<BinaryColor>::new();
//! # let _ = on_packet(&mut display, b"not a packet", &mut [Rect::of_size(0, 0); 32], &mut 0);
//! ```
//!
//! # 16-bit streams
//!
//! A [`PifsImage`] of a 16-bit stream (an elevation model, say) draws its values mapped onto
//! grey, as the stream maps them. [`PifsImage::with_values`] draws them through a mapping of
//! the caller's instead, from the value (in the data's units) to the display's colour: a
//! colour ramp, bands of height, a different grey scale.

use core::marker::PhantomData;

use embedded_graphics_core::draw_target::DrawTarget;
use embedded_graphics_core::geometry::{Dimensions, OriginDimensions, Point, Size};
use embedded_graphics_core::image::ImageDrawable;
use embedded_graphics_core::pixelcolor::{
    Bgr555, Bgr565, Bgr666, Bgr888, BinaryColor, Gray2, Gray4, Gray8, PixelColor, Rgb555, Rgb565,
    Rgb666, Rgb888, RgbColor,
};
use embedded_graphics_core::primitives::Rectangle;

use crate::colour::rgb_to_luma;
use crate::decoder::{Decoder, Input};
use crate::entropy::ByteSource;
use crate::error::{DecodeError, DrawError};
use crate::format::DEFAULT_STRIPE;
use crate::geometry::Rect;
use crate::syntax::Header;
use crate::synthesis::{PixelSink, Scale, Tile};
use crate::walk::LeafInfo;

/// A colour type that decoded 8-bit luma (and RGB) can be drawn as.
///
/// A colour of fewer than 8 bits a channel reaches its levels through a [`Threshold`]: the
/// nearest level ([`Threshold::NEAREST`], what [`FromGray::from_gray`] and
/// [`FromGray::from_rgb`] give) or the level an ordered dither gives at the pixel's position
/// ([`Threshold::ordered`]).
pub trait FromGray: PixelColor {
    /// Whether the colour has fewer than 8 bits a channel, so that the threshold of
    /// [`FromGray::from_gray_with`] matters (a drawing skips the pixels' positions otherwise).
    const DITHERED: bool = false;

    /// The nearest colour to luma `luma` (0 black, 255 white).
    fn from_gray(luma: u8) -> Self;

    /// The nearest colour to an RGB pixel of a colour stream; by default, that of its luma
    /// (BT.601, as the stream's conversion).
    #[inline]
    fn from_rgb(r: u8, g: u8, b: u8) -> Self {
        Self::from_gray(rgb_to_luma(r, g, b))
    }

    /// The colour of luma `luma` with each channel at the level `threshold` gives
    /// ([`Threshold::level`]); by default [`FromGray::from_gray`].
    #[inline]
    fn from_gray_with(luma: u8, threshold: Threshold) -> Self {
        let _ = threshold;
        Self::from_gray(luma)
    }

    /// The colour of an RGB pixel with each channel at the level `threshold` gives; by default
    /// [`FromGray::from_rgb`].
    #[inline]
    fn from_rgb_with(r: u8, g: u8, b: u8, threshold: Threshold) -> Self {
        let _ = threshold;
        Self::from_rgb(r, g, b)
    }
}

/// How decoded 8-bit pixels become a colour of fewer bits a channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Dither {
    /// Ordered dithering ([`Threshold::ordered`]): each channel takes the level below or above
    /// it in proportion, so a ramp keeps its shade on a display with few levels. The default.
    #[default]
    Ordered,
    /// The nearest level ([`Threshold::NEAREST`]).
    Nearest,
}

/// Where a channel value falls to one of the levels `0..=max` of a colour of few levels:
/// `floor(value max / 255 + t)`, `t` between 0 and 1 in units of `2^-16` (see
/// [`Threshold::level`]): a half for the nearest level, the pixel's rank in a 4 x 4 Bayer
/// matrix for ordered dithering.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Threshold(u16);

/// A 4 x 4 Bayer matrix of thresholds, `(2 k + 1) / 32` for the rank `k`, row-major by row
/// and column modulo 4 (index `4 (y & 3) + (x & 3)`).
const ORDERED: [Threshold; 16] = {
    const RANKS: [u16; 16] = [0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5];
    let mut table = [Threshold(0); 16];
    let mut i = 0;
    while i < 16 {
        table[i] = Threshold(2048 * (2 * RANKS[i] + 1));
        i += 1;
    }
    table
};

/// [`ORDERED`]'s shape with every threshold a half: the nearest level everywhere.
const NEAREST: [Threshold; 16] = [Threshold::NEAREST; 16];

impl Threshold {
    /// A half: the nearest level (rounded as embedded-graphics' conversions round; a
    /// [`BinaryColor`] is `On` from luma 128).
    pub const NEAREST: Threshold = Threshold(32768);

    /// The ordered-dither threshold of pixel `(x, y)` of the image: `(2 k + 1) / 32`, `k` its
    /// rank in a 4 x 4 Bayer matrix. Over every 4 x 4 block of pixels the mean level of a
    /// value is its exact level `value max / 255` to within 1/32 of a level.
    #[inline]
    pub fn ordered(x: u32, y: u32) -> Threshold {
        ORDERED[((y & 3) << 2 | (x & 3)) as usize]
    }

    /// The level of channel value `value` (0 to 255) on a scale of `0..=max`:
    /// `(257 value max + t) >> 16`, `t` this threshold in units of `2^-16` (`257 / 2^16` stands
    /// for `1 / 255`); 0 and 255 stay the ends.
    #[inline]
    pub fn level(self, value: u8, max: u8) -> u8 {
        // At most 257 * 255 * 255 + 65535, within u32; the result is at most `max`.
        ((257 * u32::from(value) * u32::from(max) + u32::from(self.0)) >> 16) as u8
    }
}

impl FromGray for Gray8 {
    #[inline]
    fn from_gray(luma: u8) -> Self {
        Gray8::new(luma)
    }
}

macro_rules! from_gray_levels {
    ($($color:ty: $max:expr => $make:expr),*) => {
        $(impl FromGray for $color {
            const DITHERED: bool = true;

            /// The nearest level: as the embedded-graphics conversion of [`Gray8`] (a
            /// [`BinaryColor`] is `On` for luma `>= 128`).
            #[inline]
            fn from_gray(luma: u8) -> Self {
                Self::from_gray_with(luma, Threshold::NEAREST)
            }

            #[inline]
            fn from_gray_with(luma: u8, threshold: Threshold) -> Self {
                $make(threshold.level(luma, $max))
            }

            #[inline]
            fn from_rgb_with(r: u8, g: u8, b: u8, threshold: Threshold) -> Self {
                Self::from_gray_with(rgb_to_luma(r, g, b), threshold)
            }
        })*
    };
}

from_gray_levels!(
    BinaryColor: 1 => |level: u8| BinaryColor::from(level == 1),
    Gray2: 3 => Gray2::new,
    Gray4: 15 => Gray4::new
);

macro_rules! from_rgb_levels {
    ($($color:ty),*) => {
        $(impl FromGray for $color {
            const DITHERED: bool = true;

            /// The nearest levels, as the embedded-graphics conversion of [`Gray8`].
            #[inline]
            fn from_gray(luma: u8) -> Self {
                Self::from_rgb_with(luma, luma, luma, Threshold::NEAREST)
            }

            /// The nearest levels, as the embedded-graphics conversion of [`Rgb888`].
            #[inline]
            fn from_rgb(r: u8, g: u8, b: u8) -> Self {
                Self::from_rgb_with(r, g, b, Threshold::NEAREST)
            }

            #[inline]
            fn from_gray_with(luma: u8, threshold: Threshold) -> Self {
                Self::from_rgb_with(luma, luma, luma, threshold)
            }

            #[inline]
            fn from_rgb_with(r: u8, g: u8, b: u8, threshold: Threshold) -> Self {
                <$color>::new(
                    threshold.level(r, <$color>::MAX_R),
                    threshold.level(g, <$color>::MAX_G),
                    threshold.level(b, <$color>::MAX_B),
                )
            }
        })*
    };
}

from_rgb_levels!(Rgb555, Bgr555, Rgb565, Bgr565, Rgb666, Bgr666);

macro_rules! from_rgb_exact {
    ($($color:ty),*) => {
        $(impl FromGray for $color {
            #[inline]
            fn from_gray(luma: u8) -> Self {
                <$color>::new(luma, luma, luma)
            }

            #[inline]
            fn from_rgb(r: u8, g: u8, b: u8) -> Self {
                <$color>::new(r, g, b)
            }
        })*
    };
}

from_rgb_exact!(Rgb888, Bgr888);

/// A PIFS stream held in memory (flash or RAM), drawable with embedded-graphics in colour `C`.
///
/// Creating one parses and validates the header; every draw decodes the stream again, tile by
/// tile, without a frame buffer (the decoder's state lives on the stack only while drawing).
/// `C` is usually inferred from the draw target. `STRIPE` is the widest stripe the drawing
/// holds (a byte per column, two in colour, on the stack while drawing): 512 from
/// [`PifsImage::new`], more from [`PifsImage::with_stripe_capacity`] for a stream of a wider
/// image coded as one stripe.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PifsImage<'a, C = Gray8, const STRIPE: usize = DEFAULT_STRIPE> {
    payload: &'a [u8],
    header: Header,
    scale: Scale,
    dither: Dither,
    color: PhantomData<C>,
}

impl<'a, C> PifsImage<'a, C> {
    /// Wraps the stream `data`, after checking its header, its length and its checksum (so a
    /// damaged stream is refused here, before anything is drawn), and that its stripes fit the
    /// 512 columns the drawing holds ([`DecodeError::StripeTooWide`], where the drawing would
    /// have stopped before its first pixel).
    pub fn new(data: &'a [u8]) -> Result<Self, DecodeError> {
        Self::wrap(data)
    }

    /// [`PifsImage::new`] for a drawing that holds stripes of up to `N` pixels (`N` bytes of
    /// stack while drawing, `2 N` in colour): `PifsImage::with_stripe_capacity::<1024>(data)`
    /// draws a stream of an image up to 1024 pixels wide coded as one stripe.
    pub fn with_stripe_capacity<const N: usize>(
        data: &'a [u8],
    ) -> Result<PifsImage<'a, C, N>, DecodeError> {
        PifsImage::wrap(data)
    }
}

impl<'a, C, const STRIPE: usize> PifsImage<'a, C, STRIPE> {
    /// [`PifsImage::new`] for stripes of up to `STRIPE` pixels.
    fn wrap(data: &'a [u8]) -> Result<Self, DecodeError> {
        let header = *Decoder::new(data)?.header();
        let (stripe, capacity) = (header.stripe_width(), STRIPE as u32);
        if stripe > capacity {
            return Err(DecodeError::StripeTooWide { stripe, capacity });
        }
        Ok(PifsImage {
            // `Decoder::new` checked that the stream holds its header and payload.
            payload: data.get(header.encoded_len()..).unwrap_or_default(),
            header,
            scale: Scale::One,
            dither: Dither::Ordered,
            color: PhantomData,
        })
    }

    /// The same image drawn at `scale` of its coded size (see [`Scale`]): its size, and the
    /// coordinates of [`ImageDrawable::draw_sub_image`], are those of the scaled image. A
    /// thumbnail at [`Scale::Quarter`] costs a fraction of the full decode.
    pub fn with_scale(self, scale: Scale) -> Self {
        PifsImage { scale, ..self }
    }

    /// The same image drawn with `dither` (see [`Dither`]; [`Dither::Ordered`] unless told).
    pub fn with_dither(self, dither: Dither) -> Self {
        PifsImage { dither, ..self }
    }

    /// The stream's header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// A decoder of the stream (already checked: this does not check it again), for decoding
    /// into a sink or a buffer rather than a draw target.
    pub fn decoder(&self) -> Decoder<crate::decoder::InMemory<'a>, fn(&LeafInfo), STRIPE> {
        Decoder::verified(self.header, self.payload)
            .stripe_capacity::<STRIPE>()
            .scale(self.scale)
    }
}

impl<C: FromGray, const STRIPE: usize> PifsImage<'_, C, STRIPE> {
    /// Draws the image with its top-left corner at the target's origin, like
    /// [`ImageDrawable::draw`], but reports decoding errors.
    pub fn draw_checked<D>(&self, target: &mut D) -> Result<(), DrawError<D::Error>>
    where
        D: DrawTarget<Color = C>,
    {
        let all = Rectangle::new(Point::zero(), self.size());
        draw_area(self.decoder(), target, &all, self.dither)
    }

    /// Draws the part `area` (image coordinates) of the image with `area`'s top-left corner at
    /// the target's origin, like [`ImageDrawable::draw_sub_image`], but reports decoding
    /// errors.
    pub fn draw_sub_image_checked<D>(
        &self,
        target: &mut D,
        area: &Rectangle,
    ) -> Result<(), DrawError<D::Error>>
    where
        D: DrawTarget<Color = C>,
    {
        draw_area(self.decoder(), target, area, self.dither)
    }
}

impl<'a, const STRIPE: usize> PifsImage<'a, Gray8, STRIPE> {
    /// The image drawn through `map`, from each pixel's value to a colour (see the
    /// [module documentation](self#16-bit-streams)): a 16-bit stream's values
    /// ([`Tile::values`]), an 8-bit stream's pixels (0 to 255, the luma of a colour stream).
    pub fn with_values<C, F>(self, map: F) -> ValueImage<'a, F, STRIPE>
    where
        C: PixelColor,
        F: Fn(u16) -> C,
    {
        ValueImage { image: self, map }
    }
}

/// A PIFS stream drawn through a mapping from values to colours ([`PifsImage::with_values`]).
#[derive(Debug, Clone, Copy)]
pub struct ValueImage<'a, F, const STRIPE: usize = DEFAULT_STRIPE> {
    image: PifsImage<'a, Gray8, STRIPE>,
    map: F,
}

impl<F, const STRIPE: usize> ValueImage<'_, F, STRIPE> {
    /// Draws the part `area` of the image at the target's origin, reporting decoding errors
    /// (see [`PifsImage::draw_sub_image_checked`]).
    pub fn draw_sub_image_checked<C, D>(
        &self,
        target: &mut D,
        area: &Rectangle,
    ) -> Result<(), DrawError<D::Error>>
    where
        C: PixelColor,
        F: Fn(u16) -> C,
        D: DrawTarget<Color = C>,
    {
        let offset = area.top_left;
        let Some(clip) = visible_clip(&self.image.decoder(), target, area) else {
            return Ok(());
        };
        let mut sink = ValueSink {
            target,
            offset,
            map: &self.map,
        };
        self.image.decoder().clip(clip).decode(&mut sink)?;
        Ok(())
    }
}

impl<F, const STRIPE: usize> OriginDimensions for ValueImage<'_, F, STRIPE> {
    fn size(&self) -> Size {
        self.image.size()
    }
}

impl<C: PixelColor, F: Fn(u16) -> C, const STRIPE: usize> ImageDrawable
    for ValueImage<'_, F, STRIPE>
{
    type Color = C;

    /// Draws the image; a decoding error stops the drawing silently.
    fn draw<D>(&self, target: &mut D) -> Result<(), D::Error>
    where
        D: DrawTarget<Color = C>,
    {
        let all = Rectangle::new(Point::zero(), self.size());
        ignore_decode_errors(self.draw_sub_image_checked(target, &all))
    }

    /// Draws the part `area` of the image at the target's origin; decoding errors stop the
    /// drawing silently.
    fn draw_sub_image<D>(&self, target: &mut D, area: &Rectangle) -> Result<(), D::Error>
    where
        D: DrawTarget<Color = C>,
    {
        ignore_decode_errors(self.draw_sub_image_checked(target, area))
    }
}

/// Forwards decoded tiles to a draw target through a mapping of their values.
struct ValueSink<'t, D, F> {
    target: &'t mut D,
    offset: Point,
    map: &'t F,
}

impl<D, F> PixelSink for ValueSink<'_, D, F>
where
    D: DrawTarget,
    F: Fn(u16) -> D::Color,
{
    type Error = D::Error;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), D::Error> {
        let Rect { x, y, w, h } = tile.area;
        let at = Point::new(x as i32, y as i32) - self.offset;
        let area = Rectangle::new(at, Size::new(w, h));
        let map = self.map;
        if tile.values.is_empty() {
            if tile.channels == 3 {
                let luma = triples(tile.pixels).map(|p| rgb_to_luma(p[0], p[1], p[2]));
                self.target
                    .fill_contiguous(&area, luma.map(|l| map(u16::from(l))))
            } else {
                let luma = tile.pixels.iter();
                self.target
                    .fill_contiguous(&area, luma.map(|&l| map(u16::from(l))))
            }
        } else {
            let colors = tile.values.iter().map(|&v| map(v));
            self.target.fill_contiguous(&area, colors)
        }
    }
}

impl<C, const STRIPE: usize> OriginDimensions for PifsImage<'_, C, STRIPE> {
    fn size(&self) -> Size {
        Size::new(
            self.scale.apply(self.header.width.into()),
            self.scale.apply(self.header.height.into()),
        )
    }
}

impl<C: FromGray, const STRIPE: usize> ImageDrawable for PifsImage<'_, C, STRIPE> {
    type Color = C;

    /// Draws the image; a decoding error stops the drawing silently (see the
    /// [module documentation](self)); the target's first error is returned.
    fn draw<D>(&self, target: &mut D) -> Result<(), D::Error>
    where
        D: DrawTarget<Color = C>,
    {
        ignore_decode_errors(self.draw_checked(target))
    }

    /// Draws the part `area` of the image at the target's origin, synthesising only the tiles
    /// that intersect `area`; decoding errors stop the drawing silently.
    fn draw_sub_image<D>(&self, target: &mut D, area: &Rectangle) -> Result<(), D::Error>
    where
        D: DrawTarget<Color = Self::Color>,
    {
        ignore_decode_errors(self.draw_sub_image_checked(target, area))
    }
}

/// The RGB pixels of a colour tile, three bytes each: taken three at a time, where
/// `chunks_exact(3)` divides the length by 3 (a routine call on a Cortex-M0). By reference:
/// an array value is packed into a word and unpacked again.
fn triples(pixels: &[u8]) -> Triples<'_> {
    Triples { rest: pixels }
}

/// The iterator of [`triples`].
struct Triples<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for Triples<'a> {
    type Item = &'a [u8; 3];

    #[inline(always)]
    fn next(&mut self) -> Option<&'a [u8; 3]> {
        let (pixel, tail) = self.rest.split_first_chunk::<3>()?;
        self.rest = tail;
        Some(pixel)
    }
}

fn ignore_decode_errors<E>(r: Result<(), DrawError<E>>) -> Result<(), E> {
    match r {
        Err(DrawError::Sink(e)) => Err(e),
        _ => Ok(()),
    }
}

/// Decodes a stream read sequentially from `source` (see [`Decoder::from_source`]) straight
/// onto `target`, with the image's top-left corner at the target's origin, dithered
/// ([`Dither::Ordered`]). Returns the header.
///
/// Unlike [`PifsImage`], the stream cannot be replayed, so everything is read even when only a
/// part of the image is visible, and the checksum is checked at the end, after drawing.
pub fn draw_stream<B, D>(source: B, target: &mut D) -> Result<Header, DrawError<D::Error>>
where
    B: ByteSource,
    D: DrawTarget,
    D::Color: FromGray,
{
    draw_stream_with(source, target, Dither::Ordered)
}

/// [`draw_stream`] with `dither` (see [`Dither`]).
pub fn draw_stream_with<B, D>(
    source: B,
    target: &mut D,
    dither: Dither,
) -> Result<Header, DrawError<D::Error>>
where
    B: ByteSource,
    D: DrawTarget,
    D::Color: FromGray,
{
    let decoder = Decoder::from_source(source)?;
    let header = *decoder.header();
    let size = Size::new(header.width.into(), header.height.into());
    draw_area(
        decoder,
        target,
        &Rectangle::new(Point::zero(), size),
        dither,
    )?;
    Ok(header)
}

/// Draws `area` (image coordinates) of the image `decoder` decodes, with `area`'s top-left
/// corner at the target's origin. A payload whose checksum is still to be verified is read to
/// its end even when nothing of it is visible.
fn draw_area<I, D, const STRIPE: usize>(
    decoder: Decoder<I, fn(&LeafInfo), STRIPE>,
    target: &mut D,
    area: &Rectangle,
    dither: Dither,
) -> Result<(), DrawError<D::Error>>
where
    I: Input,
    D: DrawTarget,
    D::Color: FromGray,
{
    let offset = area.top_left;
    let Some(clip) = visible_clip(&decoder, target, area) else {
        return Ok(());
    };
    let mut sink = DrawSink {
        target,
        offset,
        dither,
    };
    decoder.clip(clip).decode(&mut sink)?;
    Ok(())
}

/// The part of `area` (image coordinates) of `decoder`'s image that `target` shows, with
/// `area`'s top-left corner at the target's origin; `None` when nothing is and the stream
/// need not be read (an empty clip when its checksum is still to be verified).
fn visible_clip<I: Input, D: Dimensions, const STRIPE: usize>(
    decoder: &Decoder<I, fn(&LeafInfo), STRIPE>,
    target: &D,
    area: &Rectangle,
) -> Option<Rect> {
    let (width, height) = decoder.output_size();
    let image = Rectangle::new(Point::zero(), Size::new(width, height));
    // The target's visible area, in image coordinates.
    let visible = target.bounding_box();
    let visible = Rectangle::new(visible.top_left + area.top_left, visible.size);
    let clip = area.intersection(&image).intersection(&visible);
    if clip.is_zero_sized() || clip.top_left.x < 0 || clip.top_left.y < 0 {
        return (!I::VERIFIED).then(|| Rect::of_size(0, 0));
    }
    Some(Rect {
        x: clip.top_left.x as u32,
        y: clip.top_left.y as u32,
        w: clip.size.width,
        h: clip.size.height,
    })
}

/// The dither thresholds of a tile's pixels, row by row: a row's four thresholds packed as
/// ranks in the bytes of one word ([`packed_rows`]), rotated a byte per pixel (one register
/// on a Cortex-M0).
struct Thresholds {
    /// The table's rows, packed.
    rows: &'static [u32; 4],
    /// The current row's thresholds from the next pixel's on.
    row: u32,
    /// Pixels left in the current row, and in every row.
    left: u32,
    width: u32,
    /// The rotation that starts a row at the tile's first column (`8 (x & 3)`).
    turn: u32,
    /// The next row's `y`.
    y: u32,
}

impl Thresholds {
    /// The thresholds of a tile of `width` pixels a row from image pixel `(x, y)`, from the
    /// packed rows of a table.
    fn new(rows: &'static [u32; 4], x: u32, y: u32, width: u32) -> Thresholds {
        Thresholds {
            rows,
            row: 0,
            left: 0,
            width,
            turn: 8 * (x & 3),
            y,
        }
    }
}

impl Iterator for Thresholds {
    type Item = Threshold;

    #[inline]
    fn next(&mut self) -> Option<Threshold> {
        if self.left == 0 {
            self.row = self.rows[(self.y & 3) as usize].rotate_right(self.turn);
            self.left = self.width;
            self.y += 1;
        }
        // Wrapping: a tile of no width has no pixels to ask for thresholds.
        self.left = self.left.wrapping_sub(1);
        let t = Threshold(((self.row & 0xFF) << 11) as u16);
        self.row = self.row.rotate_right(8);
        Some(t)
    }
}

/// A 4 x 4 table's rows, each row's thresholds as ranks (`threshold >> 11`, exact for the
/// tables here: multiples of 2048 below 65536) in the bytes of a word, column 0 lowest.
const fn packed_rows(table: &[Threshold; 16]) -> [u32; 4] {
    let mut rows = [0u32; 4];
    let mut i = 0;
    while i < 16 {
        rows[i / 4] |= ((table[i].0 >> 11) as u32) << (8 * (i % 4));
        i += 1;
    }
    rows
}

/// [`ORDERED`] and [`NEAREST`], packed.
const ORDERED_ROWS: [u32; 4] = packed_rows(&ORDERED);
const NEAREST_ROWS: [u32; 4] = packed_rows(&NEAREST);

/// A [`PixelSink`] that draws decoded tiles onto an embedded-graphics target in its colours,
/// dithered ([`Dither`]) by the pixels' image coordinates: what [`PifsImage`] draws through,
/// for decodes of one's own, such as packets as they arrive (`packet.decode(&mut
/// DrawSink::new(&mut display))`, a region drawn where it lies in the image, dithered as the
/// whole image would be) or a [`Decoder`] with a clip or a scale.
pub struct DrawSink<'t, D: DrawTarget> {
    target: &'t mut D,
    /// Subtracted from image coordinates to give the target's.
    offset: Point,
    dither: Dither,
}

impl<D: DrawTarget> core::fmt::Debug for DrawSink<'_, D> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DrawSink")
            .field("offset", &self.offset)
            .field("dither", &self.dither)
            .finish_non_exhaustive()
    }
}

impl<'t, D: DrawTarget> DrawSink<'t, D> {
    /// Draws image pixel `(x, y)` at `(x, y)` of `target`, ordered-dithered.
    pub fn new(target: &'t mut D) -> Self {
        DrawSink {
            target,
            offset: Point::zero(),
            dither: Dither::Ordered,
        }
    }

    /// The same sink with `dither`.
    pub fn with_dither(self, dither: Dither) -> Self {
        DrawSink { dither, ..self }
    }
}

impl<D> PixelSink for DrawSink<'_, D>
where
    D: DrawTarget,
    D::Color: FromGray,
{
    type Error = D::Error;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), D::Error> {
        let Rect { x, y, w, h } = tile.area;
        // Tile coordinates are below 2^16 (image coordinates), so they fit in i32.
        let at = Point::new(x as i32, y as i32) - self.offset;
        let area = Rectangle::new(at, Size::new(w, h));
        if !D::Color::DITHERED {
            // Eight bits a channel: the pixels as they are, whatever the dither.
            return if tile.channels == 3 {
                let colors = triples(tile.pixels).map(|p| D::Color::from_rgb(p[0], p[1], p[2]));
                self.target.fill_contiguous(&area, colors)
            } else {
                let colors = tile.pixels.iter().map(|&l| D::Color::from_gray(l));
                self.target.fill_contiguous(&area, colors)
            };
        }
        // One way for both dithers: the nearest level is the threshold of a half everywhere.
        let rows = match self.dither {
            Dither::Ordered => &ORDERED_ROWS,
            Dither::Nearest => &NEAREST_ROWS,
        };
        let mut thresholds = Thresholds::new(rows, x, y, w);
        if tile.channels == 3 {
            let colors = triples(tile.pixels).map(|p| {
                let t = thresholds.next().unwrap_or(Threshold::NEAREST);
                D::Color::from_rgb_with(p[0], p[1], p[2], t)
            });
            self.target.fill_contiguous(&area, colors)
        } else {
            let colors = tile.pixels.iter().map(|&l| {
                let t = thresholds.next().unwrap_or(Threshold::NEAREST);
                D::Color::from_gray_with(l, t)
            });
            self.target.fill_contiguous(&area, colors)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthesis::TILE;

    /// A tile's thresholds, stepped along its rows, are the table's at each pixel's image
    /// coordinates, for every phase of the tile's corner and every width.
    #[test]
    fn thresholds_follow_the_pixels_coordinates() {
        for (rows, table) in [(&ORDERED_ROWS, &ORDERED), (&NEAREST_ROWS, &NEAREST)] {
            for (x, y) in (0..8).flat_map(|x| (0..8).map(move |y| (x, y))) {
                for w in 1..=TILE as u32 {
                    let mut thresholds = Thresholds::new(rows, x, y, w);
                    for j in 0..TILE as u32 {
                        for i in 0..w {
                            let at = ((y + j) & 3) << 2 | ((x + i) & 3);
                            assert_eq!(
                                thresholds.next(),
                                Some(table[at as usize]),
                                "({x}, {y}) width {w}, pixel ({i}, {j})"
                            );
                        }
                    }
                }
            }
        }
        assert_eq!(Threshold::ordered(5, 6), ORDERED[2 << 2 | 1]);
    }
}
