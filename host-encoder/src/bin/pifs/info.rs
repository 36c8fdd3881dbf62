//! `pifs info`: what a stream holds, from its entropy-decoded syntax (no pixels are drawn for
//! the statistics); with `--svg`, its quadtree drawn over the decoded image.

use crate::error::{CliError, Result};
use crate::output::{self, Kind};
use decoder_core::internal::model::{MODELS, MODEL_COUNT};
use decoder_core::internal::syntax::control::{CONTROL_QUANTISERS, CONTROL_STEPS};
use decoder_core::internal::syntax::ControlCoding;
use decoder_core::{Header, LeafInfo, Limits};
use host_encoder::io::{Content, Output};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The models' names, by model index.
pub const MODEL_NAMES: [&str; MODEL_COUNT] = ["2x2 bilinear", "3x3/2x2", "5x5/2x2", "9x9/4x4"];

/// What the leaves of a stream use.
#[derive(Debug, Default)]
struct Stats {
    /// Leaves per side (as a power of two).
    per_depth: BTreeMap<u8, usize>,
    /// Leaves per model.
    models: [usize; MODEL_COUNT],
    /// Leaves per model coded with DPCM, then with the grid transform.
    codings: [[usize; MODEL_COUNT]; 2],
    /// Leaves per control quantiser.
    cquant: [usize; CONTROL_QUANTISERS],
    /// Leaves per model whose control points are one pixel apart.
    pixel_grids: [usize; MODEL_COUNT],
}

impl Stats {
    fn leaf(&mut self, info: &LeafInfo) {
        let model = usize::from(info.model);
        *self.per_depth.entry(info.node.log2).or_default() += 1;
        self.models[model] += 1;
        if !MODELS[model].subdivides(info.node.log2) {
            self.pixel_grids[model] += 1;
        }
        let coding = usize::from(info.coding == ControlCoding::Transform);
        self.codings[coding][model] += 1;
        self.cquant[usize::from(info.cquant)] += 1;
    }

    fn print(&self, input: &Path, header: &Header, stream_len: usize) {
        let px = header.pixel_count() as f64;
        say!("{}", input.display());
        say!(
            "  format version   {}",
            decoder_core::internal::format::VERSION
        );
        say!(
            "  dimensions       {}x{}, {} channel(s), {} bits",
            header.width,
            header.height,
            header.channels,
            header.bit_depth
        );
        say!(
            "  colour           {}",
            if header.channels == 3 {
                "colour (YCbCr BT.601 full range, chroma 4:2:0)"
            } else {
                "grayscale"
            }
        );
        if let Some(range) = header.range {
            say!(
                "  values           {}..{} (a grey level {:.4}, decoded in 1/16 of that)",
                range.low,
                range.high(),
                f64::from(range.step) / f64::from(decoder_core::SampleRange::STEP_ONE)
            );
        }
        say!(
            "  size             {stream_len} bytes ({} header), {:.4} bpp",
            header.encoded_len(),
            stream_len as f64 * 8.0 / px
        );
        say!(
            "  leaf sizes       {}..{} px",
            1 << header.min_leaf_log2,
            1 << header.max_leaf_log2
        );
        let stripe = header.stripe_width();
        let capacity = decoder_core::internal::format::DEFAULT_STRIPE as u32;
        println!(
            "  coding           stripes of {stripe} px{}, edge smoothing {}",
            if stripe > capacity {
                format!(
                    " (a decoder needs {stripe} columns; decoder-core's default holds {capacity})"
                )
            } else {
                String::new()
            },
            match header.deblock {
                0 => "off".to_string(),
                d => format!(
                    "{d} (steps up to {} control steps, tapering off to {})",
                    f64::from(d) / 2.0,
                    f64::from(d) * 2.0
                ),
            }
        );
        let total: usize = self.per_depth.values().sum();
        say!("  leaves           {total}");
        for (log2, n) in self.per_depth.iter().rev() {
            say!("    {:>3}x{:<3}       {n}", 1 << log2, 1 << log2);
        }
        say!("  models           leaves (DPCM + transform) [pixel grids among them]");
        for (i, (name, n)) in MODEL_NAMES.iter().zip(self.models).enumerate() {
            let (dpcm, transform) = (self.codings[0][i], self.codings[1][i]);
            let pixel_grids = self.pixel_grids[i];
            say!("    {name:<14} {n} ({dpcm} + {transform}) [{pixel_grids}]");
        }
        say!(
            "  control quantiser use (steps {CONTROL_STEPS:?} /16 grey): {:?}",
            self.cquant
        );
    }

