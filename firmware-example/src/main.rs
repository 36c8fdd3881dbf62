//! Example firmware for PIFS on Cortex-M, run under QEMU (`lm3s6965evb`, Cortex-M3, with
//! `thumbv7m-none-eabi`; `microbit`, Cortex-M0, with `thumbv6m-none-eabi`).
//!
//! Default build: decodes every golden vector of `tests/golden/` (embedded with
//! `include_bytes!`, listed by `build.rs`) through embedded-graphics and prints, on semihosting
//! **stderr**, one machine-readable line per image:
//!
//! ```text
//! PIFS name=<file> w=<width> h=<height> sha256=<hex> tiles=<hex> stack=<bytes> instr=<count>
//! ```
//!
//! - `sha256`: SHA-256 of the decoded pixels in row-major order (what `golden.txt` records),
//!   computed without a frame buffer: the image is drawn one row at a time as a sub-image
//!   (`draw_sub_image` with a `width x 1` area, a row buffer only);
//! - `tiles`: SHA-256 of the tiles in the order they reach the display, hashed as they arrive in
//!   `fill_contiguous` during one `Image::draw`: per tile `x, y, w, h` (u32, little-endian) then
//!   its `w * h` luma bytes;
//! - `stack`, `instr`: peak stack (bytes, by painting) and instructions (SysTick under
//!   `-icount shift=0`) of one full decode drawn onto a display that only sums the pixels.
//!
//! A 16-bit vector's values are hashed too, decoded one clipped row at a time
//! (`PIFS-VALUES name=<file> sha256=<hex>`, row-major, each value little-endian: what
//! `tests/golden/values.txt` records).
//!
//! Every golden packet set is received as a radio would hand it over, out of order and with
//! losses, and drawn into a frame buffer (`PIFS-PACKETS`; see `packets.rs`).
//!
//! The smallest image is also drawn into a real frame buffer (`PIFS-FB name=<file>
//! sha256=<hex>`, row-major like `sha256`), every image is drawn at 1/4, 1/2 and 2 times its
//! size (`PIFS-SCALED name=<file> scale=<log2> w=<width> h=<height> sha256=<hex>`,
//! row-major), and every image is also decoded from a byte-at-a-time stream source
//! (`draw_stream`), which must give the same tiles. The human-readable log goes
//! through `defmt` (semihosting stdout; decode it with `defmt-print -e <elf>`). QEMU exits with
//! status 0 when everything decoded, 1 otherwise.
//!
//! With the `bench` feature (see `bench/embedded.sh`) it embeds the streams listed in
//! `PIFS_BENCH_STREAMS` (a path list, `:`-separated), decodes each once with
//! `decoder_core::Decoder` into a sink that sums the pixels, and prints
//! `PIFS-BENCH name=… w=… h=… bytes=… stack=… instr=… checksum=… ok=…` per stream, then
//! `PIFS-BENCH-SCALED name=… scale=… stack=… instr=… checksum=… ok=…` for its decodes at 1/2, 1/4,
//! 1/8, 2 and 4 times its size;
//! `baseline` builds the same firmware, harness and all, with a stand-in that only reads the
//! stream where the decoder is called (for the flash and RAM deltas); `draw` draws each stream
//! through `graphics::PifsImage` onto an RGB565 display that sums the colours instead
//! (`PIFS-BENCH-DRAW name=… stack=… instr=… checksum=… ok=…`: what an application's draw
//! costs, the display adapter and its dither included).
#![no_std]
#![no_main]

use cortex_m as _; // The critical-section implementation.
use defmt_semihosting as _; // The defmt global logger.

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, heprintln};

mod measure;
use measure::Decimal;
#[cfg(not(feature = "bench"))]
mod packets;
#[cfg(not(feature = "bench"))]
mod targets;
#[cfg(not(feature = "bench"))]
use packets::PacketSet;

