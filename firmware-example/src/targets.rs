//! The draw targets of the golden-vector run, and the run itself. Grayscale vectors are drawn
//! in `Gray8` (hashes of the luma bytes), colour vectors in `Rgb565` (hashes of each pixel's
//! 16-bit RGB565 value, little-endian): a colour stream drawn straight to an RGB565 display.

use core::convert::Infallible;

use cortex_m_semihosting::heprintln;
use decoder_core::graphics::{draw_stream, FromGray, PifsImage};
use decoder_core::ByteSource;
use decoder_core::DrawError;
use decoder_core::Scale;
use embedded_graphics::image::{Image, ImageDrawableExt};
use embedded_graphics::pixelcolor::raw::RawU16;
use embedded_graphics::pixelcolor::{Gray8, GrayColor, Rgb565};
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::Rectangle;
use sha2::{Digest, Sha256};

use crate::{measure, Hex, Vector, FRAME_BUFFER_LEN, FRAME_BUFFER_VECTOR, MAX_WIDTH};

/// A colour the run draws in, and the bytes its hashes take of each pixel.
pub trait Hashed: FromGray + Copy {
    /// Bytes per pixel in the hashes.
    const BYTES: usize;
    /// The pixel's bytes, into `out[..BYTES]`.
    fn put(self, out: &mut [u8]);
    /// A number to sum (the measuring display).
    fn value(self) -> u32;
}

impl Hashed for Gray8 {
    const BYTES: usize = 1;
    fn put(self, out: &mut [u8]) {
        out[0] = self.luma();
    }
    fn value(self) -> u32 {
        u32::from(self.luma())
    }
}

impl Hashed for embedded_graphics::pixelcolor::BinaryColor {
    const BYTES: usize = 1;
    fn put(self, out: &mut [u8]) {
        out[0] = u8::from(self.is_on());
    }
    fn value(self) -> u32 {
        u32::from(self.is_on())
    }
}

impl Hashed for Rgb565 {
    const BYTES: usize = 2;
    fn put(self, out: &mut [u8]) {
        out[..2].copy_from_slice(&RawU16::from(self).into_inner().to_le_bytes());
    }
    fn value(self) -> u32 {
        u32::from(RawU16::from(self).into_inner())
    }
}

/// A display that only sums what it receives: the cheapest target, for measuring the decoder.
struct SumDisplay<C> {
    size: Size,
    sum: u32,
    colour: core::marker::PhantomData<C>,
}

impl<C> OriginDimensions for SumDisplay<C> {
    fn size(&self) -> Size {
        self.size
    }
}

impl<C: Hashed> DrawTarget for SumDisplay<C> {
    type Color = C;
    type Error = Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<C>>>(&mut self, pixels: I) -> Result<(), Infallible> {
        for Pixel(_, c) in pixels {
            self.sum = self.sum.wrapping_add(c.value());
        }
        Ok(())
    }

    fn fill_contiguous<I: IntoIterator<Item = C>>(
        &mut self,
        _area: &Rectangle,
        colors: I,
    ) -> Result<(), Infallible> {
        for c in colors {
            self.sum = self.sum.wrapping_add(c.value());
        }
        Ok(())
    }
}

/// Hashes tiles as they arrive: per tile `x, y, w, h` (u32 LE) then the luma bytes. Records
/// any pixel that arrives through `draw_iter` (the decoder must use `fill_contiguous` only).
struct TileHasher<C> {
    size: Size,
    sha: Sha256,
    tiles: u32,
    per_pixel: u32,
    colour: core::marker::PhantomData<C>,
}

impl<C> TileHasher<C> {
    fn new(size: Size) -> Self {
        TileHasher {
            size,
            sha: Sha256::new(),
            tiles: 0,
            per_pixel: 0,
            colour: core::marker::PhantomData,
        }
    }
}

impl<C> OriginDimensions for TileHasher<C> {
    fn size(&self) -> Size {
        self.size
    }
}

impl<C: Hashed> DrawTarget for TileHasher<C> {
    type Color = C;
    type Error = Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<C>>>(&mut self, pixels: I) -> Result<(), Infallible> {
        self.per_pixel += pixels.into_iter().count() as u32;
        Ok(())
    }

