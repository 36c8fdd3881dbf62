//! Packets for lossy radio links (`docs/bitstream.md`, section 9): an image cut into
//! self-contained packets of at most a given size, and a receiver's assembly of whatever
//! subset arrived.
//!
//! The sender ([`packetise`]): a *preview* packet codes the whole image coarsely; the rest of
//! the budget goes to *region* packets, each a rectangle of the image coded as its own stream
//! at the packet's size. The rectangles are cut so that each holds about the same share of the
//! bits a single stream of the image spends (measured leaf by leaf), by halving the image
//! across its longer side, recursively. Packets are sent in an order that spreads consecutive
//! ones over the image, so that a burst of losses does not open one large hole.
//!
//! The receiver ([`assemble`]): every valid packet of the image is drawn (the preview first,
//! under the regions); a region that did not arrive shows the preview, or, without one, is
//! interpolated from the pixels around it. Damaged packets, duplicates and packets of another
//! image are counted and ignored.

use crate::encoder::{psnr, Analysis, EncodeError, EncoderConfig, LeafBits, Target};
use decoder_core::internal::checksum::crc16;
use decoder_core::internal::packet::{packet_crc, PacketHeader, CRC_LEN, MAX_PACKET_HEADER_LEN};
use decoder_core::internal::syntax::Header;
use decoder_core::{DecodeError, Packet, PacketKind, PixelSink, Rect, Scale, Tile, REGION_UNIT};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::convert::Infallible;
use std::fmt;

mod parity;

pub use parity::{MAX_SHARDS, PARITY_TAG};

/// The smallest packet size [`packetise`] accepts, bytes.
pub const MIN_PACKET_SIZE: usize = 48;
/// The largest packet size [`packetise`] accepts, bytes.
pub const MAX_PACKET_SIZE: usize = 1024;
/// The default packet size: a LoRa payload.
pub const DEFAULT_PACKET_SIZE: usize = 255;

/// How to cut an image into packets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PacketOptions {
    /// Largest packet, bytes ([`MIN_PACKET_SIZE`] to [`MAX_PACKET_SIZE`]): 255 for LoRa, 233
    /// for Meshtastic, 51 for LoRaWAN at SF12.
    pub size: usize,
    /// The image's number, which every packet carries (receivers tell images apart by it);
    /// `None` for one made from the packets' content ([`content_id`]), so that images sent one
    /// after another differ without the sender counting them.
    pub image_id: Option<u16>,
    /// Whether the first packet is a preview of the whole image.
    pub preview: bool,
    /// Whether the preview is sent twice, first and half way (one packet of the budget), so
    /// that a receiver loses it only when it loses both.
    pub repeat_preview: bool,
    /// Parity packets sent after the others (part of the budget): any `N` of the `N + K`
    /// packets rebuild all `N` data packets (a Reed–Solomon erasure code; the data packets are
    /// then one byte shorter, the end of a parity packet's shard). 0 for none.
    pub parity: usize,
}

impl Default for PacketOptions {
    fn default() -> Self {
        PacketOptions {
            size: DEFAULT_PACKET_SIZE,
            image_id: None,
            preview: true,
            repeat_preview: false,
            parity: 0,
        }
    }
}

/// An image cut into packets, with what a receiver of all of them shows.
#[derive(Debug, Clone)]
pub struct Packetised {
    /// The packets, in sending order (packet `i` is `packets[i]`, but for a repeated preview,
    /// which is sent twice).
    pub packets: Vec<Vec<u8>>,
    /// The image id every packet carries.
    pub image_id: u16,
    /// How many of them are previews (the first ones).
    pub previews: usize,
    /// How many of them are parity packets (the last ones).
    pub parity: usize,
    /// Bytes of packet headers and checksums, in all.
    pub overhead_bytes: usize,
    /// The image all packets decode to (gray, or RGB triples).
    pub reconstruction: Vec<u8>,
    /// Its PSNR against the original, dB (over the three channels of a colour image).
    pub psnr: f64,
}

impl Packetised {
    /// Bytes of all packets.
    pub fn total_bytes(&self) -> usize {
        self.packets.iter().map(Vec::len).sum()
    }
}

/// Why an image could not be cut into packets.
#[derive(Debug, Clone, PartialEq)]
pub enum PacketError {
    /// The packet size is outside [`MIN_PACKET_SIZE`]..=[`MAX_PACKET_SIZE`].
    BadSize(usize),
    /// The target leaves fewer than one packet.
    BudgetTooSmall {
        /// Bytes the target allows.
        budget: usize,
        /// Bytes of one packet.
        packet: usize,
    },
    /// Quality targets are not supported for packets (their count must be known first).
    QualityTarget,
    /// The image was analysed in stripes wider than 512 pixels (or as one stripe, the
    /// default), which packets do not carry: packets are for receivers with decoder-core's
    /// default frontier, so their image is analysed in stripes of at most
    /// [`crate::DEFAULT_STRIPE_TILES`].
    StripeTooWide,
    /// The image has more than 65535 packets' worth of data.
    TooManyPackets,
    /// More packets than a parity code covers ([`MAX_SHARDS`], data and parity).
    TooManyForParity {
        /// Data and parity packets asked for.
        packets: usize,
    },
    /// A link's loss rate outside `0..=0.5` ([`parity_for_loss`]).
    BadLoss(f64),
    /// Encoding a packet's region failed.
    Encode(EncodeError),
}

impl fmt::Display for PacketError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PacketError::BadSize(n) => write!(
                f,
                "packet size {n} is outside {MIN_PACKET_SIZE}..={MAX_PACKET_SIZE} bytes"
            ),
            PacketError::BudgetTooSmall { budget, packet } => write!(
                f,
                "a budget of {budget} bytes holds no packet of {packet} bytes"
            ),
            PacketError::QualityTarget => {
                write!(
                    f,
                    "packets need a size target (--bpp or --bytes), not a PSNR"
                )
            }
            PacketError::StripeTooWide => {
                write!(
                    f,
                    "packets carry stripes of at most 512 pixels (--stripe-width 512 or less)"
                )
            }
            PacketError::TooManyPackets => write!(f, "more than 65535 packets"),
            PacketError::TooManyForParity { packets } => write!(
                f,
                "{packets} packets with parity: a parity code covers at most {MAX_SHARDS} (use larger packets or fewer bytes)"
            ),
            PacketError::BadLoss(p) => {
                write!(f, "a loss rate of {p} is outside 0 to 0.5")
            }
            PacketError::Encode(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for PacketError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            PacketError::Encode(e) => Some(e),
            _ => None,
        }
    }
}

impl From<EncodeError> for PacketError {
    fn from(e: EncodeError) -> Self {
        PacketError::Encode(e)
    }
}

