//! Packets as a radio receiver gets them: one at a time, copied into a fixed buffer, in any
//! order, some lost. Each golden packet set is received in reverse order (so the preview,
//! packet 0, comes last), without the packets `packets.txt` loses; every region is drawn as it
//! arrives, and the preview only around the regions already drawn. The frame buffer's hash
//! (`PIFS-PACKETS name=<file> received=<n> sha256=<hex>`) must equal the host's assembly of
//! the same packets. `stack=<bytes>` is the largest peak stack of one packet's parse and
//! decode (the decoder's own RAM; the receiver adds its packet buffer and the list of regions
//! drawn). The same packets are then received again onto a display through
//! `graphics::DrawSink`, colour sets on RGB565, gray sets on a 1-bit panel, dithered
//! (`PIFS-PACKETS-DRAWN name=<file> sha256=<hex>`: each pixel's RGB565 value, little-endian, or
//! its bit as a byte), which the host computes from its assembly; and once more at half size,
//! every packet drawn at `Scale::Half` (`PIFS-PACKETS-HALF name=<file> sha256=<hex>`), which
//! must equal the host's assembly at that scale.
//!
//! Each golden parity set is received in the order it was sent (the data packets, then the
//! parity packets), without the lost ones, each packet added as it arrives to a `Rebuild` held
//! in a fixed buffer; the lost packets are rebuilt, and every data packet is drawn into the frame buffer: `PIFS-PARITY name=<file>
//! rebuilt=<n> stack=<bytes> sha256=<hex>` must equal the host's picture of the whole set, and
//! `stack` and `instr` are the rebuild's peak stack and instructions.

use core::convert::Infallible;

use cortex_m_semihosting::heprintln;
use decoder_core::graphics::DrawSink;
use decoder_core::{Packet, PacketKind, ParityPacket, PixelSink, Rebuild, Rect, Scale, Tile};
use embedded_graphics::pixelcolor::{BinaryColor, Rgb565};
use embedded_graphics::prelude::*;
use sha2::{Digest, Sha256};

use crate::targets::Hashed;
use crate::{measure, Hex, PACKET_FRAME_LEN, PACKET_SETS, PARITY_SETS};

/// A framed packet set (`tests/golden/packets.txt`).
pub struct PacketSet {
    /// File name.
    pub name: &'static str,
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Bytes per pixel.
    pub channels: usize,
    /// Indices of the packets the link loses.
    pub lost: &'static [u16],
    /// Every packet, each behind its length (two bytes, little-endian).
    pub data: &'static [u8],
}

/// The largest packet the receiver holds: its one packet buffer.
const MAX_PACKET: usize = 1024;
/// The most regions a receiver remembers having drawn (for a late preview).
const MAX_REGIONS: usize = 32;

/// A row-major frame buffer.
struct Frame<'a> {
    pixels: &'a mut [u8],
    width: usize,
    channels: usize,
}

impl PixelSink for Frame<'_> {
    type Error = core::convert::Infallible;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Self::Error> {
        let row = tile.area.w as usize * self.channels;
        if row == 0 {
            return Ok(());
        }
        for (r, src) in tile.pixels.chunks_exact(row).enumerate() {
            let at =
                ((tile.area.y as usize + r) * self.width + tile.area.x as usize) * self.channels;
            if let Some(dst) = self.pixels.get_mut(at..at + row) {
                dst.copy_from_slice(src);
            }
        }
        Ok(())
    }
}

/// Receives every golden packet set, and every parity set; true when all decoded.
pub fn check_all(counter: &measure::Counter) -> bool {
    let mut ok = true;
    for set in PACKET_SETS {
        ok &= receive(set);
    }
    for set in PARITY_SETS {
        ok &= rebuild(set, counter);
    }
    ok
}

/// The bytes a receiver lends the rebuild: every shard of a golden parity set.
const REBUILD_BUFFER: usize = 1024;

