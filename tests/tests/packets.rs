//! Packets (`docs/bitstream.md`, section 9): an image cut into packets, and what a receiver
//! makes of any subset of them, in any order, with duplicates, packets of another image and
//! damaged packets among them.

mod common;

use decoder_core::{Packet, PacketKind, ParityPacket, Rebuild, RebuildError, Rect, Scale};
use host_encoder::packets::{
    assemble, assemble_at, overview_config, packetise, packetise_with_progress, parity_for_loss,
    AssembleError, PacketError, PacketOptions, Packetised,
};
use host_encoder::{EncoderConfig, Target};
use proptest::prelude::*;
use std::sync::OnceLock;

const WIDTH: u32 = 96;
const HEIGHT: u32 = 64;
const SIZE: usize = 48;

/// Packets' settings: stripes of at most 512 pixels.
fn config() -> EncoderConfig {
    EncoderConfig {
        stripe: host_encoder::DEFAULT_STRIPE_TILES,
        ..EncoderConfig::default()
    }
}

/// The test image cut into 48-byte packets, with a preview (image id 1) and without (id 2).
fn sets() -> &'static (Packetised, Packetised, Vec<u8>) {
    static SETS: OnceLock<(Packetised, Packetised, Vec<u8>)> = OnceLock::new();
    SETS.get_or_init(|| {
        let plane = common::synthetic(WIDTH, HEIGHT, 31, 6);
        let source = plane.data.clone();
        let analysis = common::analyse_with(plane, &config());
        let make = |image_id, preview| {
            let options = PacketOptions {
                size: SIZE,
                image_id,
                preview,
                repeat_preview: false,
                parity: 0,
            };
            packetise(&analysis, &config(), Target::Bytes(14 * SIZE), &options).unwrap()
        };
        (make(Some(1), true), make(Some(2), false), source)
    })
}

/// The pixels of `area` of a row-major gray image `width` wide.
fn crop(pixels: &[u8], width: u32, area: Rect) -> Vec<u8> {
    (area.y..area.y + area.h)
        .flat_map(|y| {
            let at = (y * width + area.x) as usize;
            pixels[at..at + area.w as usize].iter().copied()
        })
        .collect()
}

#[test]
fn every_packet_fits_and_together_they_give_the_encoders_picture() {
    let (with, without, source) = sets();
    for (set, previews) in [(with, 1), (without, 0)] {
        assert_eq!(set.previews, previews);
        assert!(set.total_bytes() <= 14 * SIZE);
        assert_eq!(set.packets.len(), 14);
        let mut area = 0;
        for (i, bytes) in set.packets.iter().enumerate() {
            assert!(bytes.len() <= SIZE, "packet {i}: {} bytes", bytes.len());
            let p = Packet::parse(bytes).unwrap();
            assert_eq!((p.index, p.count), (i as u16, 14));
            assert_eq!(p.kind == PacketKind::Preview, i < previews);
            if p.kind == PacketKind::Region {
                area += p.region.w * p.region.h;
            }
        }
        // The regions tile the image.
        assert_eq!(area, WIDTH * HEIGHT);
        let all = assemble(set.packets.iter().map(Vec::as_slice), u64::MAX).unwrap();
        assert_eq!(all.pixels, set.reconstruction);
        assert_eq!(all.coverage, 1.0);
        assert!(all.missing.is_empty());
        let psnr = common::psnr_u8(&all.pixels, source);
        assert!((psnr - set.psnr).abs() < 1e-9 && psnr > 25.0, "{psnr}");
    }
}