/// The settings of the analysis of the whole image that [`packetise`] takes, for regions
/// analysed with `config`: leaves from a low rate's 8 pixels ([`crate::LOW_RATE_MIN_LEAF_LOG2`]).
/// That analysis only makes the preview (one packet for the whole image, a low-rate stream)
/// and weighs where the regions' bits go, which it does about as well as one from 4 px leaves
/// in a little over half the time (see docs/decisions.md).
pub fn overview_config(config: &EncoderConfig) -> EncoderConfig {
    let smallest = crate::LOW_RATE_MIN_LEAF_LOG2;
    EncoderConfig {
        min_leaf_log2: config.min_leaf_log2.max(smallest),
        max_leaf_log2: config.max_leaf_log2.max(smallest),
        ..config.clone()
    }
}

/// How far [`packetise_with_progress`] is: the region packets made so far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionsDone {
    /// Region packets made so far.
    pub done: usize,
    /// Region packets in all.
    pub regions: usize,
    /// The share of the image's pixels in the regions made so far (each region's analysis
    /// takes time about in proportion to its pixels).
    pub share: f64,
}

/// Cuts the image of `analysis` into packets of at most `options.size` bytes whose total is
/// at most `target` (a rate or a size, whole packets counted). `analysis` makes the preview and
/// the cut into regions ([`overview_config`] analyses it fastest); the regions are analysed
/// with `config`, whose stripes, like those of `analysis`, are at most 512 pixels
/// ([`crate::DEFAULT_STRIPE_TILES`], not the default whole width).
pub fn packetise(
    analysis: &Analysis,
    config: &EncoderConfig,
    target: Target,
    options: &PacketOptions,
) -> Result<Packetised, PacketError> {
    packetise_with_progress(analysis, config, target, options, &|_| {})
}

/// [`packetise`], calling `progress` before the region packets are made and each time one is
/// (from any thread, in no particular order): the regions' analyses are most of its time.
pub fn packetise_with_progress(
    analysis: &Analysis,
    config: &EncoderConfig,
    target: Target,
    options: &PacketOptions,
    progress: &(dyn Fn(RegionsDone) + Sync),
) -> Result<Packetised, PacketError> {
    if config.stripe == crate::WHOLE_WIDTH || config.stripe > crate::DEFAULT_STRIPE_TILES {
        return Err(PacketError::StripeTooWide);
    }
    let budget = budget_of(analysis, target)?;
    let layout = Layout::of(budget, options)?;
    let base = PacketHeader {
        image_id: 0,
        index: 0,
        count: layout.count,
        width: analysis.width() as u16,
        height: analysis.height() as u16,
        channels: analysis.channels(),
        region_units: None,
        coding: coding_of(analysis, config.stripe),
        deblock: 0,
    };
    let mut packets = data_packets(analysis, config, &layout, &base, progress)?;
    let image_id = options.image_id.unwrap_or_else(|| content_id(&packets));
    for packet in &mut packets {
        set_image_id(packet, image_id);
    }
    let parity_packets = match options.parity {
        0 => Vec::new(),
        k => {
            parity::parity_packets(&packets, k, image_id).ok_or(PacketError::TooManyForParity {
                packets: packets.len() + k,
            })?
        }
    };
    if layout.repeat {
        let again = packets[0].clone();
        packets.insert(packets.len() / 2, again);
    }
    let parity = parity_packets.len();
    packets.extend(parity_packets);
    // Everything but the region streams' payloads: headers, checksums, parity packets.
    let overhead_bytes = packets
        .iter()
        .map(|p| p.len() - payload_of(p).map_or(0, |n| n))
        .sum();
    let assembled = assemble(packets.iter().map(Vec::as_slice), u64::MAX)
        .map_err(|_| EncodeError::Internal("the packets do not assemble"))?;
    let sse: f64 = assembled
        .pixels
        .iter()
        .zip(analysis.source())
        .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
        .sum();
    Ok(Packetised {
        image_id,
        previews: layout.previews,
        parity,
        overhead_bytes,
        psnr: psnr(sse, assembled.pixels.len()),
        reconstruction: assembled.pixels,
        packets,
    })
}

/// The bytes `target` allows an image of `analysis`, whole packets counted.
fn budget_of(analysis: &Analysis, target: Target) -> Result<usize, PacketError> {
    let pixels = analysis.width() as usize * analysis.height() as usize;
    match target {
        Target::Bpp(b) if b.is_finite() && b > 0.0 => {
            Ok((b * pixels as f64 / 8.0).floor() as usize)
        }
        Target::Bytes(n) => Ok(n),
        Target::Psnr(_) => Err(PacketError::QualityTarget),
        Target::Bpp(_) => Err(PacketError::Encode(EncodeError::BadTarget(target))),
    }
}

/// Parity packets sized for a link: how many, and the picture a receiver can expect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParityChoice {
    /// Parity packets to send ([`PacketOptions::parity`]).
    pub parity: usize,
    /// The mean PSNR (dB) a receiver shows over the link's losses, as estimated.
    pub expected_psnr: f64,
}