    /// The same description as [`Stats::print`], as one JSON object.
    fn json(&self, input: &Path, header: &Header, stream_len: usize) -> serde_json::Value {
        let px = header.pixel_count() as f64;
        let models: Vec<serde_json::Value> = MODEL_NAMES
            .iter()
            .enumerate()
            .map(|(i, name)| {
                serde_json::json!({
                    "name": name,
                    "leaves": self.models[i],
                    "dpcm": self.codings[0][i],
                    "transform": self.codings[1][i],
                    "pixel_grids": self.pixel_grids[i],
                })
            })
            .collect();
        let by_side: serde_json::Map<String, serde_json::Value> = self
            .per_depth
            .iter()
            .map(|(log2, n)| ((1u32 << log2).to_string(), (*n).into()))
            .collect();
        serde_json::json!({
            "path": input.display().to_string(),
            "kind": "stream",
            "format_version": decoder_core::internal::format::VERSION,
            "width": header.width,
            "height": header.height,
            "channels": header.channels,
            "bit_depth": header.bit_depth,
            "range": header.range.map(|r| serde_json::json!({
                "low": r.low,
                "high": r.high(),
                "step": f64::from(r.step) / f64::from(decoder_core::SampleRange::STEP_ONE),
            })),
            "bytes": stream_len,
            "header_bytes": header.encoded_len(),
            "bpp": stream_len as f64 * 8.0 / px,
            "leaf_sizes": [1u32 << header.min_leaf_log2, 1u32 << header.max_leaf_log2],
            "stripe_width": header.stripe_width(),
            "edge_smoothing": header.deblock,
            "leaves": self.per_depth.values().sum::<usize>(),
            "leaves_by_side": by_side,
            "models": models,
            "control_steps_grey": CONTROL_STEPS.map(|s| f64::from(s) / 16.0),
            "control_quantiser_use": self.cquant,
        })
    }

    /// Prints the description: as text, or as one JSON object (`json`).
    fn report(&self, input: &Path, header: &Header, stream_len: usize, json: bool) {
        match json {
            true => println!("{}", self.json(input, header, stream_len)),
            false => self.print(input, header, stream_len),
        }
    }
}

/// `pifs info` of a stream or of packets (several inputs: their packets merged); with `svg`,
/// also the drawing of a stream's leaves over the decoded image; with `json`, the description
/// as one JSON object. The stream's header is checked against `limits` before
/// anything else; only with `svg` are pixels made: the figures need nothing but the
/// entropy-decoded syntax.
pub fn run(
    inputs: &[PathBuf],
    svg: Option<&Path>,
    limits: &Limits,
    json: bool,
    packets: bool,
) -> Result<()> {
    if json {
        // Standard output carries the object: any status line goes to standard error.
        crate::say::stdout_is_data();
    }
    let [input] = inputs else {
        if svg.is_some() {
            return Err(CliError::Refused("--svg draws one stream".into()));
        }
        return crate::packets::info(inputs, limits.max_pixels, json);
    };
    if (packets || crate::packets::is_packet_input(input)) && svg.is_none() {
        return crate::packets::info(inputs, limits.max_pixels, json);
    }
    if let Some(svg) = svg {
        output::check(svg, Some(input), Kind::Svg)?;
    }
    let stream = crate::decode::open_stream(input, limits)?;
    let name = stream.name().to_path_buf();
    let len = stream.len() as usize;
    let mut stats = Stats::default();
    let Some(svg) = svg else {
        let header = stream.verify(|leaf: &LeafInfo| stats.leaf(leaf))?;
        stats.report(&name, &header, len, json);
        return Ok(());
    };
    let out = Output::create(svg, Content::Text)?;
    let mut leaves = Vec::new();
    let (header, mut pixels) = crate::decode::decode_pixels(&stream, Some(&mut leaves))?;
    if header.channels == 3 {
        // The drawing shows the luma under the leaves.
        pixels = pixels
            .chunks_exact(3)
            .map(|p| decoder_core::internal::colour::rgb_to_luma(p[0], p[1], p[2]))
            .collect();
    }
    leaves.iter().for_each(|leaf| stats.leaf(leaf));
    let drawing = crate::leaves_svg::draw(&header, &pixels, &leaves)?;
    let mut out = out;
    out.write_all(drawing.as_bytes())
        .map_err(|e| out.error(e))?;
    out.commit()?;
    stats.report(&name, &header, len, json);
    if !json {
        say!("  leaves drawn in  {}", svg.display());
    }
    Ok(())
}