/// An embedded stream.
pub struct Vector {
    /// File name.
    pub name: &'static str,
    /// Width recorded in `golden.txt` (or read from the bench stream's header).
    pub width: u16,
    /// Height, likewise.
    pub height: u16,
    /// The stream.
    pub data: &'static [u8],
}

include!(concat!(env!("OUT_DIR"), "/vectors.rs"));

#[entry]
fn main() -> ! {
    let core = cortex_m::Peripherals::take().unwrap();
    let counter = measure::Counter::start(core.SYST);
    let milli = counter.milli_instr_per_tick();
    let units = measure::divide(milli, 1000);
    heprintln!(
        "PIFS-CALIB instr_per_tick={}.{:03} free_stack={}",
        Decimal(units as i64),
        Decimal((milli - 1000 * units) as i64),
        Decimal(measure::free_stack() as i64)
    );
    let ok = run(&counter);
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    #[allow(clippy::empty_loop)]
    loop {}
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(l) => heprintln!("PIFS-PANIC at {}:{}", l.file(), Decimal(l.line().into())),
        None => heprintln!("PIFS-PANIC"),
    }
    debug::exit(debug::EXIT_FAILURE);
    #[allow(clippy::empty_loop)]
    loop {}
}

/// Lower-case hexadecimal of a 32-byte digest.
pub struct Hex(pub [u8; 32]);