/// The number of parity packets that gives the best picture on average over a link that loses
/// each packet independently with probability `loss` (0 to 0.5), for `target` and `options`
/// (whose own `parity` is ignored). Parity packets come out of the budget, so each one costs
/// every receiver some quality and saves those that lose up to that many packets. Estimated
/// from single streams of the analysis, without packetising: with `K` parity packets the
/// full picture is the regions' share of the budget coded as one stream (a few such streams,
/// interpolated between); when more packets are lost than `K` rebuild, the lost share of the
/// regions shows the preview (without one, a flat picture).
pub fn parity_for_loss(
    analysis: &Analysis,
    target: Target,
    options: &PacketOptions,
    loss: f64,
) -> Result<ParityChoice, PacketError> {
    if !(0.0..=0.5).contains(&loss) {
        return Err(PacketError::BadLoss(loss));
    }
    let budget = budget_of(analysis, target)?;
    let plain = PacketOptions {
        parity: 0,
        ..*options
    };
    let base = Layout::of(budget, &plain)?;
    // A region's header and checksum, about (a 768x512 image's region packet in at most 127
    // packets: 14 bytes and 2; `docs/bitstream.md`, section 9).
    let header = 16;
    // The image as one flat grey (or colour): its squared error is the pixels' variance.
    let source = analysis.source();
    let mean = source.iter().map(|&v| f64::from(v)).sum::<f64>() / source.len().max(1) as f64;
    let flat = source
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()
        / source.len().max(1) as f64;
    // The squared error of the best stream of `bytes`; a flat picture's where no stream is
    // that small.
    let mse = |bytes: usize| match analysis.encode_plain(bytes) {
        Ok(encoded) => 255.0 * 255.0 / 10f64.powf(encoded.psnr / 10.0),
        Err(_) => flat,
    };
    // Without a preview a lost region is interpolated from the ones around it: counted as
    // the flat picture.
    let preview = match base.previews {
        1 => mse(base.preview_size.saturating_sub(header)),
        _ => flat,
    };
    let layouts: Vec<(usize, Layout)> = (0..=usize::from(base.count) / 2)
        .map_while(|k| {
            let with = PacketOptions { parity: k, ..plain };
            Layout::of(budget, &with).ok().map(|layout| (k, layout))
        })
        .collect();
    if layouts.len() < 2 && loss > 0.0 {
        // Not even one parity packet: the data packets alone fill what a code covers.
        return Err(PacketError::TooManyForParity {
            packets: usize::from(base.count) + 1,
        });
    }
    // The full picture's error by the regions' share: single streams at a few of the shares,
    // the rest interpolated in the logarithm of the share (where a rate/distortion curve is
    // nearly straight, over a factor of two at most here).
    let shares: Vec<usize> = layouts
        .iter()
        .map(|(_, layout)| layout.region_share(header))
        .collect();
    let last = shares.len() - 1;
    let mut picked: Vec<usize> = (0..SIZING_STREAMS)
        .map(|i| shares[i * last / (SIZING_STREAMS - 1)])
        .collect();
    picked.dedup();
    let curve: Vec<(f64, f64)> = picked
        .par_iter()
        .map(|&share| ((share.max(1) as f64).ln(), mse(share).ln()))
        .collect();
    let estimates = layouts.iter().zip(&shares).map(|((k, layout), &share)| {
        let full = interpolate(&curve, (share.max(1) as f64).ln()).exp();
        let sent = usize::from(layout.count) + k;
        ParityChoice {
            parity: *k,
            expected_psnr: expected_psnr(sent, *k, loss, full, preview.max(full)),
        }
    });
    let mut best: Option<ParityChoice> = None;
    for estimate in estimates {
        if best.is_none_or(|b| estimate.expected_psnr > b.expected_psnr) {
            best = Some(estimate);
        }
    }
    best.ok_or(PacketError::BudgetTooSmall {
        budget,
        packet: options.size,
    })
}

/// Single streams [`parity_for_loss`] makes to know the full picture at every parity count.
const SIZING_STREAMS: usize = 5;

/// The piecewise-linear function through `points` (`(x, y)`, `x` falling or rising) at `x`,
/// its end segments extended.
fn interpolate(points: &[(f64, f64)], x: f64) -> f64 {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    match sorted.as_slice() {
        [] => 0.0,
        [(_, y)] => *y,
        _ => {
            let i = sorted
                .windows(2)
                .position(|w| x <= w[1].0)
                .unwrap_or(sorted.len() - 2);
            let ((x0, y0), (x1, y1)) = (sorted[i], sorted[i + 1]);
            if x1 == x0 {
                y0
            } else {
                y0 + (y1 - y0) * (x - x0) / (x1 - x0)
            }
        }
    }
}

/// The mean PSNR over the ways a link losing each of `sent` packets with probability `loss`
/// (below 1) can lose them, when any `sent - parity` of them rebuild the picture of squared
/// error `full`, and otherwise the lost share of the packets shows a picture of error `lost`.
fn expected_psnr(sent: usize, parity: usize, loss: f64, full: f64, lost: f64) -> f64 {
    let psnr_of = |mse: f64| 10.0 * (255.0 * 255.0 / mse.max(1e-9)).log10();
    // The binomial probabilities, term by term from none lost.
    let mut probability = (1.0 - loss).powi(sent as i32);
    let mut sum = 0.0;
    for lost_count in 0..=sent {
        let mse = if lost_count <= parity {
            full
        } else {
            full + (lost - full) * lost_count as f64 / sent as f64
        };
        sum += probability * psnr_of(mse);
        if loss < 1.0 {
            probability *=
                (sent - lost_count) as f64 / (lost_count + 1) as f64 * loss / (1.0 - loss);
        }
    }
    sum
}

/// How a budget divides into packets.
struct Layout {
    /// Distinct data packets (the packets' `count`).
    count: u16,
    /// Previews among them (0 or 1, the first).
    previews: usize,
    /// Whether the preview is sent twice.
    repeat: bool,
    /// Largest data packet, bytes (less than the packet size when parity packets must hold
    /// them).
    data_size: usize,
    /// Largest preview packet, bytes: `data_size`, or what the region packets leave of the
    /// budget.
    preview_size: usize,
}

impl Layout {
    fn of(budget: usize, options: &PacketOptions) -> Result<Layout, PacketError> {
        let size = options.size;
        if !(MIN_PACKET_SIZE..=MAX_PACKET_SIZE).contains(&size) {
            return Err(PacketError::BadSize(size));
        }
        // With parity, data packets leave room for the parity packets' own fields, and the
        // parity packets (full size) come out of the budget first.
        let k = options.parity;
        let data_size = match k {
            0 => size,
            k => parity::data_packet_size(size, k),
        };
        let for_data = budget.saturating_sub(k * size);
        let repeat = options.preview
            && options.repeat_preview
            && for_data / data_size >= MIN_PACKETS_TO_REPEAT;
        let mut count = (for_data / data_size).saturating_sub(usize::from(repeat));
        if count == 0 {
            return Err(PacketError::BudgetTooSmall {
                budget,
                packet: size,
            });
        }
        let previews = usize::from(options.preview && count > 1);
        // What the whole packets leave of the budget, when it is half a packet or more (and
        // at least `MIN_SHORT_PREVIEW`), is the preview, and the packet the preview would
        // have taken is one more region: a budget of a few packets (a small picture) then
        // goes to the regions, not to a preview a quarter of it, nor to nothing.
        let left = for_data % data_size;
        let mut preview_size = data_size;
        if previews == 1 && !repeat && left >= (data_size / 2).max(MIN_SHORT_PREVIEW) {
            count += 1;
            preview_size = left;
        }
        if k > 0 && count + k > MAX_SHARDS {
            return Err(PacketError::TooManyForParity { packets: count + k });
        }
        Ok(Layout {
            count: u16::try_from(count).map_err(|_| PacketError::TooManyPackets)?,
            previews,
            repeat,
            data_size,
            preview_size,
        })
    }

    fn regions(&self) -> usize {
        usize::from(self.count) - self.previews
    }

    /// The regions' share of the budget: their packets' bytes but for headers of
    /// `header_len` bytes (checksum included).
    fn region_share(&self, header_len: usize) -> usize {
        self.regions() * self.data_size.saturating_sub(header_len)
    }
}

