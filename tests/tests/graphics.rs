//! embedded-graphics support of decoder-core (`decoder_core::graphics`, feature
//! `embedded-graphics`), checked on the host against `decode_into`:
//!
//! - `Image::new(&PifsImage, position).draw(..)` onto `MockDisplay` (at most 64x64, so the small
//!   golden vectors) draws exactly the decoded pixels, each once (MockDisplay rejects overdraw
//!   and drawing outside the display), also when the image is partly off-screen;
//! - `draw_sub_image` draws exactly the area, translated to the target's origin, and only
//!   synthesises tiles that intersect it;
//! - pixels arrive through `fill_contiguous` in tiles of at most 16x16, never through
//!   `draw_iter`;
//! - colour conversion to Gray8, Rgb565, Rgb888, BinaryColor: ordered dithering by default
//!   where the colour has fewer than 8 bits a channel (each pixel `from_gray_with` /
//!   `from_rgb_with` at `Threshold::ordered` of its image position, the shade kept over every
//!   4x4 block), the nearest
//!   level with `Dither::Nearest` (luma >= 128 is On), and a caller's mapping of values
//!   (`PifsImage::with_values`: a 16-bit stream's values);
//! - damaged streams never panic, `draw_checked` reports them, target errors stop the drawing;
//! - `draw_stream` from a byte-at-a-time source draws what the in-memory image draws.
//!
//! Expected values are derived from the golden streams at test time.

mod common;

use common::{decode_all, golden_dir, golden_list};
use decoder_core::graphics::{draw_stream, Dither, FromGray, PifsImage, Threshold};
use decoder_core::DecodeError;
use decoder_core::DrawError;
use decoder_core::TILE;
use decoder_core::{ByteSource, SliceSource};
use embedded_graphics::image::{Image, ImageDrawable, ImageDrawableExt};
use embedded_graphics::mock_display::MockDisplay;
use embedded_graphics::pixelcolor::{BinaryColor, Gray8, Rgb565, Rgb888, RgbColor};
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::Rectangle;

/// A golden vector: name, stream, decoded pixels (row-major), width, height.
struct Decoded {
    name: String,
    stream: Vec<u8>,
    pixels: Vec<u8>,
    width: u32,
    height: u32,
    channels: u8,
}

impl Decoded {
    fn luma(&self, x: i32, y: i32) -> Option<u8> {
        (x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height)
            .then(|| self.pixels[y as usize * self.width as usize + x as usize])
    }

    fn image<C>(&self) -> PifsImage<'_, C> {
        PifsImage::new(&self.stream).unwrap_or_else(|e| panic!("{}: {e}", self.name))
    }
}

/// Every golden vector, decoded with `decode_into`.
fn golden() -> Vec<Decoded> {
    let list = golden_list();
    assert!(!list.is_empty(), "no golden vectors");
    list.into_iter()
        .map(|g| {
            let stream = std::fs::read(golden_dir().join(&g.file)).unwrap();
            let (header, pixels) =
                decode_all(&stream).unwrap_or_else(|e| panic!("{}: {e}", g.file));
            Decoded {
                name: g.file,
                stream,
                pixels,
                width: header.width.into(),
                height: header.height.into(),
                channels: header.channels,
            }
        })
        .filter(|d| d.channels == 1)
        .collect()
}

/// The colour golden vectors, decoded with `decode_into` (RGB).
fn colour() -> Vec<Decoded> {
    let v: Vec<Decoded> = golden_list()
        .into_iter()
        .map(|g| {
            let stream = std::fs::read(golden_dir().join(&g.file)).unwrap();
            let (header, pixels) =
                decode_all(&stream).unwrap_or_else(|e| panic!("{}: {e}", g.file));
            Decoded {
                name: g.file,
                stream,
                pixels,
                width: header.width.into(),
                height: header.height.into(),
                channels: header.channels,
            }
        })
        .filter(|d| d.channels == 3)
        .collect();
    assert!(!v.is_empty(), "no colour golden vector");
    v
}