    fn fill_contiguous<I: IntoIterator<Item = C>>(
        &mut self,
        area: &Rectangle,
        colors: I,
    ) -> Result<(), Infallible> {
        let mut buf = [0u8; 512];
        let mut n = 0;
        for c in colors {
            if n + C::BYTES <= buf.len() {
                c.put(&mut buf[n..]);
            }
            n += C::BYTES;
        }
        for v in [
            area.top_left.x as u32,
            area.top_left.y as u32,
            area.size.width,
            area.size.height,
        ] {
            self.sha.update(v.to_le_bytes());
        }
        self.sha.update(&buf[..n.min(buf.len())]);
        self.tiles += 1;
        Ok(())
    }
}

/// A one-row display: the row buffer of the row-by-row (row-major) hash (`N` bytes: the row's
/// pixels at [`Hashed::BYTES`] each).
struct RowDisplay<C, const N: usize> {
    width: u32,
    row: [u8; N],
    colour: core::marker::PhantomData<C>,
}

impl<C, const N: usize> RowDisplay<C, N> {
    fn new(width: u32) -> Self {
        RowDisplay {
            width,
            row: [0; N],
            colour: core::marker::PhantomData,
        }
    }
}

impl<C, const N: usize> OriginDimensions for RowDisplay<C, N> {
    fn size(&self) -> Size {
        Size::new(self.width, 1)
    }
}

impl<C: Hashed, const N: usize> DrawTarget for RowDisplay<C, N> {
    type Color = C;
    type Error = Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<C>>>(&mut self, pixels: I) -> Result<(), Infallible> {
        for Pixel(p, c) in pixels {
            let at = p.x as usize * C::BYTES;
            if p.y == 0 && p.x >= 0 && (p.x as u32) < self.width && at + C::BYTES <= N {
                c.put(&mut self.row[at..]);
            }
        }
        Ok(())
    }
}

/// A Gray8 frame buffer of `size` pixels, row-major.
struct FrameBuffer<'b> {
    size: Size,
    pixels: &'b mut [u8],
}

impl OriginDimensions for FrameBuffer<'_> {
    fn size(&self) -> Size {
        self.size
    }
}

impl DrawTarget for FrameBuffer<'_> {
    type Color = Gray8;
    type Error = Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<Gray8>>>(
        &mut self,
        pixels: I,
    ) -> Result<(), Infallible> {
        let (w, h) = (self.size.width as i32, self.size.height as i32);
        for Pixel(p, c) in pixels {
            if p.x >= 0 && p.y >= 0 && p.x < w && p.y < h {
                self.pixels[(p.y * w + p.x) as usize] = c.luma();
            }
        }
        Ok(())
    }
}

/// A byte source that hands out one byte per call, standing in for a UART.
struct Uart {
    data: &'static [u8],
    pos: usize,
}

impl ByteSource for Uart {
    fn next_byte(&mut self) -> Option<u8> {
        let b = self.data.get(self.pos).copied();
        if b.is_some() {
            self.pos += 1;
        }
        b
    }
}

/// Decodes one vector every way; prints its `PIFS` line; `false` on any failure.
///
/// Every pass is its own function (not inlined), so that only one decoder state and one
/// display are on the stack at a time: the micro:bit has 16 KiB of RAM.
pub fn check_vector(v: &Vector, counter: &measure::Counter) -> bool {
    let header = decoder_core::Header::read(v.data);
    let colour = header.is_ok_and(|h| h.channels == 3);
    let deep = header.is_ok_and(|h| h.range.is_some());
    if colour {
        check_vector_as::<Rgb565>(v, counter)
    } else {
        check_vector_as::<Gray8>(v, counter) && (!deep || value_hash(v))
    }
}

/// A row of a 16-bit stream's values, as the decoder hands them over.
struct ValueRow {
    values: [u16; MAX_WIDTH],
    missing: u32,
}

impl decoder_core::PixelSink for ValueRow {
    type Error = Infallible;

    fn tile(&mut self, tile: decoder_core::Tile<'_>) -> Result<(), Infallible> {
        let x = tile.area.x as usize;
        if tile.values.len() != tile.pixels.len() || tile.area.h != 1 {
            self.missing += 1;
        }
        for (i, &v) in tile.values.iter().enumerate() {
            if let Some(slot) = self.values.get_mut(x + i) {
                *slot = v;
            }
        }
        Ok(())
    }
}