#[test]
fn an_overview_analysis_makes_the_preview_with_its_own_leaf_sizes() {
    let plane = common::synthetic(WIDTH, HEIGHT, 31, 6);
    let source = plane.data.clone();
    let overview = common::analyse_with(plane, &overview_config(&config()));
    let options = PacketOptions {
        size: SIZE,
        image_id: Some(3),
        ..PacketOptions::default()
    };
    let set = packetise(&overview, &config(), Target::Bytes(14 * SIZE), &options).unwrap();
    assert_eq!((set.packets.len(), set.previews), (14, 1));
    for bytes in &set.packets {
        assert!(bytes.len() <= SIZE);
        let p = Packet::parse(bytes).unwrap();
        // Each packet carries its own stream's coding fields: the preview's leaves start at
        // the overview's 8 px, the regions' at the configuration's 4 px.
        let smallest = match p.kind {
            PacketKind::Preview => host_encoder::LOW_RATE_MIN_LEAF_LOG2,
            PacketKind::Region => config().min_leaf_log2,
        };
        assert_eq!(
            p.stream_header().min_leaf_log2,
            smallest,
            "packet {}",
            p.index
        );
    }
    let all = assemble(set.packets.iter().map(Vec::as_slice), u64::MAX).unwrap();
    assert_eq!(all.pixels, set.reconstruction);
    // The regions are as good as those cut from a full analysis (the same budget and packets).
    let (full, _, _) = sets();
    let error = |pixels: &[u8]| common::sse(pixels, &source);
    assert!(
        error(&set.reconstruction) <= 1.05 * error(&full.reconstruction),
        "{} against {}",
        error(&set.reconstruction),
        error(&full.reconstruction)
    );
}

#[test]
fn progress_counts_every_region_and_its_pixels() {
    let plane = common::synthetic(WIDTH, HEIGHT, 31, 6);
    let analysis = common::analyse_with(plane, &config());
    let options = PacketOptions {
        size: SIZE,
        image_id: Some(1),
        ..PacketOptions::default()
    };
    let reports = std::sync::Mutex::new(Vec::new());
    let set = packetise_with_progress(
        &analysis,
        &config(),
        Target::Bytes(14 * SIZE),
        &options,
        &|done| reports.lock().unwrap().push(done),
    )
    .unwrap();
    let mut reports = reports.into_inner().unwrap();
    reports.sort_by_key(|r| r.done);
    // One report before the regions and one per region, every count once; the shares grow
    // with the counts (they are made under one lock) and end with the whole image.
    let regions = set.packets.len() - set.previews;
    assert!(regions > 1);
    assert_eq!(reports.len(), regions + 1);
    for (i, r) in reports.iter().enumerate() {
        assert_eq!((r.done, r.regions), (i, regions));
    }
    assert!(reports.windows(2).all(|w| w[0].share < w[1].share));
    assert_eq!(reports[0].share, 0.0);
    assert!((reports[regions].share - 1.0).abs() < 1e-12);
    // The same packets as without progress.
    assert_eq!(set.packets, sets().0.packets);
}

#[test]
fn a_lost_region_without_preview_is_filled_from_its_neighbours() {
    let (_, without, source) = sets();
    let lost = 5;
    let kept = without
        .packets
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != lost)
        .map(|(_, p)| p.as_slice());
    let image = assemble(kept, u64::MAX).unwrap();
    assert_eq!(image.missing, vec![lost as u16]);
    let region = Packet::parse(&without.packets[lost]).unwrap().region;
    let filled = crop(&image.pixels, WIDTH, region);
    let original = crop(source, WIDTH, region);
    let psnr = common::psnr_u8(&filled, &original);
    // Smooth content: interpolation is close, and nothing is left black or grey.
    assert!(psnr > 18.0, "{psnr} dB in the lost region");
}

/// What the receiver may be handed.
#[derive(Debug, Clone)]
enum Arrival {
    /// Packet `i` of the set with the preview.
    Packet(usize),
    /// Packet `i` of the other image (no preview, another id).
    Foreign(usize),
    /// Packet `i` with byte `at` (mod its length) flipped by `mask`.
    Damaged(usize, usize, u8),
    /// Packet `i` cut to `n` bytes (mod its length).
    Cut(usize, usize),
}