/// A colour stream draws its RGB pixels on RGB displays (Rgb888 exactly, Rgb565 and Bgr565
/// dithered, or by the embedded-graphics conversion of them with `Dither::Nearest`) and its
/// luma on gray ones.
#[test]
fn colour_streams_draw_rgb_on_colour_displays_and_luma_on_gray_ones() {
    use decoder_core::internal::colour::rgb_to_luma;
    use embedded_graphics::pixelcolor::Bgr565;
    for d in colour() {
        let rgb = |x: i32, y: i32| {
            let i = 3 * (y as usize * d.width as usize + x as usize);
            (d.pixels[i], d.pixels[i + 1], d.pixels[i + 2])
        };
        let mut display = MockDisplay::<Rgb888>::new();
        Image::new(&d.image::<Rgb888>(), Point::zero())
            .draw(&mut display)
            .unwrap();
        let mut display565 = MockDisplay::<Rgb565>::new();
        Image::new(&d.image::<Rgb565>(), Point::zero())
            .draw(&mut display565)
            .unwrap();
        let mut nearest565 = MockDisplay::<Rgb565>::new();
        Image::new(
            &d.image::<Rgb565>().with_dither(Dither::Nearest),
            Point::zero(),
        )
        .draw(&mut nearest565)
        .unwrap();
        let mut display_bgr = MockDisplay::<Bgr565>::new();
        Image::new(&d.image::<Bgr565>(), Point::zero())
            .draw(&mut display_bgr)
            .unwrap();
        let mut gray = MockDisplay::<Gray8>::new();
        Image::new(&d.image::<Gray8>(), Point::zero())
            .draw(&mut gray)
            .unwrap();
        let mut colourful = 0;
        for y in 0..d.height as i32 {
            for x in 0..d.width as i32 {
                let p = Point::new(x, y);
                let (r, g, b) = rgb(x, y);
                colourful += usize::from(r != g || g != b);
                let c = Rgb888::new(r, g, b);
                assert_eq!(display.get_pixel(p), Some(c), "{}: {p:?}", d.name);
                let (px, py) = (x as u32, y as u32);
                assert_eq!(
                    display565.get_pixel(p),
                    Some(Rgb565::from_rgb_with(r, g, b, Threshold::ordered(px, py))),
                    "{}",
                    d.name
                );
                assert_eq!(nearest565.get_pixel(p), Some(Rgb565::from(c)), "{}", d.name);
                assert_eq!(
                    display_bgr.get_pixel(p),
                    Some(Bgr565::from_rgb_with(r, g, b, Threshold::ordered(px, py))),
                    "{}",
                    d.name
                );
                assert_eq!(
                    gray.get_pixel(p),
                    Some(Gray8::new(rgb_to_luma(r, g, b))),
                    "{}",
                    d.name
                );
            }
        }
        assert!(
            colourful > (d.width * d.height / 2) as usize,
            "{}: mostly gray",
            d.name
        );
    }
}

/// The golden vectors that fit a MockDisplay (64x64).
fn small() -> Vec<Decoded> {
    let v: Vec<Decoded> = golden()
        .into_iter()
        .filter(|d| d.width <= 64 && d.height <= 64)
        .collect();
    assert!(
        v.len() >= 2,
        "fewer than two golden vectors of at most 64x64"
    );
    v
}

/// What a 64x64 display shows when `d` is drawn with the top-left of `area` (image
/// coordinates) at `at`, in colour `C`.
fn expected<C: FromGray>(d: &Decoded, area: Rectangle, at: Point) -> MockDisplay<C> {
    expected_with(d, area, at, Dither::Ordered)
}

/// The display `area` of `d` drawn at `at` gives with `dither`: each pixel's colour at its
/// position in the image.
fn expected_with<C: FromGray>(
    d: &Decoded,
    area: Rectangle,
    at: Point,
    dither: Dither,
) -> MockDisplay<C> {
    let mut display = MockDisplay::new();
    for y in 0..64 {
        for x in 0..64 {
            let p = Point::new(x, y) - at + area.top_left;
            if area.contains(p) {
                if let Some(l) = d.luma(p.x, p.y) {
                    let c = match dither {
                        Dither::Ordered => {
                            C::from_gray_with(l, Threshold::ordered(p.x as u32, p.y as u32))
                        }
                        Dither::Nearest => C::from_gray(l),
                    };
                    display.set_pixel(Point::new(x, y), Some(c));
                }
            }
        }
    }
    display
}

fn whole(d: &Decoded) -> Rectangle {
    Rectangle::new(Point::zero(), Size::new(d.width, d.height))
}