/// The preview (if any) and the region packets, by index: the image cut where a single stream
/// of the regions' share of the budget spends equal bits, each part encoded on its own.
fn data_packets(
    analysis: &Analysis,
    config: &EncoderConfig,
    layout: &Layout,
    base: &PacketHeader,
    progress: &(dyn Fn(RegionsDone) + Sync),
) -> Result<Vec<Vec<u8>>, PacketError> {
    let size = layout.data_size;
    let mut head = [0u8; MAX_PACKET_HEADER_LEN];
    // A region header is the preview's and four one- or two-byte fields; then the checksum.
    let typical_header = base.write(&mut head) + 4 * 2 + CRC_LEN;
    let share = layout.region_share(typical_header);
    let leaves = analysis.leaf_bits(share.max(64))?;
    let mass = BitMass::of(analysis.width(), analysis.height(), &leaves);
    let areas = spread(mass.cut(layout.regions()));
    let made = Made::new(
        areas.len(),
        analysis.width() as usize * analysis.height() as usize,
    );
    progress(RegionsDone {
        done: 0,
        regions: areas.len(),
        share: 0.0,
    });
    let mut packets = Vec::with_capacity(usize::from(layout.count));
    if layout.previews == 1 {
        packets.push(fill_packet(base, layout.preview_size, |capacity| {
            analysis.encode_plain(capacity)
        })?);
    }
    let regions: Vec<Result<Vec<u8>, PacketError>> = areas
        .par_iter()
        .enumerate()
        .map(|(i, area)| {
            let header = PacketHeader {
                index: (layout.previews + i) as u16,
                region_units: Some(units_of(area)),
                ..*base
            };
            let region = analysis.region(*area, config)?;
            let header = PacketHeader {
                coding: coding_of(&region, config.stripe),
                ..header
            };
            let packet = fill_packet(&header, size, |capacity| region.encode_plain(capacity));
            progress(made.add(area.w as usize * area.h as usize));
            packet
        })
        .collect();
    for packet in regions {
        packets.push(packet?);
    }
    Ok(packets)
}

/// The region packets made so far and their pixels, counted from any thread.
struct Made {
    regions: usize,
    pixels: usize,
    counts: std::sync::Mutex<(usize, usize)>,
}

impl Made {
    fn new(regions: usize, pixels: usize) -> Made {
        Made {
            regions,
            pixels,
            counts: std::sync::Mutex::new((0, 0)),
        }
    }

    /// Counts one more region of `pixels` pixels made; what is done now.
    fn add(&self, pixels: usize) -> RegionsDone {
        let mut counts = match self.counts.lock() {
            Ok(c) => c,
            Err(poisoned) => poisoned.into_inner(),
        };
        counts.0 += 1;
        counts.1 += pixels;
        RegionsDone {
            done: counts.0,
            regions: self.regions,
            share: counts.1 as f64 / self.pixels.max(1) as f64,
        }
    }
}

/// A packet's coding fields for a stream of `analysis` in stripes of `stripe` tiles: its leaf
/// sizes and stripe (each packet carries its own stream's, so the preview's analysis may stop
/// at larger leaves than the regions').
fn coding_of(analysis: &Analysis, stripe: u8) -> [u8; 2] {
    [
        analysis.max_leaf_log2() << 4 | analysis.min_leaf_log2(),
        stripe,
    ]
}

/// An image id made from an image's data packets (written with id 0): the CRC-16 of their
/// bytes. Packets of different pictures, or of one picture coded differently, get different
/// ids but for one chance in 65 536; the same packets get the same id.
pub fn content_id(packets: &[Vec<u8>]) -> u16 {
    crc16(&packets.concat())
}

/// Writes `id` into a packet's image id field and seals it again (its checksum).
fn set_image_id(packet: &mut [u8], id: u16) {
    let Some(body_len) = packet.len().checked_sub(CRC_LEN) else {
        return;
    };
    let (body, crc) = packet.split_at_mut(body_len);
    if let Some(field) = body.get_mut(1..3) {
        field.copy_from_slice(&id.to_le_bytes());
    }
    crc.copy_from_slice(&packet_crc(body));
}

/// The smallest preview packet made of what the region packets leave of a budget, bytes:
/// below it, the preview is a whole packet as usual.
const MIN_SHORT_PREVIEW: usize = 128;

/// The fewest packets of which one is given to a second copy of the preview.
const MIN_PACKETS_TO_REPEAT: usize = 8;

/// Payload bytes of a valid packet.
fn payload_of(packet: &[u8]) -> Option<usize> {
    Packet::parse(packet)
        .ok()
        .map(|p| p.stream_header().payload_len as usize)
}

/// A packet of at most `size` bytes with `header`'s fields around the payload of the stream
/// `encode` makes for a byte budget (the stream's own header is dropped: the packet's fields
/// replace it). The range coder's last bytes are cut to those the packet still decodes the
/// same without (a receiver reads zeros past a packet's end), and the budget is first tried
/// with the bytes that usually frees.
fn fill_packet(
    header: &PacketHeader,
    size: usize,
    encode: impl Fn(usize) -> Result<crate::Encoded, EncodeError>,
) -> Result<Vec<u8>, PacketError> {
    let mut head = [0u8; MAX_PACKET_HEADER_LEN];
    let capacity = size - header.write(&mut head) - CRC_LEN;
    // The stream's own header is counted by its budget, not by the packet.
    let stream_header = region_stream_header(header, capacity).encoded_len();
    for extra in [FLUSH_SAVING, 0] {
        let encoded = encode(capacity + extra + stream_header)?;
        let (stream, offset) = Header::parse(&encoded.bytes).map_err(EncodeError::Syntax)?;
        if [
            stream.max_leaf_log2 << 4 | stream.min_leaf_log2,
            stream.stripe,
        ] != header.coding
        {
            return Err(EncodeError::Internal("a region's stream has other coding fields").into());
        }
        let header = PacketHeader {
            deblock: stream.deblock,
            ..*header
        };
        let packet = shortest_packet(&header, &encoded.bytes[offset..])?;
        if packet.len() <= size {
            return Ok(packet);
        }
    }
    Err(EncodeError::Internal("a region's stream does not fit its packet").into())
}

/// The header of the stream of `packet`'s region with a payload of `payload_len` bytes: what
/// the region's encoder writes before the packet's fields replace it.
fn region_stream_header(packet: &PacketHeader, payload_len: usize) -> Header {
    let (width, height) = match packet.region_units {
        None => (packet.width, packet.height),
        Some([x, y, w, h]) => {
            let unit = REGION_UNIT as u16;
            let side = |start: u16, size: u16, whole: u16| {
                (size * unit).min(whole.saturating_sub(start * unit))
            };
            (side(x, w, packet.width), side(y, h, packet.height))
        }
    };
    Header {
        width,
        height,
        channels: packet.channels,
        bit_depth: 8,
        min_leaf_log2: packet.coding[0] & 0x0F,
        max_leaf_log2: packet.coding[0] >> 4,
        stripe: packet.coding[1],
        deblock: packet.deblock,
        payload_len: payload_len as u32,
        checksum: 0,
        range: None,
    }
}

