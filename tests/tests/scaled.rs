//! Scaled decoding (`Decoder::scale`): decodes at 1/8, 1/4, 1/2, 2 and 4 times the coded size
//! keep the sink contract, agree with the full decode where they must, and a half-size decode
//! looks like the full decode box-downscaled.

mod common;

use common::{decode_all, golden_dir, golden_list, psnr_u8, synthetic, CoverageSink};
use decoder_core::internal::syntax::control_step;
use decoder_core::{Decoder, LeafInfo, Rect, Scale, SliceSource};
use host_encoder::{EncoderConfig, Target};

/// Every golden stream, and a textured synthetic image encoded at two rates (busier leaves
/// than the golden vectors, which are small).
fn streams() -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = golden_list()
        .into_iter()
        .map(|g| {
            let data = std::fs::read(golden_dir().join(&g.file)).unwrap();
            (g.file, data)
        })
        .collect();
    let analysis = common::analyse_with(synthetic(96, 80, 7, 12), &EncoderConfig::default());
    for bpp in [0.3, 1.5] {
        let encoded = analysis.encode(Target::Bpp(bpp)).expect("encode");
        out.push((format!("synthetic@{bpp}"), encoded.bytes));
    }
    out
}

/// A decode at `scale` into a coverage sink of the scaled size, clipped to `clip`.
fn decode_scaled(data: &[u8], scale: Scale, clip: Rect) -> CoverageSink {
    let decoder = Decoder::new(data).unwrap().scale(scale);
    let (w, h) = decoder.output_size();
    let mut sink = CoverageSink::new(w, h);
    decoder.clip(clip).decode(&mut sink).unwrap();
    sink
}

#[test]
fn scaled_decodes_draw_every_pixel_once_in_legal_tiles() {
    for (name, data) in streams() {
        let header = decoder_core::Header::read(&data).unwrap();
        for scale in Scale::ALL {
            let sink = decode_scaled(&data, scale, Rect::EVERYTHING);
            assert_eq!(
                sink.width,
                scale.apply(header.width.into()),
                "{name} {scale:?}"
            );
            assert!(
                sink.violations.is_empty(),
                "{name} {scale:?}: {:?}",
                sink.violations
            );
            assert!(
                sink.not_once(1).is_empty(),
                "{name} {scale:?}: {:?}",
                sink.not_once(5)
            );
        }
    }
}

/// Which pixels of the full decode lie on a leaf's first or last row or column (where edge
/// smoothing may move them), and the most it may move one: a pixel is smoothed across at most
/// four leaf edges, each time by at most `round(D / 3)` with `32 |D| <= d s` (a larger step,
/// up to four times that, is moved less).
fn leaf_edges(data: &[u8]) -> (Vec<bool>, i32) {
    let header = decoder_core::Header::read(data).unwrap();
    let (w, h) = (u32::from(header.width), u32::from(header.height));
    let mut edge = vec![false; (w * h) as usize];
    let mut max_step = 0;
    Decoder::new(data)
        .unwrap()
        .observe(|leaf: &LeafInfo| {
            let node = leaf.node;
            max_step = max_step.max(control_step(leaf.cquant));
            let last = node.size() - 1;
            for y in node.y..(node.y + last + 1).min(h) {
                for x in node.x..(node.x + last + 1).min(w) {
                    if x == node.x || y == node.y || x == node.x + last || y == node.y + last {
                        edge[(y * w + x) as usize] = true;
                    }
                }
            }
        })
        .verify()
        .unwrap();
    let d = i32::from(header.deblock);
    let most = if d == 0 {
        0
    } else {
        4 * ((d * max_step / 32 + 1) / 3 + 1)
    };
    (edge, most)
}