/// `with_values` draws each pixel's value through the caller's mapping: a 16-bit stream's
/// values (a colour ramp here), an 8-bit stream's pixels (its luma for a colour stream), each
/// once, also as a sub-image.
#[test]
fn values_draw_through_the_callers_mapping() {
    let ramp = |v: u16| Rgb565::new((v >> 11) as u8, (v >> 5) as u8 & 0x3F, v as u8 & 0x1F);
    let mut deep = 0;
    for d in small() {
        let values: Vec<u16> = common::decode_values(&d.stream)
            .unwrap()
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .collect();
        let header = decoder_core::Header::read(&d.stream).unwrap();
        deep += usize::from(header.range.is_some());
        let value = |x: i32, y: i32| -> u16 {
            let i = y as usize * d.width as usize + x as usize;
            match (header.range, d.channels) {
                (Some(_), _) => values[i],
                (None, 3) => {
                    let p = &d.pixels[3 * i..3 * i + 3];
                    u16::from(decoder_core::internal::colour::rgb_to_luma(
                        p[0], p[1], p[2],
                    ))
                }
                (None, _) => u16::from(d.pixels[i]),
            }
        };
        let img = PifsImage::new(&d.stream).unwrap().with_values(ramp);
        let area = Rectangle::new(Point::new(1, 2), Size::new(d.width - 1, d.height - 2));
        for (area, at) in [(whole(&d), Point::zero()), (area, Point::new(1, 0))] {
            let mut display = MockDisplay::<Rgb565>::new();
            Image::new(&img.sub_image(&area), at)
                .draw(&mut display)
                .unwrap();
            let mut expected = MockDisplay::new();
            for p in area.points() {
                expected.set_pixel(p - area.top_left + at, Some(ramp(value(p.x, p.y))));
            }
            display.assert_eq(&expected);
        }
    }
    assert!(deep > 0, "no 16-bit golden vector of at most 64x64");
}

#[test]
fn image_draws_the_decoded_pixels_once_each() {
    for d in small() {
        let img = d.image::<Gray8>();
        assert_eq!(img.size(), Size::new(d.width, d.height), "{}", d.name);
        let mut display = MockDisplay::<Gray8>::new();
        Image::new(&img, Point::zero()).draw(&mut display).unwrap();
        display.assert_eq(&expected(&d, whole(&d), Point::zero()));
    }
}

#[test]
fn image_at_an_offset_and_partly_off_screen_is_clipped_to_the_display() {
    for d in small() {
        let img = d.image::<Gray8>();
        let (w, h) = (d.width as i32, d.height as i32);
        for at in [
            Point::new(3, 5),
            Point::new(-7, -3),
            Point::new(64 - w / 2, 64 - h / 2),
            Point::new(-w / 2, 60),
            Point::new(64 - 1, -h + 1),
        ] {
            // MockDisplay panics on pixels outside 64x64: nothing off-screen may be drawn.
            let mut display = MockDisplay::<Gray8>::new();
            Image::new(&img, at).draw(&mut display).unwrap();
            display.assert_eq(&expected(&d, whole(&d), at));
        }
    }
}

#[test]
fn sub_images_draw_exactly_their_area_at_the_origin() {
    for d in small() {
        let img = d.image::<Gray8>();
        let (w, h) = (d.width as i32, d.height as i32);
        let areas = [
            Rectangle::new(Point::new(0, 0), Size::new(d.width, d.height)),
            Rectangle::new(
                Point::new(w / 3, h / 4),
                Size::new(d.width / 2, d.height / 2),
            ),
            Rectangle::new(Point::new(1, 1), Size::new(1, 1)),
            Rectangle::new(Point::new(w - 4, h - 3), Size::new(10, 10)),
            Rectangle::new(Point::new(-3, -2), Size::new(8, 9)),
            Rectangle::new(Point::new(0, h - 1), Size::new(d.width, 1)),
        ];
        for area in areas {
            for at in [Point::zero(), Point::new(5, 2), Point::new(-2, -1)] {
                // `sub_image` first cuts the area to the image.
                let mut display = MockDisplay::<Gray8>::new();
                Image::new(&img.sub_image(&area), at)
                    .draw(&mut display)
                    .unwrap();
                display.assert_eq(&expected(&d, whole(&d).intersection(&area), at));
                // `draw_sub_image` itself takes any area: its top-left is the target's origin.
                let mut display = MockDisplay::<Gray8>::new();
                img.draw_sub_image(&mut display.translated(at), &area)
                    .unwrap();
                display.assert_eq(&expected(&d, area, at));
            }
        }
    }
}