/// Bytes the shortest ending of the range coder usually saves ([`shortest_packet`]).
const FLUSH_SAVING: usize = 2;

/// The most bytes of a range coder's final flush that a packet's end may cut: a receiver reads
/// zeros past the payload.
const FLUSH_BYTES: usize = 4;

/// The packet of `header` and `payload`, its payload cut by as many of its last bytes (at
/// most [`FLUSH_BYTES`], the range coder's final flush) as leave its pixels unchanged.
fn shortest_packet(header: &PacketHeader, payload: &[u8]) -> Result<Vec<u8>, PacketError> {
    let make = |payload: &[u8]| {
        let mut packet = vec![0u8; MAX_PACKET_HEADER_LEN + payload.len() + CRC_LEN];
        let len = header
            .write_packet(payload, &mut packet)
            .expect("room for the packet");
        packet.truncate(len);
        packet
    };
    let pixels = |packet: &[u8]| -> Option<Vec<u8>> {
        let p = Packet::parse(packet).ok()?;
        let mut local = RegionBuffer::of(&p);
        p.decode(&mut local).ok()?;
        Some(local.pixels)
    };
    let full = make(payload);
    let Some(reference) = pixels(&full) else {
        return Err(EncodeError::Internal("a packet does not decode").into());
    };
    let mut best = full;
    for cut in 1..=FLUSH_BYTES.min(payload.len()) {
        let shorter = make(&payload[..payload.len() - cut]);
        if pixels(&shorter).as_ref() != Some(&reference) {
            break;
        }
        best = shorter;
    }
    Ok(best)
}

/// A region in [`REGION_UNIT`]s, as the packet header carries it.
fn units_of(area: &Rect) -> [u16; 4] {
    [area.x, area.y, area.w, area.h].map(|v| v.div_ceil(REGION_UNIT) as u16)
}

/// Bits per [`REGION_UNIT`] square of the image, from a stream's leaves.
struct BitMass {
    /// Squares per row and column.
    cols: usize,
    rows: usize,
    /// Image size, pixels.
    width: u32,
    height: u32,
    /// Bits per square, row-major.
    bits: Vec<f64>,
}

impl BitMass {
    /// Spreads each leaf's bits evenly over its pixels in the image.
    fn of(width: u32, height: u32, leaves: &[LeafBits]) -> BitMass {
        let cols = width.div_ceil(REGION_UNIT) as usize;
        let rows = height.div_ceil(REGION_UNIT) as usize;
        let mut bits = vec![0.0; cols * rows];
        for leaf in leaves {
            let n = leaf.node;
            let x1 = (n.x + n.size()).min(width);
            let y1 = (n.y + n.size()).min(height);
            let per_pixel = leaf.bits / f64::from((x1 - n.x) * (y1 - n.y));
            for y in n.y..y1 {
                for x in n.x..x1 {
                    let cell = (y / REGION_UNIT) as usize * cols + (x / REGION_UNIT) as usize;
                    bits[cell] += per_pixel;
                }
            }
        }
        BitMass {
            cols,
            rows,
            width,
            height,
            bits,
        }
    }

    /// `n` rectangles covering the image, each with about `1/n` of the bits: the image halved
    /// recursively across its longer side where the bits divide in the ratio of the packets
    /// each side gets.
    fn cut(&self, n: usize) -> Vec<Rect> {
        let mut out = Vec::with_capacity(n);
        self.cut_into([0, 0, self.cols, self.rows], n, &mut out);
        out
    }

    /// `cells` is `[x, y, w, h]` in squares.
    fn cut_into(&self, cells: [usize; 4], n: usize, out: &mut Vec<Rect>) {
        let [x, y, w, h] = cells;
        if n <= 1 || (w <= 1 && h <= 1) {
            out.push(self.rect(cells));
            return;
        }
        let across_columns = w >= h;
        let len = if across_columns { w } else { h };
        // Bits of each column (or row) of the rectangle.
        let lines: Vec<f64> = (0..len)
            .map(|i| {
                let (cx, cy, cw, ch) = if across_columns {
                    (x + i, y, 1, h)
                } else {
                    (x, y + i, w, 1)
                };
                (cy..cy + ch)
                    .flat_map(|r| (cx..cx + cw).map(move |c| (r, c)))
                    .map(|(r, c)| self.bits[r * self.cols + c])
                    .sum()
            })
            .collect();
        let total: f64 = lines.iter().sum();
        let first = n / 2;
        let wanted = total * first as f64 / n as f64;
        let mut best = (f64::INFINITY, 1);
        let mut sum = 0.0;
        for (i, bits) in lines.iter().enumerate().take(len - 1) {
            sum += bits;
            let miss = (sum - wanted).abs();
            if miss < best.0 {
                best = (miss, i + 1);
            }
        }
        let at = best.1;
        // Each side gets at least one packet per square it could hold.
        let (a, b) = if across_columns {
            ([x, y, at, h], [x + at, y, w - at, h])
        } else {
            ([x, y, w, at], [x, y + at, w, h - at])
        };
        let first = first.min(a[2] * a[3]).max(1);
        let second = (n - first).min(b[2] * b[3]).max(1);
        self.cut_into(a, first, out);
        self.cut_into(b, second, out);
    }

    /// The pixels of `[x, y, w, h]` squares, cut to the image.
    fn rect(&self, [x, y, w, h]: [usize; 4]) -> Rect {
        let px = x as u32 * REGION_UNIT;
        let py = y as u32 * REGION_UNIT;
        Rect {
            x: px,
            y: py,
            w: (w as u32 * REGION_UNIT).min(self.width - px),
            h: (h as u32 * REGION_UNIT).min(self.height - py),
        }
    }
}

/// The rectangles in an order that spreads neighbours in the list apart: the cut's order
/// keeps neighbours together, so it is read with its index bits reversed. A burst of lost
/// packets then loses scattered regions, and a picture shown as packets arrive fills in
/// everywhere at once.
fn spread(areas: Vec<Rect>) -> Vec<Rect> {
    let n = areas.len();
    let bits = usize::BITS - n.next_power_of_two().leading_zeros() - 1;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| {
        if bits == 0 {
            i
        } else {
            i.reverse_bits() >> (usize::BITS - bits)
        }
    });
    order.into_iter().map(|i| areas[i]).collect()
}