/// Smaller decodes are the full decode's pixels on their grid, exactly. Larger ones hold the
/// full decode's pixels on theirs as tabulated, before edge smoothing: equal off the leaves'
/// edges, within what smoothing may move a pixel on them.
#[test]
fn smaller_decodes_are_the_full_decode_subsampled_and_larger_ones_contain_it() {
    for (name, data) in streams() {
        let (header, full) = decode_all(&data).unwrap();
        let (edge, most) = leaf_edges(&data);
        let width = usize::from(header.width);
        let ch = usize::from(header.channels);
        let mut moved = 0;
        for scale in Scale::ALL {
            let sink = decode_scaled(&data, scale, Rect::EVERYTHING);
            let k = scale.log2();
            let (w, h) = (sink.width as usize, sink.height as usize);
            for y in 0..h {
                for x in 0..w {
                    for c in 0..ch {
                        let got = sink.pixels[(y * w + x) * ch + c];
                        if k <= 0 {
                            let (fx, fy) = (x << -k, y << -k);
                            assert_eq!(
                                got,
                                full[(fy * width + fx) * ch + c],
                                "{name} {scale:?} ({x}, {y})"
                            );
                        } else if x % (1 << k) == 0 && y % (1 << k) == 0 {
                            let at = (y >> k) * width + (x >> k);
                            let diff = (i32::from(got) - i32::from(full[at * ch + c])).abs();
                            let allowed = if edge[at] { most } else { 0 };
                            assert!(
                                diff <= allowed,
                                "{name} {scale:?} ({x}, {y}): {got} against {}",
                                full[at * ch + c]
                            );
                            moved += usize::from(diff > 0);
                        }
                    }
                }
            }
        }
        println!("{name}: {moved} grid pixels of the larger decodes moved by edge smoothing");
    }
}

#[test]
fn clipped_and_streamed_scaled_decodes_agree_with_the_whole_one() {
    for (name, data) in streams() {
        for scale in [Scale::Quarter, Scale::Half, Scale::Double, Scale::Quadruple] {
            let whole = decode_scaled(&data, scale, Rect::EVERYTHING);
            let (w, h) = (whole.width, whole.height);
            let clip = Rect {
                x: w / 3,
                y: h / 5,
                w: w / 2 + 1,
                h: h / 2 + 1,
            };
            let cut = decode_scaled(&data, scale, clip);
            let ch = whole.channels;
            let inside = clip.intersect(&Rect::of_size(w, h));
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) as usize;
                    let pixel = Rect { x, y, w: 1, h: 1 };
                    let want = u32::from(inside.contains(&pixel));
                    assert_eq!(cut.counts[i], want, "{name} {scale:?} ({x}, {y})");
                    if want == 1 {
                        assert_eq!(
                            cut.pixels[i * ch..(i + 1) * ch],
                            whole.pixels[i * ch..(i + 1) * ch],
                            "{name} {scale:?}"
                        );
                    }
                }
            }
            let mut streamed = CoverageSink::new(w, h);
            Decoder::from_source(SliceSource::new(&data))
                .unwrap()
                .scale(scale)
                .decode(&mut streamed)
                .unwrap();
            assert_eq!(streamed.pixels, whole.pixels, "{name} {scale:?} streamed");
        }
    }
}

/// A decode at half size is close to the full decode downscaled by 2x2 box averaging (it is
/// the full decode's even pixels: equal where the image is smooth, aliased in fine texture).
#[test]
fn half_size_decode_is_close_to_the_box_downscaled_full_decode() {
    for (name, data) in streams() {
        let (header, full) = decode_all(&data).unwrap();
        let (fw, fh) = (usize::from(header.width), usize::from(header.height));
        let ch = usize::from(header.channels);
        if fw < 16 || fh < 16 {
            continue;
        }
        let (w, h) = (fw / 2, fh / 2);
        let mut boxed = Vec::with_capacity(w * h * ch);
        for y in 0..h {
            for x in 0..w {
                for c in 0..ch {
                    let at = |dx: usize, dy: usize| {
                        u32::from(full[((2 * y + dy) * fw + 2 * x + dx) * ch + c])
                    };
                    boxed.push(((at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1) + 2) / 4) as u8);
                }
            }
        }
        let half = decode_scaled(&data, Scale::Half, Rect::of_size(w as u32, h as u32));
        let stride = half.width as usize;
        let mut cut = Vec::with_capacity(w * h * ch);
        for y in 0..h {
            cut.extend_from_slice(&half.pixels[y * stride * ch..(y * stride + w) * ch]);
        }
        let psnr = psnr_u8(&cut, &boxed);
        println!("{name}: half-size decode against the box-downscaled full decode: {psnr:.2} dB");
        assert!(psnr > 26.0, "{name}: {psnr:.2} dB");
    }
}