#[test]
fn colour_types_follow_the_conversion_rules() {
    assert_eq!(BinaryColor::from_gray(127), BinaryColor::Off);
    assert_eq!(BinaryColor::from_gray(128), BinaryColor::On);
    assert_eq!(Rgb888::from_gray(77), Rgb888::new(77, 77, 77));
    assert_eq!(Rgb565::from_gray(0), Rgb565::BLACK);
    assert_eq!(Rgb565::from_gray(255), Rgb565::WHITE);
    assert_eq!(Rgb565::from_gray(130), Rgb565::from(Gray8::new(130)));
    // The nearest levels are embedded-graphics' conversions, for every value.
    for v in 0..=255u8 {
        let c = Rgb888::new(v, 255 - v, v / 3);
        assert_eq!(Rgb565::from_rgb(v, 255 - v, v / 3), Rgb565::from(c), "{v}");
        assert_eq!(Rgb565::from_gray(v), Rgb565::from(Gray8::new(v)), "{v}");
        assert_eq!(
            embedded_graphics::pixelcolor::Gray4::from_gray(v),
            embedded_graphics::pixelcolor::Gray4::from(Gray8::new(v)),
            "{v}"
        );
    }
    for d in small() {
        let at = Point::new(-1, 2);
        let mut display = MockDisplay::<Rgb565>::new();
        Image::new(&d.image::<Rgb565>(), at)
            .draw(&mut display)
            .unwrap();
        display.assert_eq(&expected(&d, whole(&d), at));

        for dither in [Dither::Ordered, Dither::Nearest] {
            let mut display = MockDisplay::<BinaryColor>::new();
            Image::new(&d.image::<BinaryColor>().with_dither(dither), at)
                .draw(&mut display)
                .unwrap();
            display.assert_eq(&expected_with(&d, whole(&d), at, dither));
        }

        let mut display = MockDisplay::<Rgb888>::new();
        Image::new(&d.image::<Rgb888>(), at)
            .draw(&mut display)
            .unwrap();
        display.assert_eq(&expected(&d, whole(&d), at));
        for y in 0..64 {
            for x in 0..64 {
                if let (Some(c), Some(l)) = (
                    display.get_pixel(Point::new(x, y)),
                    d.luma(x - at.x, y - at.y),
                ) {
                    assert_eq!(c, Rgb888::new(l, l, l), "{}", d.name);
                }
            }
        }
    }
}

/// Ordered dithering keeps a shade: over every 4x4 block the mean dithered level of a value is
/// its exact level to within 1/32 of a level, the ends stay the ends; a picture on a 1-bit
/// display lights the share of pixels its luma says; and a sub-image is dithered as the same
/// pixels of the whole image are (the pattern belongs to the image, not to the draw).
#[test]
fn dithering_keeps_the_shade() {
    for max in [1u8, 3, 15, 31, 63] {
        for v in 0..=255u8 {
            for (ox, oy) in [(0u32, 0u32), (5, 2)] {
                let levels: Vec<u8> = (0..16)
                    .map(|k| Threshold::ordered(ox + k % 4, oy + k / 4).level(v, max))
                    .collect();
                let mean = levels.iter().map(|&l| f64::from(l)).sum::<f64>() / 16.0;
                let exact = f64::from(v) * f64::from(max) / 255.0;
                assert!(
                    (mean - exact).abs() <= 1.0 / 32.0 + 1e-3,
                    "value {v} on {max}: mean {mean}, exact {exact}"
                );
                let ends = match v {
                    0 => Some(0),
                    255 => Some(max),
                    _ => None,
                };
                if let Some(end) = ends {
                    assert!(levels.iter().all(|&l| l == end), "value {v} on {max}");
                }
            }
        }
    }
    for d in small() {
        let mut display = MockDisplay::<BinaryColor>::new();
        Image::new(&d.image::<BinaryColor>(), Point::zero())
            .draw(&mut display)
            .unwrap();
        let n = (d.width * d.height) as usize;
        let lit = (0..d.height as i32)
            .flat_map(|y| (0..d.width as i32).map(move |x| Point::new(x, y)))
            .filter(|&p| display.get_pixel(p) == Some(BinaryColor::On))
            .count();
        let shade = (0..d.height as i32)
            .flat_map(|y| (0..d.width as i32).map(move |x| (x, y)))
            .filter_map(|(x, y)| d.luma(x, y))
            .map(|l| f64::from(l) / 255.0)
            .sum::<f64>();
        assert!(
            (lit as f64 - shade).abs() <= 0.02 * n as f64,
            "{}: {lit} of {n} lit for a shade of {shade:.1}",
            d.name
        );
        let area = Rectangle::new(Point::new(3, 5), Size::new(10, 7));
        let mut part = MockDisplay::<BinaryColor>::new();
        d.image::<BinaryColor>()
            .draw_sub_image(&mut part, &area)
            .unwrap();
        part.assert_eq(&expected(&d, area, Point::zero()));
    }
}