impl core::fmt::Display for Hex {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for b in self.0 {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

#[cfg(not(feature = "bench"))]
fn run(counter: &measure::Counter) -> bool {
    defmt::info!(
        "PIFS example firmware: {=usize} golden vectors",
        VECTORS.len()
    );
    let mut ok = true;
    for v in VECTORS {
        ok &= targets::check_vector(v, counter);
    }
    ok &= packets::check_all(counter);
    if ok {
        defmt::info!("all vectors decoded");
    } else {
        defmt::error!("some vectors failed");
    }
    ok
}

#[cfg(all(feature = "bench", not(feature = "draw")))]
fn run(counter: &measure::Counter) -> bool {
    /// Sums the pixels, so that the decode cannot be optimised away.
    struct Sum(u32);

    impl decoder_core::PixelSink for Sum {
        type Error = core::convert::Infallible;

        fn tile(&mut self, tile: decoder_core::Tile<'_>) -> Result<(), Self::Error> {
            for &p in tile.pixels {
                self.0 = self.0.wrapping_add(u32::from(p));
            }
            Ok(())
        }
    }

    /// The measured call, not inlined so that all its stack is below the caller's.
    #[inline(never)]
    fn decode_once(data: &'static [u8], sum: &mut Sum) -> bool {
        // The same (one) instantiation of the decoder as the scaled decodes below.
        decode_scaled(data, decoder_core::Scale::One, sum)
    }

    let mut all_ok = true;
    for v in VECTORS {
        defmt::info!("bench: {=str}, {=usize} bytes", v.name, v.data.len());
        let mut sum = Sum(0);
        let m = counter.measure(|| decode_once(v.data, &mut sum));
        heprintln!(
            "PIFS-BENCH name={} w={} h={} bytes={} stack={} instr={} checksum={} ok={}",
            v.name,
            Decimal(v.width.into()),
            Decimal(v.height.into()),
            Decimal(v.data.len() as i64),
            Decimal(m.stack as i64),
            Decimal(m.instructions as i64),
            Decimal(sum.0.into()),
            m.value
        );
        all_ok &= m.value;
        for scale in [
            decoder_core::Scale::Half,
            decoder_core::Scale::Quarter,
            decoder_core::Scale::Eighth,
            decoder_core::Scale::Double,
            decoder_core::Scale::Quadruple,
        ] {
            let mut sum = Sum(0);
            let m = counter.measure(|| decode_scaled(v.data, scale, &mut sum));
            heprintln!(
                "PIFS-BENCH-SCALED name={} scale={} stack={} instr={} checksum={} ok={}",
                v.name,
                Decimal(scale.log2().into()),
                Decimal(m.stack as i64),
                Decimal(m.instructions as i64),
                Decimal(sum.0.into()),
                m.value
            );
            all_ok &= m.value;
        }
    }
    all_ok
}

/// With `draw`: each stream drawn once as an application draws it, through
/// `graphics::PifsImage` (ordered dither) onto an RGB565 display that only sums the colours it
/// is given (a driver streaming each tile to the panel at no cost of its own), printing
/// `PIFS-BENCH-DRAW name=… stack=… instr=… checksum=… ok=…`.
#[cfg(feature = "draw")]
fn run(counter: &measure::Counter) -> bool {
    use embedded_graphics::pixelcolor::{raw::RawU16, Rgb565};
    use embedded_graphics::prelude::*;
    use embedded_graphics::primitives::Rectangle;

    /// An RGB565 panel that sums the raw colours drawn onto it.
    struct Panel(u32);

    impl OriginDimensions for Panel {
        fn size(&self) -> Size {
            Size::new(u32::from(u16::MAX), u32::from(u16::MAX))
        }
    }

    impl DrawTarget for Panel {
        type Color = Rgb565;
        type Error = core::convert::Infallible;

        fn draw_iter<I: IntoIterator<Item = Pixel<Rgb565>>>(
            &mut self,
            pixels: I,
        ) -> Result<(), Self::Error> {
            for Pixel(_, c) in pixels {
                self.0 = self.0.wrapping_add(u32::from(RawU16::from(c).into_inner()));
            }
            Ok(())
        }

        fn fill_contiguous<I: IntoIterator<Item = Rgb565>>(
            &mut self,
            _area: &Rectangle,
            colors: I,
        ) -> Result<(), Self::Error> {
            for c in colors {
                self.0 = self.0.wrapping_add(u32::from(RawU16::from(c).into_inner()));
            }
            Ok(())
        }
    }

    /// The measured call, not inlined so that all its stack is below the caller's.
    #[inline(never)]
    fn draw_once(data: &'static [u8], panel: &mut Panel) -> bool {
        decoder_core::graphics::PifsImage::<Rgb565>::new(core::hint::black_box(data)).is_ok_and(
            |picture| {
                embedded_graphics::image::Image::new(&picture, Point::zero())
                    .draw(panel)
                    .is_ok()
            },
        )
    }

    let mut all_ok = true;
    for v in VECTORS {
        defmt::info!("draw: {=str}, {=usize} bytes", v.name, v.data.len());
        let mut panel = Panel(0);
        let m = counter.measure(|| draw_once(v.data, &mut panel));
        heprintln!(
            "PIFS-BENCH-DRAW name={} stack={} instr={} checksum={} ok={}",
            v.name,
            Decimal(m.stack as i64),
            Decimal(m.instructions as i64),
            Decimal(panel.0.into()),
            m.value
        );
        all_ok &= m.value;
    }
    all_ok
}

/// A decode at `scale` (every decode of the bench), not inlined.
#[cfg(all(feature = "bench", not(feature = "baseline"), not(feature = "draw")))]
#[inline(never)]
fn decode_scaled<S: decoder_core::PixelSink>(
    data: &'static [u8],
    scale: decoder_core::Scale,
    sink: &mut S,
) -> bool {
    decoder_core::Decoder::new(core::hint::black_box(data))
        .is_ok_and(|decoder| decoder.scale(scale).decode(sink).is_ok())
}

/// The baseline's stand-in for [`decode_scaled`]: the same harness around it, no decoder, so
/// that the firmware's size without the decoder is the harness's alone.
#[cfg(feature = "baseline")]
#[inline(never)]
fn decode_scaled<S>(data: &'static [u8], scale: decoder_core::Scale, _sink: &mut S) -> bool {
    let mut sum = scale.log2() as u32;
    for &b in core::hint::black_box(data) {
        sum = sum.wrapping_add(u32::from(b));
    }
    core::hint::black_box(sum) != 0
}