/// A 16-bit stream's values, row-major and little-endian, hashed one clipped row at a time
/// (`PIFS-VALUES name=<file> sha256=<hex>`, what `values.txt` records); `false` on an error.
#[inline(never)]
fn value_hash(v: &Vector) -> bool {
    let mut sha = Sha256::new();
    let mut row = ValueRow {
        values: [0; MAX_WIDTH],
        missing: 0,
    };
    let (w, h) = (u32::from(v.width), u32::from(v.height));
    for y in 0..h {
        let area = decoder_core::Rect { x: 0, y, w, h: 1 };
        let decoded =
            decoder_core::Decoder::new(v.data).and_then(|d| Ok(d.clip(area).decode(&mut row)?));
        if let Err(e) = decoded {
            heprintln!("PIFS-ERROR name={} values: {}", v.name, e);
            return false;
        }
        for &value in &row.values[..w as usize] {
            sha.update(value.to_le_bytes());
        }
    }
    if row.missing != 0 {
        heprintln!(
            "PIFS-ERROR name={} {} tiles without values",
            v.name,
            row.missing
        );
        return false;
    }
    heprintln!(
        "PIFS-VALUES name={} sha256={}",
        v.name,
        Hex(sha.finalize().into())
    );
    true
}

/// [`check_vector`] in colour `C`.
fn check_vector_as<C: Hashed>(v: &Vector, counter: &measure::Counter) -> bool {
    let img: PifsImage<'static, C> = match PifsImage::new(v.data) {
        Ok(img) => img,
        Err(e) => {
            heprintln!("PIFS-ERROR name={} header: {}", v.name, e);
            // The same error through defmt (decoder-core's `defmt` feature): no `core::fmt`.
            defmt::error!("{=str}: {}", v.name, e);
            return false;
        }
    };
    let size = img.size();
    if size != Size::new(v.width.into(), v.height.into()) {
        heprintln!(
            "PIFS-ERROR name={} size {}x{} differs from golden.txt",
            v.name,
            size.width,
            size.height
        );
        return false;
    }
    let (stack, instr) = match measured_decode(&img, counter) {
        Ok(m) => m,
        Err(e) => {
            heprintln!("PIFS-ERROR name={} decode: {}", v.name, e);
            return false;
        }
    };
    let (tile_hash, tiles, per_pixel) = tile_hash(&img);
    if per_pixel != 0 {
        heprintln!(
            "PIFS-ERROR name={} {} pixels drawn one by one",
            v.name,
            per_pixel
        );
        return false;
    }
    match stream_tile_hash::<C>(v.data, size) {
        Ok(h) if h == tile_hash => {}
        Ok(_) => {
            heprintln!("PIFS-ERROR name={} streamed tiles differ", v.name);
            return false;
        }
        Err(e) => {
            heprintln!("PIFS-ERROR name={} stream: {}", v.name, e);
            return false;
        }
    }
    let pixel_hash = row_hash(&img);

    defmt::info!(
        "{=str}: {=u32}x{=u32}, {=usize} bytes, {=u32} tiles, {=u64} instructions, {=usize} bytes of stack",
        v.name,
        size.width,
        size.height,
        v.data.len(),
        tiles,
        instr,
        stack
    );
    heprintln!(
        "PIFS name={} w={} h={} sha256={} tiles={} stack={} instr={}",
        v.name,
        size.width,
        size.height,
        Hex(pixel_hash),
        Hex(tile_hash),
        stack,
        instr
    );
    if v.name == FRAME_BUFFER_VECTOR {
        if let Ok(gray) = PifsImage::<Gray8>::new(v.data) {
            frame_buffer(v, &gray);
        }
    }
    for scale in [Scale::Quarter, Scale::Half, Scale::Double] {
        scaled_hash(v, &img.with_scale(scale), scale);
    }
    true
}