/// A large display that records every `fill_contiguous` call and every pixel, counts pixels
/// sent through `draw_iter`, and can be told to fail after a number of calls.
struct Recorder {
    size: Size,
    fills: Vec<Rectangle>,
    pixels: Vec<Option<u8>>,
    per_pixel: usize,
    fail_after: Option<usize>,
}

#[derive(Debug, PartialEq, Eq)]
struct Broken;

impl Recorder {
    fn new(width: u32, height: u32) -> Self {
        Recorder {
            size: Size::new(width, height),
            fills: Vec::new(),
            pixels: vec![None; (width * height) as usize],
            per_pixel: 0,
            fail_after: None,
        }
    }
}

impl OriginDimensions for Recorder {
    fn size(&self) -> Size {
        self.size
    }
}

impl DrawTarget for Recorder {
    type Color = Gray8;
    type Error = Broken;

    fn draw_iter<I: IntoIterator<Item = Pixel<Gray8>>>(&mut self, pixels: I) -> Result<(), Broken> {
        self.per_pixel += pixels.into_iter().count();
        Ok(())
    }

    fn fill_contiguous<I: IntoIterator<Item = Gray8>>(
        &mut self,
        area: &Rectangle,
        colors: I,
    ) -> Result<(), Broken> {
        if self.fail_after == Some(self.fills.len()) {
            return Err(Broken);
        }
        self.fills.push(*area);
        let colors: Vec<Gray8> = colors.into_iter().collect();
        assert_eq!(colors.len() as u32, area.size.width * area.size.height);
        for (p, c) in area.points().zip(colors) {
            assert!(
                self.bounding_box().contains(p),
                "pixel {p:?} outside the target"
            );
            let i = (p.y as u32 * self.size.width + p.x as u32) as usize;
            assert!(self.pixels[i].is_none(), "pixel {p:?} drawn twice");
            self.pixels[i] = Some(c.into_storage());
        }
        Ok(())
    }
}

#[test]
fn pixels_arrive_as_tiles_through_fill_contiguous_only() {
    for d in golden() {
        let img = d.image::<Gray8>();
        let mut target = Recorder::new(d.width, d.height);
        Image::new(&img, Point::zero()).draw(&mut target).unwrap();
        assert_eq!(target.per_pixel, 0, "{}: pixels drawn one by one", d.name);
        for a in &target.fills {
            assert!(
                a.size.width as usize <= TILE && a.size.height as usize <= TILE,
                "{}: tile {a:?}",
                d.name
            );
        }
        let drawn: Vec<u8> = target
            .pixels
            .iter()
            .map(|p| p.unwrap_or_else(|| panic!("{}: pixel not drawn", d.name)))
            .collect();
        assert!(
            drawn == d.pixels,
            "{}: pixels differ from decode_into",
            d.name
        );
    }
}