/// Receives `set` with its lost data packets missing, rebuilds them from its parity packets
/// and draws every data packet into a frame buffer (see the module's documentation).
fn rebuild(set: &PacketSet, counter: &measure::Counter) -> bool {
    let mut shards = [0u8; REBUILD_BUFFER];
    // A slot per packet as long as the link's largest packet (a shard is shorter).
    let slot_len = frames(set.data).map(<[u8]>::len).max().unwrap_or(0);
    let mut code = Rebuild::new(slot_len, &mut shards);
    let mut lost = 0;
    for bytes in frames(set.data) {
        let added = match ParityPacket::parse(bytes) {
            Ok(parity) => code.add_parity(&parity),
            Err(_) => match Packet::parse(bytes) {
                Ok(p) if set.lost.contains(&p.index) => {
                    lost += 1;
                    Ok(())
                }
                _ => code.add_packet(bytes),
            },
        };
        if let Err(e) = added {
            heprintln!("PIFS-ERROR name={} rebuild: {}", set.name, e);
            return false;
        }
    }
    let measure::Measured {
        value: rebuilt,
        stack,
        instructions: instr,
    } = counter.measure(|| rebuild_lost(&mut code));
    if let Err(e) = rebuilt {
        heprintln!("PIFS-ERROR name={} rebuild: {}", set.name, e);
        return false;
    }
    let mut pixels = [0u8; PACKET_FRAME_LEN];
    let len = set.width * set.height * set.channels;
    let Some(pixels) = pixels.get_mut(..len) else {
        heprintln!("PIFS-ERROR name={} rebuild: frame too small", set.name);
        return false;
    };
    let mut frame = Frame {
        pixels,
        width: set.width,
        channels: set.channels,
    };
    let mut buffer = [0u8; MAX_PACKET];
    let mut drawn = [Rect::of_size(0, 0); MAX_REGIONS];
    let mut regions = 0;
    // The preview (packet 0) first, then the regions over it.
    let mut index = 0;
    while code.has(index) {
        let result = match code.packet(index, &mut buffer) {
            Ok(n) => draw(
                &buffer[..n],
                Scale::One,
                &mut frame,
                &mut drawn,
                &mut regions,
            )
            .map_err(|_| "a rebuilt packet does not decode"),
            Err(_) => Err("a packet missing after the rebuild"),
        };
        if let Err(e) = result {
            heprintln!("PIFS-ERROR name={} packet {}: {}", set.name, index, e);
            return false;
        }
        index += 1;
    }
    let hash: [u8; 32] = Sha256::digest(&frame.pixels[..]).into();
    heprintln!(
        "PIFS-PARITY name={} rebuilt={} packets={} stack={} instr={} sha256={}",
        set.name,
        lost,
        index,
        stack,
        instr,
        Hex(hash)
    );
    true
}

/// The packets of a framed file, in the file's order.
fn frames(data: &'static [u8]) -> impl Iterator<Item = &'static [u8]> {
    let mut at = 0;
    core::iter::from_fn(move || {
        let len = usize::from(u16::from_le_bytes([*data.get(at)?, *data.get(at + 1)?]));
        let start = at + 2;
        at = (start + len).min(data.len());
        data.get(start..at)
    })
}

/// The frames of `data`, last first.
fn frames_reversed(data: &'static [u8]) -> impl Iterator<Item = &'static [u8]> {
    let mut ends = [0usize; 64];
    let mut n = 0;
    let mut at = 0;
    while at + 2 <= data.len() && n < ends.len() {
        let len = usize::from(u16::from_le_bytes([data[at], data[at + 1]]));
        at = (at + 2 + len).min(data.len());
        ends[n] = at;
        n += 1;
    }
    (0..n).rev().map(move |i| {
        let start = if i == 0 { 0 } else { ends[i - 1] };
        &data[start + 2..ends[i]]
    })
}

fn receive(set: &PacketSet) -> bool {
    let mut pixels = [0u8; PACKET_FRAME_LEN];
    let len = set.width * set.height * set.channels;
    let mut frame = Frame {
        pixels: &mut pixels[..len],
        width: set.width,
        channels: set.channels,
    };
    let Some((received, stack)) = receive_into(set, Scale::One, &mut frame) else {
        return false;
    };
    let hash: [u8; 32] = Sha256::digest(&frame.pixels[..]).into();
    heprintln!(
        "PIFS-PACKETS name={} received={} stack={} sha256={}",
        set.name,
        received,
        stack,
        Hex(hash)
    );
    // The same frame's memory, now a display.
    let drawn = if set.channels == 3 {
        on_display::<Rgb565>(set, &mut pixels)
    } else {
        on_display::<BinaryColor>(set, &mut pixels)
    };
    let Some(hash) = drawn else {
        return false;
    };
    heprintln!("PIFS-PACKETS-DRAWN name={} sha256={}", set.name, Hex(hash));
    // At half size, as a panel half the picture's size receives it.
    let (width, height) = (set.width.div_ceil(2), set.height.div_ceil(2));
    let mut half = Frame {
        pixels: &mut pixels[..width * height * set.channels],
        width,
        channels: set.channels,
    };
    if receive_into(set, Scale::Half, &mut half).is_none() {
        return false;
    }
    let hash: [u8; 32] = Sha256::digest(&half.pixels[..]).into();
    heprintln!("PIFS-PACKETS-HALF name={} sha256={}", set.name, Hex(hash));
    true
}

/// The packets of `set` received onto a display of colour `C` held in `memory`, through
/// `DrawSink`: the hash of its pixels.
fn on_display<C: Hashed>(set: &PacketSet, memory: &mut [u8]) -> Option<[u8; 32]> {
    let len = set.width * set.height * C::BYTES;
    let mut panel = Panel::<C> {
        pixels: memory.get_mut(..len)?,
        size: Size::new(set.width as u32, set.height as u32),
        colour: core::marker::PhantomData,
    };
    receive_into(set, Scale::One, &mut DrawSink::new(&mut panel))?;
    Some(Sha256::digest(&panel.pixels[..]).into())
}

/// A display in memory: each pixel's bytes ([`Hashed::put`]), row-major.
struct Panel<'a, C> {
    pixels: &'a mut [u8],
    size: Size,
    colour: core::marker::PhantomData<C>,
}

impl<C> OriginDimensions for Panel<'_, C> {
    fn size(&self) -> Size {
        self.size
    }
}

