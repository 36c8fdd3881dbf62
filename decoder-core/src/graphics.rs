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
//! display: it is implemented for every colour type of embedded-graphics (grays and RGB/BGR use
//! the embedded-graphics conversion from [`Gray8`] for luma and from [`Rgb888`] for RGB;
//! a colour stream on a gray display is drawn as its luma; [`BinaryColor`] is `On` for luma
//! `>= 128`). Everything is integer arithmetic.
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
    Rgb666, Rgb888,
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
pub trait FromGray: PixelColor {
    /// The colour of luma `luma` (0 black, 255 white).
    fn from_gray(luma: u8) -> Self;

    /// The colour of an RGB pixel of a colour stream; by default, that of its luma (BT.601,
    /// as the stream's conversion).
    #[inline]
    fn from_rgb(r: u8, g: u8, b: u8) -> Self {
        Self::from_gray(rgb_to_luma(r, g, b))
    }
}

impl FromGray for Gray8 {
    #[inline]
    fn from_gray(luma: u8) -> Self {
        Gray8::new(luma)
    }
}

impl FromGray for BinaryColor {
    /// `On` for luma `>= 128`, `Off` below.
    #[inline]
    fn from_gray(luma: u8) -> Self {
        if luma >= 128 {
            BinaryColor::On
        } else {
            BinaryColor::Off
        }
    }
}

macro_rules! from_gray8 {
    ($($color:ty),*) => {
        $(impl FromGray for $color {
            /// The embedded-graphics conversion of [`Gray8`] (rounded, integer).
            #[inline]
            fn from_gray(luma: u8) -> Self {
                <$color>::from(Gray8::new(luma))
            }
        })*
    };
}

from_gray8!(Gray2, Gray4);

macro_rules! from_gray8_rgb888 {
    ($($color:ty),*) => {
        $(impl FromGray for $color {
            /// The embedded-graphics conversion of [`Gray8`] (rounded, integer).
            #[inline]
            fn from_gray(luma: u8) -> Self {
                <$color>::from(Gray8::new(luma))
            }

            /// The embedded-graphics conversion of [`Rgb888`] (integer).
            #[inline]
            fn from_rgb(r: u8, g: u8, b: u8) -> Self {
                <$color>::from(Rgb888::new(r, g, b))
            }
        })*
    };
}

from_gray8_rgb888!(Rgb555, Bgr555, Rgb565, Bgr565, Rgb666, Bgr666, Rgb888, Bgr888);

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
            color: PhantomData,
        })
    }

    /// The same image drawn at `scale` of its coded size (see [`Scale`]): its size, and the
    /// coordinates of [`ImageDrawable::draw_sub_image`], are those of the scaled image. A
    /// thumbnail at [`Scale::Quarter`] costs a fraction of the full decode.
    pub fn with_scale(self, scale: Scale) -> Self {
        PifsImage { scale, ..self }
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
        draw_area(self.decoder(), target, &all)
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
        draw_area(self.decoder(), target, area)
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
            let step = usize::from(tile.channels.max(1));
            let luma = tile.pixels.chunks_exact(step).map(|p| match *p {
                [r, g, b] => rgb_to_luma(r, g, b),
                _ => p[0],
            });
            self.target
                .fill_contiguous(&area, luma.map(|l| map(u16::from(l))))
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

fn ignore_decode_errors<E>(r: Result<(), DrawError<E>>) -> Result<(), E> {
    match r {
        Err(DrawError::Sink(e)) => Err(e),
        _ => Ok(()),
    }
}

/// Decodes a stream read sequentially from `source` (see [`Decoder::from_source`]) straight
/// onto `target`, with the image's top-left corner at the target's origin. Returns the header.
///
/// Unlike [`PifsImage`], the stream cannot be replayed, so everything is read even when only a
/// part of the image is visible, and the checksum is checked at the end, after drawing.
pub fn draw_stream<B, D>(source: B, target: &mut D) -> Result<Header, DrawError<D::Error>>
where
    B: ByteSource,
    D: DrawTarget,
    D::Color: FromGray,
{
    let decoder = Decoder::from_source(source)?;
    let header = *decoder.header();
    let size = Size::new(header.width.into(), header.height.into());
    draw_area(decoder, target, &Rectangle::new(Point::zero(), size))?;
    Ok(header)
}

/// Draws `area` (image coordinates) of the image `decoder` decodes, with `area`'s top-left
/// corner at the target's origin. A payload whose checksum is still to be verified is read to
/// its end even when nothing of it is visible.
fn draw_area<I, D, const STRIPE: usize>(
    decoder: Decoder<I, fn(&LeafInfo), STRIPE>,
    target: &mut D,
    area: &Rectangle,
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
    let mut sink = TargetSink { target, offset };
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

/// Forwards decoded tiles to a draw target, translated by `-offset`.
struct TargetSink<'t, D: DrawTarget> {
    target: &'t mut D,
    offset: Point,
}

impl<D> PixelSink for TargetSink<'_, D>
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
        if tile.channels == 3 {
            let colors = tile
                .pixels
                .chunks_exact(3)
                .map(|p| D::Color::from_rgb(p[0], p[1], p[2]));
            self.target.fill_contiguous(&area, colors)
        } else {
            let colors = tile.pixels.iter().map(|&l| D::Color::from_gray(l));
            self.target.fill_contiguous(&area, colors)
        }
    }
}