#[test]
fn sub_image_and_off_screen_parts_synthesise_only_visible_tiles() {
    for d in golden() {
        let img = d.image::<Gray8>();
        let full_tiles = {
            let mut t = Recorder::new(d.width, d.height);
            img.draw(&mut t).unwrap();
            t.fills.len()
        };
        // A small area: only the tiles that intersect it arrive, cut to it.
        let area = Rectangle::new(
            Point::new(d.width as i32 / 2, d.height as i32 / 2),
            Size::new(d.width.div_ceil(4), d.height.div_ceil(4)),
        );
        let mut t = Recorder::new(area.size.width, area.size.height);
        img.draw_sub_image(&mut t, &area).unwrap();
        assert!(t.pixels.iter().all(Option::is_some), "{}", d.name);
        assert_eq!(t.per_pixel, 0);
        for (p, v) in t.bounding_box().points().zip(&t.pixels) {
            let q = p + area.top_left;
            assert_eq!(*v, d.luma(q.x, q.y), "{}", d.name);
        }
        if d.width * d.height >= 64 * 64 {
            assert!(t.fills.len() < full_tiles, "{}", d.name);
        }
        // A display smaller than the image: nothing outside it is sent.
        let mut t = Recorder::new(d.width.div_ceil(2), d.height.div_ceil(3));
        Image::new(&img, Point::new(-(d.width as i32) / 4, 0))
            .draw(&mut t)
            .unwrap();
        assert!(t.pixels.iter().all(Option::is_some), "{}", d.name);
        // Entirely off-screen: nothing at all.
        let mut t = Recorder::new(10, 10);
        Image::new(&img, Point::new(10, 0)).draw(&mut t).unwrap();
        Image::new(&img, Point::new(-(d.width as i32), 0))
            .draw(&mut t)
            .unwrap();
        assert!(t.fills.is_empty(), "{}", d.name);
    }
}

#[test]
fn damaged_streams_never_panic_and_draw_checked_reports_them() {
    for d in golden() {
        let header_len = decoder_core::Header::read(&d.stream).unwrap().encoded_len();
        // Truncated payload: refused before anything is drawn.
        let cut = &d.stream[..(header_len + 4).max(d.stream.len() * 2 / 3)];
        assert_eq!(
            PifsImage::<Gray8>::new(cut).err(),
            Some(DecodeError::Truncated),
            "{}",
            d.name
        );
        // Streamed, the same bytes draw a correct prefix of the image, then report the error.
        let mut t = Recorder::new(d.width, d.height);
        assert_eq!(
            draw_stream(SliceSource::new(cut), &mut t),
            Err(DrawError::Decode(DecodeError::Truncated)),
            "{}",
            d.name
        );
        for (i, p) in t.pixels.iter().enumerate() {
            if let Some(v) = p {
                assert_eq!(*v, d.pixels[i], "{}", d.name);
            }
        }
        // Flipped payload bytes: the checksum refuses the stream before drawing; streamed, no
        // panic and an error at the latest at the end.
        for k in 0..16 {
            let mut bad = d.stream.clone();
            let i = header_len + (k * 7919) % (bad.len() - header_len);
            bad[i] ^= 0x5A;
            assert!(
                matches!(
                    PifsImage::<Gray8>::new(&bad),
                    Err(DecodeError::ChecksumMismatch { .. })
                ),
                "{}: byte {i} flipped",
                d.name
            );
            let streamed = draw_stream(
                SliceSource::new(&bad),
                &mut Recorder::new(d.width, d.height),
            );
            assert!(
                matches!(streamed, Err(DrawError::Decode(_))),
                "{}: byte {i} flipped",
                d.name
            );
        }
        assert_eq!(
            PifsImage::<Gray8>::new(&d.stream)
                .unwrap()
                .decoder()
                .verify()
                .map(|_| ()),
            Ok(())
        );
    }
    assert_eq!(
        PifsImage::<Gray8>::new(b"JPEG....").err(),
        Some(DecodeError::BadMagic)
    );
    let d = &golden()[0];
    let header_len = decoder_core::Header::read(&d.stream).unwrap().encoded_len();
    assert_eq!(
        PifsImage::<Gray8>::new(&d.stream[..header_len]).err(),
        Some(DecodeError::Truncated)
    );
}

#[test]
fn target_errors_stop_the_drawing() {
    for d in golden() {
        let img = d.image::<Gray8>();
        let mut t = Recorder::new(d.width, d.height);
        t.fail_after = Some(1);
        assert_eq!(img.draw(&mut t), Err(Broken), "{}", d.name);
        assert_eq!(
            t.fills.len(),
            1,
            "{}: drawing went on after the error",
            d.name
        );
        let mut t = Recorder::new(d.width, d.height);
        t.fail_after = Some(0);
        assert_eq!(img.draw_checked(&mut t), Err(DrawError::Sink(Broken)));
    }
}