/// The framed form for serial links (`docs/bitstream.md`, section 9): each packet behind its length, two bytes little-endian.
pub fn frame(packets: &[Vec<u8>]) -> Vec<u8> {
    let mut out = Vec::with_capacity(packets.iter().map(|p| p.len() + 2).sum());
    for p in packets {
        out.extend_from_slice(&(p.len() as u16).to_le_bytes());
        out.extend_from_slice(p);
    }
    out
}

/// The packets of a framed file; a last frame cut short is kept as it is (it will fail its
/// check, like any damaged packet).
pub fn unframe(data: &[u8]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut rest = data;
    while rest.len() >= 2 {
        let len = usize::from(u16::from_le_bytes([rest[0], rest[1]]));
        let end = (2 + len).min(rest.len());
        out.push(rest[2..end].to_vec());
        rest = &rest[end..];
    }
    out
}

/// Whether `data` (a whole file) is a stream rather than packets: it opens as a stream of any
/// version does (format 21 and earlier: `PIFS`), and it is not an exact framing of packets (a
/// frame's two length bytes may begin the way a stream does: its third byte then is a
/// packet's first).
pub fn is_stream_data(data: &[u8]) -> bool {
    use decoder_core::internal::syntax::check_first_byte;
    let stream_like = matches!(
        check_first_byte(data, decoder_core::STREAM_TAG),
        Ok(()) | Err(decoder_core::DecodeError::UnsupportedVersion(_))
    ) || data.starts_with(&decoder_core::internal::format::LEGACY_MAGIC);
    stream_like && !is_framing(data)
}

/// Whether `data` is exactly a sequence of frames, each holding what opens as a packet or a
/// parity packet of any version.
fn is_framing(data: &[u8]) -> bool {
    let kind = |b: u8| b >> 6;
    let mut rest = data;
    while rest.len() >= 2 {
        let len = usize::from(u16::from_le_bytes([rest[0], rest[1]]));
        match rest.get(2..2 + len) {
            Some([first, ..])
                if kind(*first) == kind(decoder_core::PACKET_TAG)
                    || kind(*first) == kind(parity::PARITY_TAG) => {}
            _ => return false,
        }
        rest = &rest[2 + len..];
    }
    rest.is_empty() && !data.is_empty()
}

/// What a receiver made of a set of packets.
#[derive(Debug, Clone)]
pub struct Assembled {
    /// The image's number.
    pub image_id: u16,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// 1 (gray) or 3 (RGB).
    pub channels: u8,
    /// Row-major pixels (RGB triples for colour).
    pub pixels: Vec<u8>,
    /// How many packets the image was sent as.
    pub count: u16,
    /// Indices of the packets drawn, ascending.
    pub received: Vec<u16>,
    /// Indices of the packets that did not arrive (or did not decode), ascending.
    pub missing: Vec<u16>,
    /// Indices of the packets that did not arrive but were rebuilt from parity packets
    /// (among `received`).
    pub recovered: Vec<u16>,
    /// Parity packets of the image held (distinct ones).
    pub parity: usize,
    /// Whether the preview was drawn.
    pub preview: bool,
    /// Share of the image's pixels that a region packet drew (the rest is preview or
    /// interpolation).
    pub coverage: f64,
    /// Inputs that were not valid packets (damaged, truncated, not a packet).
    pub rejected: usize,
    /// Valid packets of another image, or that disagree with the image's size.
    pub foreign: usize,
    /// Packets received more than once (the copies beyond the first).
    pub duplicates: usize,
    /// What tells the image's packets from others' ([`identity`]).
    identity: Identity,
}

impl Assembled {
    /// Whether `packet` is one of the image's: a valid data packet of its id, size, channels
    /// and count, or a parity packet of its id and count.
    pub fn owns(&self, packet: &[u8]) -> bool {
        let (image_id, .., count) = self.identity;
        match decoder_core::ParityPacket::parse(packet) {
            Ok(parity) => parity.image_id == image_id && parity.count == count,
            Err(_) => Packet::parse(packet).is_ok_and(|p| identity(&p) == self.identity),
        }
    }

    /// How many more packets, any of the image's data or parity packets not held, would
    /// complete it: the data packets missing, less the parity packets held when any were sent
    /// (without parity, exactly the missing ones are needed).
    pub fn packets_short(&self) -> usize {
        self.missing.len().saturating_sub(self.parity)
    }
}

/// Why no image could be assembled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AssembleError {
    /// No input was a valid packet; the first input's error is given.
    NoValidPacket(Option<DecodeError>),
    /// The image at the scale asked for would have more pixels than allowed.
    TooLarge {
        /// Width at that scale, pixels.
        width: u32,
        /// Height at that scale, pixels.
        height: u32,
    },
}

impl fmt::Display for AssembleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AssembleError::NoValidPacket(Some(e)) => write!(f, "no valid packet ({e})"),
            AssembleError::NoValidPacket(None) => write!(f, "no packet"),
            AssembleError::TooLarge { width, height } => {
                write!(
                    f,
                    "{width}x{height} pixels at that scale: more than allowed"
                )
            }
        }
    }
}

impl std::error::Error for AssembleError {}

/// Assembles the image from whatever packets arrived, in any order. The image is the one
/// most of the valid packets belong to; everything else is counted and ignored. Packets of
/// images larger than `max_pixels` are refused (as [`DecodeError::TooLarge`]) before anything
/// is allocated for them.
pub fn assemble<'a>(
    inputs: impl IntoIterator<Item = &'a [u8]>,
    max_pixels: u64,
) -> Result<Assembled, AssembleError> {
    assemble_at(inputs, max_pixels, Scale::One)
}