fn arrival() -> impl Strategy<Value = Arrival> {
    prop_oneof![
        6 => (0..14usize).prop_map(Arrival::Packet),
        1 => (0..14usize).prop_map(Arrival::Foreign),
        1 => (0..14usize, 0..64usize, 1..=255u8).prop_map(|(i, a, m)| Arrival::Damaged(i, a, m)),
        1 => (0..14usize, 0..64usize).prop_map(|(i, n)| Arrival::Cut(i, n)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any subset, in any order, with duplicates, foreign and damaged packets: every region
    /// received shows exactly what the full set shows there, the preview fills the rest when it
    /// came, and the receiver reports exactly which packets it is missing.
    #[test]
    fn any_arrivals_give_the_regions_received(arrivals in proptest::collection::vec(arrival(), 0..30)) {
        let (with, without, _) = sets();
        let inputs: Vec<Vec<u8>> = arrivals
            .iter()
            .map(|a| match *a {
                Arrival::Packet(i) => with.packets[i].clone(),
                Arrival::Foreign(i) => without.packets[i].clone(),
                Arrival::Damaged(i, at, mask) => {
                    let mut p = with.packets[i].clone();
                    let at = at % p.len();
                    p[at] ^= mask;
                    p
                }
                Arrival::Cut(i, n) => {
                    let p = &with.packets[i];
                    p[..n % p.len()].to_vec()
                }
            })
            .collect();
        let result = assemble(inputs.iter().map(Vec::as_slice), u64::MAX);
        let mut ours: Vec<u16> = arrivals
            .iter()
            .filter_map(|a| match *a {
                Arrival::Packet(i) => Some(i as u16),
                _ => None,
            })
            .collect();
        ours.sort_unstable();
        ours.dedup();
        let foreign = arrivals.iter().filter(|a| matches!(a, Arrival::Foreign(_))).count();
        let Ok(image) = result else {
            // Only when nothing valid arrived.
            prop_assert!(ours.is_empty() && foreign == 0);
            return Ok(());
        };
        if image.image_id == 2 {
            // The other image had more packets here: ours were the foreign ones.
            prop_assert!(foreign >= ours.len());
            return Ok(());
        }
        prop_assert_eq!(&image.received, &ours);
        let missing: Vec<u16> = (0..14).filter(|i| !ours.contains(i)).collect();
        prop_assert_eq!(&image.missing, &missing);
        prop_assert_eq!(image.preview, ours.contains(&0));
        let full = &with.reconstruction;
        for &i in &ours {
            let p = Packet::parse(&with.packets[usize::from(i)]).unwrap();
            if p.kind == PacketKind::Region {
                prop_assert_eq!(crop(&image.pixels, WIDTH, p.region), crop(full, WIDTH, p.region));
            }
        }
        if image.preview {
            let preview = assemble([with.packets[0].as_slice()], u64::MAX).unwrap();
            for &i in &missing {
                let region = Packet::parse(&with.packets[usize::from(i)]).unwrap().region;
                prop_assert_eq!(
                    crop(&image.pixels, WIDTH, region),
                    crop(&preview.pixels, WIDTH, region)
                );
            }
        }
    }
}

#[test]
fn images_larger_than_the_limit_are_refused_before_anything_is_allocated() {
    let (with, _, _) = sets();
    let result = assemble(
        with.packets.iter().map(Vec::as_slice),
        u64::from(WIDTH * HEIGHT) - 1,
    );
    assert!(matches!(
        result,
        Err(host_encoder::packets::AssembleError::NoValidPacket(Some(
            decoder_core::DecodeError::TooLarge { .. }
        )))
    ));
}

#[test]
fn a_repeated_preview_is_sent_twice_and_counted_once() {
    let plane = common::synthetic(WIDTH, HEIGHT, 31, 6);
    let analysis = common::analyse_with(plane, &config());
    let options = PacketOptions {
        size: SIZE,
        image_id: Some(3),
        preview: true,
        repeat_preview: true,
        parity: 0,
    };
    let made = packetise(&analysis, &config(), Target::Bytes(14 * SIZE), &options).unwrap();
    assert_eq!(made.packets.len(), 14);
    assert_eq!(made.packets[6], made.packets[0]);
    let first = Packet::parse(&made.packets[0]).unwrap();
    assert_eq!((first.kind, first.count), (PacketKind::Preview, 13));
    // Without the first copy, the second one still gives the whole picture.
    let image = assemble(made.packets[1..].iter().map(Vec::as_slice), u64::MAX).unwrap();
    assert!(image.missing.is_empty() && image.preview);
    assert_eq!(image.pixels, made.reconstruction);
    let all = assemble(made.packets.iter().map(Vec::as_slice), u64::MAX).unwrap();
    assert_eq!(all.duplicates, 1);
}

/// Without an image id given, each packet set gets one made from its content: pictures sent
/// one after another differ, the same packets made again keep theirs, and every packet,
/// parity packets included, carries it and passes its checks.
#[test]
fn image_ids_come_from_the_packets_unless_given() {
    let made = |seed, image_id| {
        let plane = common::synthetic(WIDTH, HEIGHT, seed, 6);
        let analysis = common::analyse_with(plane, &config());
        let options = PacketOptions {
            size: SIZE,
            image_id,
            preview: true,
            repeat_preview: false,
            parity: 2,
        };
        packetise(&analysis, &config(), Target::Bytes(10 * SIZE), &options).unwrap()
    };
    let carried = |set: &Packetised| -> Vec<u16> {
        set.packets
            .iter()
            .map(|p| match ParityPacket::parse(p) {
                Ok(parity) => parity.image_id,
                Err(_) => Packet::parse(p).unwrap().image_id,
            })
            .collect()
    };
    let first = made(31, None);
    let second = made(32, None);
    assert_eq!(carried(&first), vec![first.image_id; first.packets.len()]);
    assert_eq!(
        carried(&second),
        vec![second.image_id; second.packets.len()]
    );
    assert_ne!(first.image_id, second.image_id);
    assert_eq!(made(31, None).image_id, first.image_id);
    let given = made(31, Some(9));
    assert_eq!(carried(&given), vec![9; given.packets.len()]);
    let image = assemble(first.packets.iter().map(Vec::as_slice), u64::MAX).unwrap();
    assert_eq!(image.image_id, first.image_id);
    assert_eq!(image.pixels, first.reconstruction);
}

/// The test image in packets of `size` bytes, `packets` of them in all, `parity` of them
/// parity packets.
fn with_parity(size: usize, packets: usize, parity: usize, preview: bool) -> Packetised {
    let plane = common::synthetic(WIDTH, HEIGHT, 31, 6);
    let analysis = common::analyse_with(plane, &config());
    let options = PacketOptions {
        size,
        image_id: Some(4),
        preview,
        repeat_preview: false,
        parity,
    };
    packetise(
        &analysis,
        &config(),
        Target::Bytes(packets * size),
        &options,
    )
    .unwrap()
}

#[test]
fn parity_packets_rebuild_any_lost_packets_up_to_their_number() {
    let made = with_parity(96, 12, 3, true);
    // Nine data packets of at most 95 bytes (a parity packet is at most one byte longer than
    // the longest), three parity packets of at most 96.
    assert_eq!((made.packets.len(), made.parity), (12, 3));
    let (data, parity) = made.packets.split_at(9);
    assert!(data.iter().all(|p| p.len() <= 95));
    let longest = data.iter().map(Vec::len).max().unwrap();
    assert!(parity.iter().all(|p| p.len() == longest + 1), "{longest}");
    assert!(made.total_bytes() <= 12 * 96);
    assert_eq!(Packet::parse(&made.packets[0]).unwrap().count, 9);
    let all = assemble(made.packets.iter().map(Vec::as_slice), u64::MAX).unwrap();
    assert_eq!(all.pixels, made.reconstruction);
    // Any three lost (data or parity): everything rebuilt, byte for byte.
    for lost in [[0, 1, 2], [3, 7, 8], [2, 9, 11], [9, 10, 11], [6, 8, 10]] {
        let kept = made
            .packets
            .iter()
            .enumerate()
            .filter(|(i, _)| !lost.contains(i))
            .map(|(_, p)| p.as_slice());
        let image = assemble(kept, u64::MAX).unwrap();
        assert!(image.missing.is_empty(), "{lost:?}: {:?}", image.missing);
        assert_eq!(image.pixels, made.reconstruction, "{lost:?}");
        let data_lost: Vec<u16> = lost.iter().filter(|&&i| i < 9).map(|&i| i as u16).collect();
        assert_eq!(image.recovered, data_lost);
    }
    // Four lost: nothing rebuilt, the data packets that came are drawn, and one more packet,
    // any of the four, completes the set.
    let kept = made.packets[4..].iter().map(Vec::as_slice);
    let image = assemble(kept, u64::MAX).unwrap();
    assert_eq!(image.missing, vec![0, 1, 2, 3]);
    assert!(image.recovered.is_empty());
    assert_eq!((image.parity, image.packets_short()), (3, 1));
    for one_more in 0..4 {
        let kept = made.packets[4..]
            .iter()
            .chain([&made.packets[one_more]])
            .map(Vec::as_slice);
        let image = assemble(kept, u64::MAX).unwrap();
        assert!(image.missing.is_empty(), "{one_more}");
        assert_eq!(image.pixels, made.reconstruction);
    }
}

/// decoder-core's rebuild, as a device runs it (one fixed buffer, no allocation), against the
/// parity packets the encoder makes with the `reed-solomon-erasure` crate: every way of losing
/// up to three of twelve packets gives back the lost data packets byte for byte, with the
/// packets added in the order sent (data first) or the reverse, and slots as long as the
/// shards or as the link's packets.
#[test]
fn a_fixed_buffer_rebuilds_every_loss_the_parity_covers_byte_for_byte() {
    let made = with_parity(96, 12, 3, true);
    let sent = &made.packets;
    let n = sent.len() - made.parity;
    let shard_len = ParityPacket::parse(&sent[n]).unwrap().shard.len();
    assert!(shard_len < 96);
    let mut buf = [0xA5u8; 12 * 96];
    let mut out = [0u8; 96];
    let mut checked = 0;
    for lost in 1u32..1 << sent.len() {
        if lost.count_ones() > 3 {
            continue;
        }
        let kept = |i: usize| lost >> i & 1 == 0;
        // Slots of the link's packet size, or of the shard's length; packets in the order
        // sent, or the reverse.
        let slot_len = if lost % 2 == 0 { 96 } else { shard_len };
        let mut order: Vec<usize> = (0..sent.len()).filter(|&i| kept(i)).collect();
        if lost % 3 == 0 {
            order.reverse();
        }
        buf.fill(0xA5);
        let mut code = Rebuild::new(slot_len, &mut buf);
        for &i in &order {
            match ParityPacket::parse(&sent[i]) {
                Ok(p) => code.add_parity(&p).unwrap(),
                Err(_) => code.add_packet(&sent[i]).unwrap(),
            }
            assert!(i >= n || code.has(i as u16));
        }
        let data_lost = (0..n).filter(|&i| !kept(i)).count();
        let parity_kept = (n..sent.len()).filter(|&i| kept(i)).count();
        assert_eq!(code.parity_held(), parity_kept);
        assert_eq!(code.packets_short(), data_lost.saturating_sub(parity_kept));
        if data_lost > parity_kept {
            assert_eq!(
                code.rebuild(),
                Err(RebuildError::NotEnough {
                    missing: data_lost,
                    parity: parity_kept
                })
            );
            continue;
        }
        code.rebuild().unwrap();
        assert_eq!(code.missing(), 0);
        for (i, packet) in sent[..n].iter().enumerate() {
            let len = code.packet(i as u16, &mut out).unwrap();
            assert_eq!(&out[..len], &packet[..], "packet {i}, lost {lost:b}");
        }
        checked += 1;
    }
    assert!(checked > 250, "{checked}");
    // Four lost data packets, three parity packets: not enough, and said so.
    let mut code = Rebuild::new(shard_len, &mut buf);
    for packet in &sent[4..n] {
        code.add_packet(packet).unwrap();
    }
    for packet in &sent[n..] {
        code.add_parity(&ParityPacket::parse(packet).unwrap())
            .unwrap();
    }
    assert_eq!(
        code.rebuild(),
        Err(RebuildError::NotEnough {
            missing: 4,
            parity: 3
        })
    );
    assert_eq!((code.parity_held(), code.packets_short()), (3, 1));
    assert_eq!(code.packet(0, &mut out), Err(RebuildError::NotHeld));
    // Another image's packet, and a buffer without a slot for the last parity packet.
    let mut other = sent[5].clone();
    other[1] ^= 1;
    let crc = decoder_core::internal::packet::packet_crc(&other[..other.len() - 2]);
    let at = other.len() - 2;
    other[at..].copy_from_slice(&crc);
    assert_eq!(code.add_packet(&other), Err(RebuildError::OtherImage));
    let last = ParityPacket::parse(&sent[n + 2]).unwrap();
    let small = Rebuild::buffer_len(n, 2, shard_len);
    let mut code = Rebuild::new(shard_len, &mut buf[..small]);
    assert_eq!(code.add_parity(&last), Err(RebuildError::NoSlot));
    // Slots shorter than the shards: no room.
    let mut code = Rebuild::new(shard_len - 1, &mut buf);
    assert_eq!(code.add_parity(&last), Err(RebuildError::NoSlot));
    // A data packet whose content is longer than the code's shards is of another code,
    // whether it comes before the parity packet or after it.
    let mut long = sent[5].clone();
    long.splice(long.len() - 2.., vec![7u8; shard_len]);
    let crc = decoder_core::internal::packet::packet_crc(&long);
    long.extend_from_slice(&crc);
    assert!(Packet::parse(&long).is_ok());
    let mut wide = vec![0u8; Rebuild::buffer_len(n, 3, 2 * 96)];
    let mut code = Rebuild::new(2 * 96, &mut wide);
    code.add_packet(&long).unwrap();
    assert_eq!(code.add_parity(&last), Err(RebuildError::OtherImage));
    let mut code = Rebuild::new(2 * 96, &mut wide);
    code.add_parity(&last).unwrap();
    assert_eq!(code.add_packet(&long), Err(RebuildError::OtherImage));
    // Before any packet the rebuild knows of no image: nothing missing, nothing held.
    let code = Rebuild::new(96, &mut buf);
    assert_eq!((code.missing(), code.has(0)), (0, false));
}

#[test]
fn parity_packets_past_128_keep_to_the_packet_size() {
    // 130 parity packets: the last two's index fields take two bytes, and the data packets
    // leave room for them (two bytes shorter than the packet size).
    let made = with_parity(SIZE, 150, 130, false);
    let n = made.packets.len() - made.parity;
    assert_eq!((n, made.parity), (20, 130));
    assert!(made.packets[..n].iter().all(|p| p.len() <= SIZE - 2));
    assert!(made.packets.iter().all(|p| p.len() <= SIZE));
    // Every data packet lost: the parity packets alone rebuild them all.
    let image = assemble(made.packets[n..].iter().map(Vec::as_slice), u64::MAX);
    // Without a data packet the image is unknown (its size and mode are in data packets
    // only), so nothing is drawn; with one, the rest is rebuilt.
    assert!(matches!(image, Err(AssembleError::NoValidPacket(None))));
    let one_data = made.packets[n - 1..].iter().map(Vec::as_slice);
    let image = assemble(one_data, u64::MAX).unwrap();
    assert!(image.missing.is_empty(), "{:?}", image.missing);
    assert_eq!(image.recovered, (0..n as u16 - 1).collect::<Vec<_>>());
    assert_eq!(image.pixels, made.reconstruction);
}

#[test]
fn parity_sized_for_a_link_grows_with_its_losses() {
    let plane = common::synthetic(WIDTH, HEIGHT, 31, 6);
    let analysis = common::analyse_with(plane, &config());
    let options = PacketOptions {
        size: SIZE,
        image_id: Some(5),
        preview: true,
        repeat_preview: false,
        parity: 0,
    };
    let target = Target::Bytes(40 * SIZE);
    let sized = |loss| parity_for_loss(&analysis, target, &options, loss).unwrap();
    // A link that loses nothing gets no parity packets, whose estimate is the full picture's.
    let lossless = sized(0.0);
    assert_eq!(lossless.parity, 0);
    let counts = [0.02, 0.1, 0.2].map(|loss| sized(loss).parity);
    assert!(counts.windows(2).all(|w| w[0] <= w[1]), "{counts:?}");
    assert!(counts[2] > 0, "{counts:?}");
    // More loss, a worse picture to expect.
    assert!(sized(0.2).expected_psnr < lossless.expected_psnr);
    // The count chosen is one packetise makes within the budget.
    let made = packetise(
        &analysis,
        &config(),
        target,
        &PacketOptions {
            parity: counts[2],
            ..options
        },
    )
    .unwrap();
    assert_eq!(made.parity, counts[2]);
    assert!(made.total_bytes() <= 40 * SIZE);
    for loss in [-0.1, 0.6, f64::NAN] {
        assert!(matches!(
            parity_for_loss(&analysis, target, &options, loss),
            Err(PacketError::BadLoss(_))
        ));
    }
}

/// A receiver drawing at a scale ([`assemble_at`], [`Packet::scale`]): smaller pictures are
/// the full one subsampled, exactly (regions start on multiples of 8 pixels), lost regions
/// and the preview included; larger ones hold the full picture at multiples of the scale
/// when the stream smooths no edges (a larger decode is not smoothed, `docs/bitstream.md`
/// section 6).
#[test]
fn packets_draw_at_every_scale_as_the_whole_picture_does() {
    let (with, _, _) = sets();
    let kept = || {
        (with.packets.iter().enumerate())
            .filter(|&(i, _)| i != 3 && i != 8)
            .map(|(_, p)| p.as_slice())
    };
    let full = assemble(kept(), u64::MAX).unwrap();
    assert_eq!(full.missing, vec![3, 8]);
    for scale in [Scale::Eighth, Scale::Quarter, Scale::Half] {
        let small = assemble_at(kept(), u64::MAX, scale).unwrap();
        let step = 1 << -scale.log2();
        assert_eq!(
            (small.width, small.height),
            (WIDTH.div_ceil(step), HEIGHT.div_ceil(step))
        );
        let subsampled: Vec<u8> = (0..small.height)
            .flat_map(|y| (0..small.width).map(move |x| (x * step, y * step)))
            .map(|(x, y)| full.pixels[(y * WIDTH + x) as usize])
            .collect();
        assert_eq!(small.pixels, subsampled, "{scale:?}");
        assert_eq!((&small.received, small.preview), (&full.received, true));
    }

    let plane = common::synthetic(WIDTH, HEIGHT, 31, 6);
    let unsmoothed = EncoderConfig {
        deblock: Some(0),
        ..config()
    };
    let analysis = common::analyse_with(plane, &unsmoothed);
    let options = PacketOptions {
        size: SIZE,
        image_id: Some(3),
        preview: true,
        repeat_preview: false,
        parity: 0,
    };
    let set = packetise(&analysis, &unsmoothed, Target::Bytes(14 * SIZE), &options).unwrap();
    let full = assemble(set.packets.iter().map(Vec::as_slice), u64::MAX).unwrap();
    for scale in [Scale::Double, Scale::Quadruple] {
        let large = assemble_at(set.packets.iter().map(Vec::as_slice), u64::MAX, scale).unwrap();
        let step = 1 << scale.log2();
        assert_eq!((large.width, large.height), (WIDTH * step, HEIGHT * step));
        let on_grid: Vec<u8> = (0..HEIGHT)
            .flat_map(|y| (0..WIDTH).map(move |x| (x * step, y * step)))
            .map(|(x, y)| large.pixels[(y * large.width + x) as usize])
            .collect();
        assert_eq!(on_grid, full.pixels, "{scale:?}");
    }
    // A picture too large at that scale is refused before anything is drawn.
    let pixels = u64::from(WIDTH * HEIGHT);
    assert!(assemble_at(kept(), pixels, Scale::One).is_ok());
    assert_eq!(
        assemble_at(kept(), pixels, Scale::Double).unwrap_err(),
        AssembleError::TooLarge {
            width: 2 * WIDTH,
            height: 2 * HEIGHT
        }
    );
}