/// One byte per call, like a UART.
struct Uart<'a>(&'a [u8], usize);

impl ByteSource for Uart<'_> {
    fn next_byte(&mut self) -> Option<u8> {
        let b = self.0.get(self.1).copied();
        self.1 += usize::from(b.is_some());
        b
    }
}

#[test]
fn streamed_drawing_equals_in_memory_drawing() {
    for d in golden() {
        let mut a = Recorder::new(d.width, d.height);
        d.image::<Gray8>().draw(&mut a).unwrap();
        let mut b = Recorder::new(d.width, d.height);
        let header = draw_stream(Uart(&d.stream, 0), &mut b).unwrap();
        assert_eq!(
            (u32::from(header.width), u32::from(header.height)),
            (d.width, d.height)
        );
        assert_eq!(a.fills, b.fills, "{}: tiles differ", d.name);
        assert!(a.pixels == b.pixels, "{}: pixels differ", d.name);
        // And the PixelSink-level streaming decoder gives the decode_into pixels.
        let mut out = vec![0u8; d.pixels.len()];
        struct Buf<'a>(&'a mut [u8], u32);
        impl decoder_core::PixelSink for Buf<'_> {
            type Error = std::convert::Infallible;

            fn tile(&mut self, tile: decoder_core::Tile<'_>) -> Result<(), Self::Error> {
                let decoder_core::Rect { x, y, w, h } = tile.area;
                for j in 0..h {
                    for i in 0..w {
                        self.0[((y + j) * self.1 + x + i) as usize] =
                            tile.pixels[(j * w + i) as usize];
                    }
                }
                Ok(())
            }
        }
        pifs_tests::decode_stream(Uart(&d.stream, 0), &mut Buf(&mut out, d.width)).unwrap();
        assert!(
            out == d.pixels,
            "{}: decode_stream differs from decode_into",
            d.name
        );
        let mut region = Recorder::new(d.width, d.height);
        let clip = decoder_core::Rect {
            x: d.width / 4,
            y: d.height / 4,
            w: d.width / 2,
            h: d.height / 2,
        };
        struct Rec<'a>(&'a mut Recorder);
        impl decoder_core::PixelSink for Rec<'_> {
            type Error = Broken;

            fn tile(&mut self, tile: decoder_core::Tile<'_>) -> Result<(), Self::Error> {
                let decoder_core::Rect { x, y, w, h } = tile.area;
                let area = Rectangle::new(Point::new(x as i32, y as i32), Size::new(w, h));
                self.0
                    .fill_contiguous(&area, tile.pixels.iter().map(|&l| Gray8::new(l)))
            }
        }
        decoder_core::Decoder::from_source(Uart(&d.stream, 0))
            .unwrap()
            .clip(clip)
            .decode(&mut Rec(&mut region))
            .unwrap();
        for (i, p) in region.pixels.iter().enumerate() {
            let (x, y) = (i as u32 % d.width, i as u32 / d.width);
            let inside = x >= clip.x && y >= clip.y && x < clip.x + clip.w && y < clip.y + clip.h;
            assert_eq!(p.is_some(), inside, "{}: ({x}, {y})", d.name);
            if let Some(v) = p {
                assert_eq!(*v, d.pixels[i]);
            }
        }
    }
}

