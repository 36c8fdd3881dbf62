//! The quadtree of a stream drawn over its decoded image, leaves outlined in a colour per
//! model, as the thesis's figures show it: a hand-written SVG with the image embedded as a
//! PNG.

use crate::error::Result;
use crate::info::MODEL_NAMES;
use decoder_core::internal::model::MODEL_COUNT;
use decoder_core::{Header, LeafInfo};
use host_encoder::io::OutputFormat;
use std::fmt::Write;
use std::path::Path;

/// Outline colour per model: saturated hues that stand out on grey.
pub const MODEL_COLOURS: [&str; MODEL_COUNT] = ["#ff3030", "#ffd700", "#30d030", "#ff40ff"];

/// Images are drawn at least this large (the larger side, screen pixels), magnified by a
/// whole factor, so that the outlines of small leaves stay apart.
const MIN_DRAWN_SIDE: u32 = 512;

/// Height of a legend row, screen pixels.
const LEGEND_ROW: u32 = 18;

/// The SVG document: the image (`pixels`, as decoded from a stream with `header`), each leaf's
/// square (clipped to the image) outlined in its model's colour, and a legend with the count
/// of leaves per model.
pub fn draw(header: &Header, pixels: &[u8], leaves: &[LeafInfo]) -> Result<String> {
    let (w, h) = (u32::from(header.width), u32::from(header.height));
    let png = OutputFormat::Png.encode(Path::new("the embedded image"), w, h, 1, pixels)?;
    let scale = MIN_DRAWN_SIDE.div_ceil(w.max(h)).clamp(1, 32);
    let (dw, dh) = (w * scale, h * scale);
    let legend_top = dh + 8;
    let width = dw.max(260);
    let height = legend_top + LEGEND_ROW * MODEL_COUNT as u32 + 8;
    let mut svg = String::new();
    // Writing into a String cannot fail.
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" width="{width}" height="{height}" viewBox="0 0 {width} {height}">"#
    );
    let _ = writeln!(
        svg,
        "<title>PIFS quadtree: {} leaves on {w}x{h} pixels</title>",
        leaves.len()
    );
    let _ = writeln!(
        svg,
        r#"<rect width="{width}" height="{height}" fill="white"/>"#
    );
    let _ = writeln!(
        svg,
        r#"<image x="0" y="0" width="{dw}" height="{dh}" style="image-rendering:pixelated" preserveAspectRatio="none" xlink:href="data:image/png;base64,{}"/>"#,
        base64(&png)
    );
    let _ = writeln!(svg, r#"<g fill="none" stroke-width="1">"#);
    let mut counts = [0usize; MODEL_COUNT];
    for leaf in leaves {
        let model = usize::from(leaf.model).min(MODEL_COUNT - 1);
        counts[model] += 1;
        let r = leaf.node.rect();
        let (x0, y0) = (r.x.min(w), r.y.min(h));
        let (x1, y1) = ((r.x + r.w).min(w), (r.y + r.h).min(h));
        // Inset by half a stroke: neighbours' outlines lie side by side.
        let _ = writeln!(
            svg,
            r#"<rect class="leaf" data-model="{model}" x="{}.5" y="{}.5" width="{}" height="{}" stroke="{}"/>"#,
            x0 * scale,
            y0 * scale,
            ((x1 - x0) * scale).saturating_sub(1),
            ((y1 - y0) * scale).saturating_sub(1),
            MODEL_COLOURS[model]
        );
    }
    let _ = writeln!(svg, "</g>");
    let _ = writeln!(
        svg,
        r#"<g font-family="sans-serif" font-size="12" fill="black">"#
    );
    for (i, (name, colour)) in MODEL_NAMES.iter().zip(MODEL_COLOURS).enumerate() {
        let y = legend_top + LEGEND_ROW * i as u32;
        let _ = writeln!(
            svg,
            r#"<rect x="8.5" y="{}.5" width="12" height="12" fill="none" stroke="{colour}" stroke-width="2"/><text x="28" y="{}">{name}: {} {}</text>"#,
            y + 2,
            y + 13,
            counts[i],
            if counts[i] == 1 { "leaf" } else { "leaves" }
        );
    }
    let _ = writeln!(svg, "</g>\n</svg>");
    Ok(svg)
}

/// Standard base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_vectors() {
        // RFC 4648, section 10.
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), coded, "{plain:?}");
        }
        assert_eq!(base64(&[0xFF, 0xFE, 0xFD]), "//79");
    }
}