/// The row-major hash of the image drawn at `scale` (`PIFS-SCALED name=<file> scale=<log2>
/// w=<width> h=<height> sha256=<hex>`): scaled decoding through embedded-graphics.
#[inline(never)]
fn scaled_hash<C: Hashed>(v: &Vector, img: &PifsImage<'static, C>, scale: Scale) {
    let size = img.size();
    let mut row = RowDisplay::<C, { 4 * MAX_WIDTH }>::new(size.width.min(4 * MAX_WIDTH as u32 / 2));
    let mut sha = Sha256::new();
    for y in 0..size.height {
        let area = Rectangle::new(Point::new(0, y as i32), Size::new(size.width, 1));
        let Ok(()) = Image::new(&img.sub_image(&area), Point::zero()).draw(&mut row);
        sha.update(&row.row[..row.width as usize * C::BYTES]);
    }
    heprintln!(
        "PIFS-SCALED name={} scale={} w={} h={} sha256={}",
        v.name,
        scale.log2(),
        size.width,
        size.height,
        Hex(sha.finalize().into())
    );
}

/// One full decode onto [`SumDisplay`], with peak stack and instructions.
#[inline(never)]
fn measured_decode<C: Hashed>(
    img: &PifsImage<'static, C>,
    counter: &measure::Counter,
) -> Result<(usize, u64), decoder_core::DecodeError> {
    let mut display = SumDisplay {
        size: img.size(),
        sum: 0,
        colour: core::marker::PhantomData,
    };
    measure::paint();
    let base = measure::sp();
    let t0 = measure::ticks();
    let result = draw_once(img, &mut display);
    let t1 = measure::ticks();
    let stack = measure::peak(base);
    match result {
        Ok(()) => Ok((stack, counter.instructions(t1 - t0))),
        Err(DrawError::Decode(e)) => Err(e),
        Err(DrawError::Sink(never)) => match never {},
    }
}

/// The measured call: not inlined, so that all of the decoder's stack is below the caller's
/// stack pointer.
#[inline(never)]
fn draw_once<C: Hashed>(
    img: &PifsImage<'static, C>,
    display: &mut SumDisplay<C>,
) -> Result<(), DrawError<Infallible>> {
    img.draw_checked(display)
}

/// Tiles hashed as they arrive, through the embedded-graphics `Image` API: the hash, the
/// number of tiles, the number of pixels that arrived one by one.
#[inline(never)]
fn tile_hash<C: Hashed>(img: &PifsImage<'static, C>) -> ([u8; 32], u32, u32) {
    let mut tiles = TileHasher::<C>::new(img.size());
    let Ok(()) = Image::new(img, Point::zero()).draw(&mut tiles);
    (tiles.sha.finalize().into(), tiles.tiles, tiles.per_pixel)
}

/// The tile hash of a decode from a byte-at-a-time stream.
#[inline(never)]
fn stream_tile_hash<C: Hashed>(
    data: &'static [u8],
    size: Size,
) -> Result<[u8; 32], decoder_core::DecodeError> {
    let mut streamed = TileHasher::<C>::new(size);
    match draw_stream(Uart { data, pos: 0 }, &mut streamed) {
        Ok(_) => Ok(streamed.sha.finalize().into()),
        Err(DrawError::Decode(e)) => Err(e),
        Err(DrawError::Sink(never)) => match never {},
    }
}

/// Row-major hash without a frame buffer: one sub-image (`draw_sub_image`) per row.
#[inline(never)]
fn row_hash<C: Hashed>(img: &PifsImage<'static, C>) -> [u8; 32] {
    let size = img.size();
    let mut row = RowDisplay::<C, { 2 * MAX_WIDTH }>::new(size.width);
    let mut sha = Sha256::new();
    for y in 0..size.height {
        let area = Rectangle::new(Point::new(0, y as i32), Size::new(size.width, 1));
        let Ok(()) = Image::new(&img.sub_image(&area), Point::zero()).draw(&mut row);
        sha.update(&row.row[..size.width as usize * C::BYTES]);
    }
    sha.finalize().into()
}

/// The smallest image, drawn into a real frame buffer.
#[inline(never)]
fn frame_buffer(v: &Vector, img: &PifsImage<'static, Gray8>) {
    let mut pixels = [0u8; FRAME_BUFFER_LEN];
    let size = img.size();
    let n = ((size.width * size.height) as usize).min(FRAME_BUFFER_LEN);
    let mut fb = FrameBuffer {
        size,
        pixels: &mut pixels[..n],
    };
    let Ok(()) = Image::new(img, Point::zero()).draw(&mut fb);
    heprintln!(
        "PIFS-FB name={} sha256={}",
        v.name,
        Hex(Sha256::digest(&pixels[..n]).into())
    );
}