/// A stream coded as one stripe wider than the default frontier (the encoder's default for an
/// image wider than 512 pixels) is refused when wrapped, not left undrawn; an image holding
/// wider stripes draws it, as the same image in stripes of 512 draws with the default.
#[test]
fn a_stripe_wider_than_the_frontier_is_refused_before_drawing() {
    let plane = common::synthetic(640, 16, 7, 4);
    let encode = |stripe| {
        let config = host_encoder::EncoderConfig {
            stripe,
            ..common::small_config()
        };
        common::analyse_with(plane.clone(), &config)
            .encode(host_encoder::Target::Bytes(400))
            .unwrap()
            .bytes
    };
    let whole = encode(host_encoder::WHOLE_WIDTH);
    assert_eq!(
        PifsImage::<Gray8>::new(&whole).err(),
        Some(DecodeError::StripeTooWide {
            stripe: 640,
            capacity: 512
        })
    );
    let pixels = host_pixels(&whole);
    let wide = PifsImage::<Gray8>::with_stripe_capacity::<1024>(&whole).unwrap();
    let mut t = Recorder::new(640, 16);
    Image::new(&wide, Point::zero()).draw(&mut t).unwrap();
    assert!(t.pixels.iter().zip(&pixels).all(|(p, &v)| *p == Some(v)));

    let narrow = encode(host_encoder::DEFAULT_STRIPE_TILES);
    let img = PifsImage::<Gray8>::new(&narrow).unwrap();
    let mut t = Recorder::new(640, 16);
    Image::new(&img, Point::zero()).draw(&mut t).unwrap();
    assert!(t.pixels.iter().all(Option::is_some));
}

/// A grayscale stream's pixels as a host decodes them (stripes of any width).
fn host_pixels(stream: &[u8]) -> Vec<u8> {
    let decoder = decoder_core::Decoder::new(stream)
        .unwrap()
        .stripe_capacity::<65536>();
    let mut pixels = vec![0u8; decoder.header().pixel_count()];
    decoder.decode_into(&mut pixels).unwrap();
    pixels
}

/// Packets drawn as they arrive through `DrawSink`: each region where it lies in the image,
/// every pixel the colour its decoded value has at its image position (dithered as the whole
/// image would be), on a colour and on a 1-bit display; the preview likewise.
#[test]
fn packets_draw_onto_a_display_through_draw_sink() {
    use decoder_core::graphics::DrawSink;
    use decoder_core::{Packet, Tile};
    /// Every decoded pixel of a packet by image position, as `(x, y, [r, g, b])`.
    struct Pixels(Vec<(u32, u32, [u8; 3])>);
    impl decoder_core::PixelSink for Pixels {
        type Error = std::convert::Infallible;
        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Self::Error> {
            let ch = usize::from(tile.channels);
            for (i, p) in tile.pixels.chunks_exact(ch).enumerate() {
                let (x, y) = (i as u32 % tile.area.w, i as u32 / tile.area.w);
                let rgb = if ch == 3 {
                    [p[0], p[1], p[2]]
                } else {
                    [p[0]; 3]
                };
                self.0.push((tile.area.x + x, tile.area.y + y, rgb));
            }
            Ok(())
        }
    }
    for (file, colour) in [
        ("packets_colour_40x32.pifsp", true),
        ("packets_gray_64x48.pifsp", false),
    ] {
        let framed = std::fs::read(golden_dir().join(file)).unwrap();
        let mut at = 0;
        let mut packets = 0;
        while at + 2 <= framed.len() {
            let len = usize::from(u16::from_le_bytes([framed[at], framed[at + 1]]));
            let packet = Packet::parse(&framed[at + 2..at + 2 + len]).unwrap();
            at += 2 + len;
            packets += 1;
            let mut pixels = Pixels(Vec::new());
            packet.decode(&mut pixels).unwrap();
            assert!(
                !pixels.0.is_empty(),
                "{file}: packet {packets} draws nothing"
            );
            let mut rgb = MockDisplay::<Rgb565>::new();
            packet.decode(&mut DrawSink::new(&mut rgb)).unwrap();
            let mut mono = MockDisplay::<BinaryColor>::new();
            packet
                .decode(&mut DrawSink::new(&mut mono).with_dither(Dither::Ordered))
                .unwrap();
            for &(x, y, [r, g, b]) in &pixels.0 {
                let p = Point::new(x as i32, y as i32);
                let t = Threshold::ordered(x, y);
                let luma = if colour {
                    decoder_core::internal::colour::rgb_to_luma(r, g, b)
                } else {
                    r
                };
                let expected = if colour {
                    Rgb565::from_rgb_with(r, g, b, t)
                } else {
                    Rgb565::from_gray_with(luma, t)
                };
                assert_eq!(rgb.get_pixel(p), Some(expected), "{file} {x},{y}");
                assert_eq!(
                    mono.get_pixel(p),
                    Some(BinaryColor::from_gray_with(luma, t)),
                    "{file} {x},{y}"
                );
            }
        }
        assert!(packets > 2, "{file}: {packets} packets");
    }
}