/// [`assemble`] at `scale` of the image's size, every packet drawn at that scale
/// ([`Packet::scale`]): the picture a smaller (or larger) display shows, made without the
/// full-size one. The result's size and pixels are the scaled image's, which must also be
/// within `max_pixels`.
pub fn assemble_at<'a>(
    inputs: impl IntoIterator<Item = &'a [u8]>,
    max_pixels: u64,
    scale: Scale,
) -> Result<Assembled, AssembleError> {
    let mut valid: Vec<(Packet<'a>, &'a [u8])> = Vec::new();
    let mut parities = Vec::new();
    let mut rejected = 0;
    let mut first_error = None;
    for data in inputs {
        if let Ok(parity) = decoder_core::ParityPacket::parse(data) {
            parities.push(parity);
            continue;
        }
        match parse_within(data, max_pixels) {
            Ok(p) => valid.push((p, data)),
            Err(e) => {
                rejected += 1;
                first_error.get_or_insert(e);
            }
        }
    }
    // The image most packets agree on: its id and geometry.
    let mut votes: BTreeMap<Identity, usize> = BTreeMap::new();
    for (p, _) in &valid {
        *votes.entry(identity(p)).or_default() += 1;
    }
    let Some((&chosen, _)) = votes.iter().max_by_key(|(_, &n)| n) else {
        return Err(AssembleError::NoValidPacket(first_error));
    };
    let (image_id, width, height, channels, count) = chosen;
    let (w, h) = (scale.apply(width.into()), scale.apply(height.into()));
    if u64::from(w) * u64::from(h) > max_pixels {
        return Err(AssembleError::TooLarge {
            width: w,
            height: h,
        });
    }
    let mut foreign = 0;
    let mut duplicates = 0;
    let mut raw: BTreeMap<u16, &'a [u8]> = BTreeMap::new();
    for (p, data) in &valid {
        if identity(p) != chosen {
            foreign += 1;
        } else if let std::collections::btree_map::Entry::Vacant(slot) = raw.entry(p.index) {
            slot.insert(data);
        } else {
            duplicates += 1;
        }
    }
    // Missing packets rebuilt from the image's parity packets, when enough arrived.
    let ours: Vec<decoder_core::ParityPacket<'_>> = parities
        .into_iter()
        .filter(|p| p.image_id == image_id && p.count == count)
        .collect();
    let mut parity_indices: Vec<u16> = ours.iter().map(|p| p.index).collect();
    parity_indices.sort_unstable();
    parity_indices.dedup();
    let parity = parity_indices.len();
    let rebuilt = if ours.is_empty() || raw.len() == usize::from(count) {
        Vec::new()
    } else {
        let by_index: Vec<Option<&[u8]>> = (0..count).map(|i| raw.get(&i).copied()).collect();
        parity::rebuild(&by_index, &ours, image_id)
    };
    let mut by_index: BTreeMap<u16, Packet<'_>> = BTreeMap::new();
    for (index, data) in &raw {
        if let Ok(p) = Packet::parse(data) {
            by_index.insert(*index, p.scale(scale));
        }
    }
    let mut recovered = Vec::new();
    for (index, data) in &rebuilt {
        if let Ok(p) = parse_within(data, max_pixels) {
            if identity(&p) == chosen && p.index == *index {
                by_index.insert(*index, p.scale(scale));
                recovered.push(*index);
            }
        }
    }
    let ch = usize::from(channels);
    let mut canvas = Canvas {
        width: w as usize,
        channels: ch,
        pixels: vec![0; w as usize * h as usize * ch],
        covered: vec![false; w as usize * h as usize],
    };
    let mut received = Vec::new();
    let mut preview = false;
    // Previews first, under the regions.
    let ordered = by_index
        .values()
        .filter(|p| p.kind == PacketKind::Preview)
        .chain(by_index.values().filter(|p| p.kind == PacketKind::Region));
    for p in ordered {
        if canvas.draw(p).is_ok() {
            received.push(p.index);
            preview |= p.kind == PacketKind::Preview;
        }
    }
    received.sort_unstable();
    let drawn = canvas.covered.iter().filter(|&&c| c).count();
    let coverage = drawn as f64 / canvas.covered.len() as f64;
    if !preview {
        canvas.conceal(w as usize, h as usize);
    }
    let missing = (0..count)
        .filter(|i| received.binary_search(i).is_err())
        .collect();
    Ok(Assembled {
        image_id,
        width: w,
        height: h,
        channels,
        pixels: canvas.pixels,
        count,
        received,
        missing,
        recovered,
        parity,
        preview,
        coverage,
        rejected,
        foreign,
        duplicates,
        identity: chosen,
    })
}

/// Parses a packet of an image of at most `max_pixels`.
fn parse_within(data: &[u8], max_pixels: u64) -> Result<Packet<'_>, DecodeError> {
    let p = Packet::parse(data)?;
    if u64::from(p.width) * u64::from(p.height) > max_pixels {
        return Err(DecodeError::TooLarge {
            width: p.width,
            height: p.height,
        });
    }
    Ok(p)
}

/// What tells one image's packets from another's: its id, width, height, channels and count.
type Identity = (u16, u16, u16, u8, u16);

/// A packet's [`Identity`].
fn identity(p: &Packet<'_>) -> Identity {
    (p.image_id, p.width, p.height, p.channels, p.count)
}

/// The receiver's image and which of its pixels a region drew.
struct Canvas {
    width: usize,
    channels: usize,
    pixels: Vec<u8>,
    covered: Vec<bool>,
}

impl Canvas {
    /// Draws packet `p`: into a buffer of its own first, so that a packet that fails to
    /// decode leaves nothing behind.
    fn draw(&mut self, p: &Packet<'_>) -> Result<(), DecodeError> {
        let area = p.output_region();
        let mut local = RegionBuffer::of(p);
        p.decode(&mut local)?;
        let row = area.w as usize * self.channels;
        for (r, src) in local.pixels.chunks_exact(row).enumerate() {
            let y = area.y as usize + r;
            let start = (y * self.width + area.x as usize) * self.channels;
            self.pixels[start..start + row].copy_from_slice(src);
            if p.kind == PacketKind::Region {
                let at = y * self.width + area.x as usize;
                self.covered[at..at + area.w as usize].fill(true);
            }
        }
        Ok(())
    }

    /// Fills every pixel no region drew (there is no preview) from the drawn pixels around
    /// it: the mean of the linear interpolations between the nearest drawn pixels on its row
    /// and on its column (those that exist), or grey when nothing was drawn at all.
    fn conceal(&mut self, w: usize, h: usize) {
        let ch = self.channels;
        if !self.covered.contains(&true) {
            self.pixels.fill(128);
            return;
        }
        let mut sum = vec![0f32; w * h * ch];
        let mut weight = vec![0f32; w * h];
        let lines = [(h, w, 1usize, w), (w, h, w, 1usize)];
        for (count, len, step, stride) in lines {
            for line in 0..count {
                let at = |i: usize| line * stride + i * step;
                let mut before: Option<usize> = None;
                let mut i = 0;
                while i < len {
                    if self.covered[at(i)] {
                        before = Some(i);
                        i += 1;
                        continue;
                    }
                    let gap_end = (i..len).find(|&j| self.covered[at(j)]);
                    let end = gap_end.unwrap_or(len);
                    for k in i..end {
                        let p = at(k);
                        for c in 0..ch {
                            let value = match (before, gap_end) {
                                (Some(a), Some(b)) => {
                                    let t = (k - a) as f32 / (b - a) as f32;
                                    let va = f32::from(self.pixels[at(a) * ch + c]);
                                    let vb = f32::from(self.pixels[at(b) * ch + c]);
                                    va + t * (vb - va)
                                }
                                (Some(a), None) => f32::from(self.pixels[at(a) * ch + c]),
                                (None, Some(b)) => f32::from(self.pixels[at(b) * ch + c]),
                                (None, None) => continue,
                            };
                            sum[p * ch + c] += value;
                        }
                        if before.is_some() || gap_end.is_some() {
                            weight[p] += 1.0;
                        }
                    }
                    i = end;
                }
            }
        }
        for p in 0..w * h {
            if self.covered[p] {
                continue;
            }
            for c in 0..ch {
                self.pixels[p * ch + c] = if weight[p] > 0.0 {
                    (sum[p * ch + c] / weight[p]).round().clamp(0.0, 255.0) as u8
                } else {
                    128
                };
            }
        }
    }
}

