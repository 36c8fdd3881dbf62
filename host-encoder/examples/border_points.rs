//! What shared borders between leaves could save, and what they would cost a decoder: encodes
//! each image at each rate (as `pifs` does: one analysis per target, with the small leaves of
//! [`host_encoder::EncoderConfig::for_targets`]), walks the stream in decoding order and counts the
//! control values that sit exactly where an earlier leaf already has a control point (the
//! values a shared-border format would not code), how many of those are within half a
//! quantiser step (of the later leaf) of the earlier leaf's value there (those a shared border
//! would impose at no more than the quantiser's own error), and the largest number of such
//! points that are waiting for a later leaf at any one time (what a decoder would have to
//! remember).
//!
//! `cargo run --release -p host-encoder --example border_points -- [--bpp 0.1,0.5] IMAGE...`

mod common;

use decoder_core::internal::entropy::RangeDecoder;
use decoder_core::internal::model::MODELS;
use decoder_core::internal::prediction::Frontier;
use decoder_core::internal::syntax::control::CONTROL_STEPS;
use decoder_core::internal::syntax::{control_step, Header};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk, LeafInfo, TreeVisitor};
use decoder_core::DecodeError;
use decoder_core::SliceSource;
use host_encoder::{analyse, io, EncoderConfig, Target};
use std::collections::HashMap;

/// A control point: position, decoded value and the step of its leaf's quantiser.
#[derive(Clone, Copy)]
struct Point {
    at: (u32, u32),
    value: i32,
    step: i32,
}

/// The control points of every leaf, in decoding order.
#[derive(Default)]
struct ControlPoints {
    leaves: Vec<Vec<Point>>,
}

impl TreeVisitor for ControlPoints {
    type Error = DecodeError;
    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        frontier.record(&info.node, control_step(info.cquant), patch, &mut Discard);
        let intervals = u32::from(MODELS[usize::from(info.model)].intervals);
        let spacing = (1u32 << info.node.log2) / intervals;
        let step = CONTROL_STEPS[usize::from(info.cquant)];
        let points = (0..=intervals)
            .flat_map(|i| (0..=intervals).map(move |j| (j, i)))
            .map(|(j, i)| Point {
                at: (info.node.x + j * spacing, info.node.y + i * spacing),
                value: i32::from(patch.control[(i * (intervals + 1) + j) as usize]),
                step,
            })
            .collect();
        self.leaves.push(points);
        Ok(())
    }
}

/// What [`count`] finds.
struct Counts {
    /// Control values coded.
    values: usize,
    /// Those at an earlier leaf's control point.
    met: usize,
    /// Those of `met` within half a step of the earlier leaf's value there.
    close: usize,
    /// The most such points waiting at once.
    most_waiting: i64,
}

/// Control values, those at an earlier leaf's control point (and how many of those are close
/// to the value the earlier leaf has there), and the most such points waiting at once (from
/// the leaf that makes a point to the last leaf that meets it again).
fn count(points: &ControlPoints) -> Counts {
    // Where each point was first made: the leaf, and its value there.
    let mut made: HashMap<(u32, u32), (usize, i32)> = HashMap::new();
    let mut last_met: HashMap<(u32, u32), usize> = HashMap::new();
    let (mut values, mut met, mut close) = (0, 0, 0);
    for (t, leaf) in points.leaves.iter().enumerate() {
        for p in leaf {
            values += 1;
            if let Some(&(_, earlier)) = made.get(&p.at) {
                met += 1;
                close += usize::from(2 * (p.value - earlier).abs() <= p.step);
                last_met.insert(p.at, t);
            }
        }
        for p in leaf {
            made.entry(p.at).or_insert((t, p.value));
        }
    }
    let mut change = vec![0i64; points.leaves.len() + 1];
    for (p, &last) in &last_met {
        change[made[p].0] += 1;
        change[last] -= 1;
    }
    let (mut waiting, mut most) = (0i64, 0i64);
    for c in change {
        waiting += c;
        most = most.max(waiting);
    }
    Counts {
        values,
        met,
        close,
        most_waiting: most,
    }
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let rates = common::take_rates(&mut args, &[0.1, 0.5]);
    println!(
        "image,target_bpp,leaves,control_values,at_earlier_points,share_pct,within_half_step_pct,most_waiting"
    );
    for path in &args {
        let plane = io::load_luma(path.as_ref()).expect("readable image");
        let pixels = plane.data.len();
        for &bpp in &rates {
            let target = Target::Bpp(bpp);
            let config = EncoderConfig::for_targets(&[target], pixels);
            let analysis = analyse(plane.clone(), &config, &|_| {}).expect("analysable image");
            let encoded = analysis.encode(target).expect("reachable rate");
            let (header, at) = Header::parse(&encoded.bytes).expect("own stream");
            let payload = &encoded.bytes[at..at + header.payload_len as usize];
            let mut decoder = RangeDecoder::new(SliceSource::new(payload)).expect("own stream");
            let mut points = ControlPoints::default();
            walk::<_, _, { 1 << 16 }>(&header, &mut decoder, &mut points).expect("own stream");
            let c = count(&points);
            let name = std::path::Path::new(path)
                .file_name()
                .map_or(path.clone(), |n| n.to_string_lossy().into_owned());
            println!(
                "{name},{bpp},{},{},{},{:.1},{:.1},{}",
                points.leaves.len(),
                c.values,
                c.met,
                100.0 * c.met as f64 / c.values as f64,
                100.0 * c.close as f64 / c.met.max(1) as f64,
                c.most_waiting
            );
        }
    }
}