#[test]
fn buffers_are_sized_by_the_scaled_image() {
    let data = std::fs::read(golden_dir().join(&golden_list()[0].file)).unwrap();
    let decoder = Decoder::new(&data).unwrap().scale(Scale::Double);
    let (w, h) = decoder.output_size();
    let mut small = vec![0u8; (w * h) as usize - 1];
    assert_eq!(
        decoder.clone().decode_into(&mut small),
        Err(decoder_core::DecodeError::BufferTooSmall)
    );
    let mut out = vec![0u8; (w * h) as usize];
    decoder.decode_into(&mut out).unwrap();
}

/// An enlarged decode closes each smoothed step on the later leaf's side by the whole
/// correction the full decode makes to it: where the full decode moves the pixel above a leaf
/// from `p` to `p'` and the leaf's own pixel to `q'`, the enlarged decode draws `p` as
/// tabulated above the edge and `q' - (p' - p)` below it, on the coded grid (checked where
/// neither pixel is in its leaf's first or last column, which other edges move too).
#[test]
fn enlarged_decodes_close_each_smoothed_step_on_the_later_leafs_side() {
    let mut checked = 0;
    for (name, data) in streams() {
        let header = decoder_core::Header::read(&data).unwrap();
        if header.channels != 1 || header.deblock == 0 || header.bit_depth != 8 {
            continue;
        }
        let (_, full) = decode_all(&data).unwrap();
        let (w, h) = (usize::from(header.width), usize::from(header.height));
        let mut leaves = Vec::new();
        Decoder::new(&data)
            .unwrap()
            .observe(|leaf: &LeafInfo| leaves.push(leaf.node))
            .verify()
            .unwrap();
        // Pixels in their leaf's first or last column.
        let mut side = vec![false; w * h];
        for n in &leaves {
            let (x, s) = (n.x as usize, n.size() as usize);
            for y in n.y as usize..(n.y as usize + s).min(h) {
                for col in [x, x + s - 1].into_iter().filter(|&c| c < w) {
                    side[y * w + col] = true;
                }
            }
        }
        for scale in [Scale::Double, Scale::Quadruple] {
            let k = scale.log2() as usize;
            let sink = decode_scaled(&data, scale, Rect::EVERYTHING);
            let sw = sink.width as usize;
            let grid = |x: usize, y: usize| i32::from(sink.pixels[(y << k) * sw + (x << k)]);
            for n in leaves.iter().filter(|n| n.y > 0 && (n.y as usize) < h) {
                let (x0, y) = (n.x as usize, n.y as usize);
                for x in x0..(x0 + n.size() as usize).min(w) {
                    let (p, q) = ((y - 1) * w + x, y * w + x);
                    if side[p] || side[q] {
                        continue;
                    }
                    let moved = i32::from(full[p]) - grid(x, y - 1);
                    let want = i32::from(full[q]) - moved;
                    // Past the clamps (a pixel at 0 or 255, a correction past an i8): skipped.
                    if !(0..=255).contains(&want) || 2 * moved.abs() > 127 {
                        continue;
                    }
                    assert_eq!(grid(x, y), want, "{name} {scale:?} ({x}, {y})");
                    checked += usize::from(moved != 0);
                }
            }
        }
    }
    println!("{checked} smoothed steps checked");
    assert!(checked > 100, "{checked} smoothed steps checked");
}