/// A sink holding one region's pixels (image coordinates in, region coordinates stored).
struct RegionBuffer {
    area: Rect,
    channels: usize,
    pixels: Vec<u8>,
}

impl RegionBuffer {
    /// An empty buffer for packet `p`'s region (at the packet's scale).
    fn of(p: &Packet<'_>) -> RegionBuffer {
        let channels = usize::from(p.channels);
        let area = p.output_region();
        RegionBuffer {
            area,
            channels,
            pixels: vec![0; area.w as usize * area.h as usize * channels],
        }
    }
}

impl PixelSink for RegionBuffer {
    type Error = Infallible;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
        let ch = self.channels;
        let row = tile.area.w as usize * ch;
        if row == 0 {
            return Ok(());
        }
        let x = tile.area.x.saturating_sub(self.area.x) as usize;
        for (r, src) in tile.pixels.chunks_exact(row).enumerate() {
            let y = tile.area.y.saturating_sub(self.area.y) as usize + r;
            let start = (y * self.area.w as usize + x) * ch;
            if let Some(dst) = self.pixels.get_mut(start..start + row) {
                dst.copy_from_slice(src);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_goes_through_its_points_and_extends_its_ends() {
        let points = [(3.0, 30.0), (1.0, 10.0), (2.0, 40.0)];
        for (x, y) in points {
            assert_eq!(interpolate(&points, x), y);
        }
        assert_eq!(interpolate(&points, 1.5), 25.0);
        assert_eq!(interpolate(&points, 0.0), -20.0);
        assert_eq!(interpolate(&points, 4.0), 20.0);
        assert_eq!(interpolate(&[(1.0, 5.0)], 9.0), 5.0);
    }

    #[test]
    fn expected_psnr_is_the_full_pictures_without_loss_or_beyond_the_parity() {
        let psnr = |mse: f64| 10.0 * (255.0f64 * 255.0 / mse).log10();
        let (full, lost) = (20.0, 200.0);
        assert!((expected_psnr(50, 0, 0.0, full, lost) - psnr(full)).abs() < 1e-9);
        assert!((expected_psnr(50, 50, 0.3, full, lost) - psnr(full)).abs() < 1e-9);
        // More loss, less to expect; more parity, more (at the same full picture).
        let by_loss: Vec<f64> = [0.05, 0.1, 0.2]
            .iter()
            .map(|&p| expected_psnr(50, 5, p, full, lost))
            .collect();
        assert!(by_loss.windows(2).all(|w| w[0] > w[1]), "{by_loss:?}");
        let by_parity: Vec<f64> = [0, 5, 10]
            .iter()
            .map(|&k| expected_psnr(50, k, 0.1, full, lost))
            .collect();
        assert!(by_parity.windows(2).all(|w| w[0] < w[1]), "{by_parity:?}");
    }

    /// A budget's bytes past its whole packets go to the preview when they are half a packet
    /// or more, and the packet the preview would have taken to a region; otherwise, and with
    /// a repeated preview, the layout is whole packets, the first a preview.
    #[test]
    fn what_whole_packets_leave_of_a_budget_is_the_preview() {
        let options = PacketOptions::default();
        let layout = |budget: usize, options: &PacketOptions| {
            let l = Layout::of(budget, options).expect("a layout");
            (
                usize::from(l.count),
                l.previews,
                l.regions(),
                l.preview_size,
            )
        };
        // 1200 bytes: four regions of 255 and a preview of the 180 left (before: a preview
        // and three regions, 180 bytes unused).
        assert_eq!(layout(1200, &options), (5, 1, 4, 180));
        // Less than half a packet left: whole packets as before.
        assert_eq!(layout(1100, &options), (4, 1, 3, 255));
        assert_eq!(layout(12_288, &options), (48, 1, 47, 255));
        // Without a preview, or with it sent twice, the rule does not apply.
        let plain = PacketOptions {
            preview: false,
            ..options
        };
        assert_eq!(layout(1200, &plain), (4, 0, 4, 255));
        let twice = PacketOptions {
            repeat_preview: true,
            ..options
        };
        assert_eq!(layout(2200, &twice), (7, 1, 6, 255));
        // Small packets never make a preview under `MIN_SHORT_PREVIEW` bytes.
        let small = PacketOptions {
            size: 200,
            ..options
        };
        assert_eq!(layout(1000 + 120, &small), (5, 1, 4, 200));
        // Every layout stays within its budget.
        for budget in (300..5000).step_by(37) {
            let l = Layout::of(budget, &options).expect("a layout");
            let bytes = l.regions() * l.data_size + l.previews * l.preview_size;
            assert!(bytes <= budget, "{budget}: {bytes}");
        }
    }

    #[test]
    fn frames_round_trip_and_a_cut_frame_stays_a_packet() {
        let packets = vec![vec![1u8, 2, 3], vec![], vec![9u8; 300]];
        let framed = frame(&packets);
        assert_eq!(framed.len(), 3 + 300 + 3 * 2);
        assert_eq!(unframe(&framed), packets);
        let cut = unframe(&framed[..framed.len() - 10]);
        assert_eq!(cut.len(), 3);
        assert_eq!(cut[2].len(), 290);
    }

    /// A framed file whose first packet is as many bytes as a stream's tag says (151 in format
    /// 23) opens with that tag: the framing, not the first byte, says it is packets; a stream,
    /// of this version or of format 21 (`PIFS`), is a stream.
    #[test]
    fn a_framed_file_is_told_from_a_stream_by_its_framing() {
        let mut packet = vec![decoder_core::PACKET_TAG];
        packet.resize(usize::from(decoder_core::STREAM_TAG), 7);
        let framed = frame(&[packet.clone(), packet]);
        assert_eq!(framed[0], decoder_core::STREAM_TAG);
        assert!(!is_stream_data(&framed));
        let mut stream = framed.clone();
        stream[2] = 0;
        assert!(is_stream_data(&stream));
        assert!(is_stream_data(b"PIFS\x15\x01\x08\x00"));
        assert!(!is_stream_data(&[decoder_core::PACKET_TAG, 1, 2]));
        assert!(!is_stream_data(&[]));
    }
}