impl<C: Hashed> DrawTarget for Panel<'_, C> {
    type Color = C;
    type Error = Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<C>>>(&mut self, pixels: I) -> Result<(), Infallible> {
        for Pixel(p, c) in pixels {
            if p.x >= 0 && p.y >= 0 && (p.x as u32) < self.size.width {
                let at = (p.y as usize * self.size.width as usize + p.x as usize) * C::BYTES;
                if let Some(out) = self.pixels.get_mut(at..at + C::BYTES) {
                    c.put(out);
                }
            }
        }
        Ok(())
    }
}

/// Receives `set` into `sink` at `scale`: every packet but the lost ones, last first. Returns
/// the packets received and the largest peak stack of one, or `None` after reporting an error.
fn receive_into<S: PixelSink<Error = Infallible>>(
    set: &PacketSet,
    scale: Scale,
    sink: &mut S,
) -> Option<(usize, usize)> {
    let mut buffer = [0u8; MAX_PACKET];
    let mut drawn = [Rect::of_size(0, 0); MAX_REGIONS];
    let mut regions = 0;
    let mut received = 0;
    let mut stack = 0;
    for bytes in frames_reversed(set.data) {
        // The radio hands over one packet: it is copied into the receiver's buffer.
        let n = bytes.len().min(MAX_PACKET);
        buffer[..n].copy_from_slice(&bytes[..n]);
        let index = match Packet::parse(&buffer[..n]) {
            Ok(p) => p.index,
            Err(e) => {
                heprintln!("PIFS-ERROR name={} packet: {}", set.name, e);
                return None;
            }
        };
        if set.lost.contains(&index) {
            continue;
        }
        measure::paint();
        let base = measure::sp();
        let result = draw(&buffer[..n], scale, sink, &mut drawn, &mut regions);
        stack = stack.max(measure::peak(base));
        if let Err(e) = result {
            heprintln!("PIFS-ERROR name={} packet {}: {}", set.name, index, e);
            return None;
        }
        received += 1;
    }
    Some((received, stack))
}

/// The rebuild, not inlined, so that its stack is measured alone.
#[inline(never)]
fn rebuild_lost(code: &mut Rebuild<'_>) -> Result<(), decoder_core::RebuildError> {
    code.rebuild()
}

/// One received packet, parsed and drawn at `scale`: a region as it is (and remembered), a
/// preview around the regions already drawn. Not inlined, so that its stack is measured alone.
#[inline(never)]
fn draw<S: PixelSink<Error = Infallible>>(
    bytes: &[u8],
    scale: Scale,
    frame: &mut S,
    drawn: &mut [Rect; MAX_REGIONS],
    regions: &mut usize,
) -> Result<(), decoder_core::DrawError<Infallible>> {
    let packet = Packet::parse(bytes)?.scale(scale);
    match packet.kind {
        PacketKind::Region => {
            if *regions < MAX_REGIONS {
                drawn[*regions] = packet.output_region();
                *regions += 1;
            }
            packet.decode(frame)
        }
        PacketKind::Preview => packet.decode_around(&drawn[..*regions], frame),
    }
}
