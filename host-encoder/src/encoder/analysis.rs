//! Exhaustive analysis (thesis Alg. 1): every model that a block can support is fitted at every
//! quadtree node down to the smallest leaf, then quantised with every quantiser, and each
//! candidate's distortion is measured through decoder-core's own reconstruction (closed loop).

use super::fit::{fit_default, fit_weighted, Fit};
use super::quantise::{
    lloyd_max, quantise, weight_classes, ControlTargets, Quantised, ROUNDING_LAMBDA,
    ROUNDING_VARIANTS,
};
use super::rate::{Anchor, RateTable};
use super::{EncoderConfig, Plane};
use decoder_core::internal::format::{MAX_LEAF_LOG2, MIN_LEAF_LOG2};
use decoder_core::internal::model::SAMPLE_ONE;
use decoder_core::internal::model::{WeightClass, MODELS};
use decoder_core::internal::prediction::{inside_tile, SamplePrediction};
use decoder_core::internal::syntax::control::WeightQuantiser;
use decoder_core::internal::syntax::control::{
    CONTROL_QUANTISERS, WEIGHT_QUANTISERS, WEIGHT_QUANTISER_KINDS,
};
use decoder_core::internal::syntax::LeafSyntax;
use decoder_core::internal::syntax::{models_for_block, Codebook, Header};
use decoder_core::internal::syntax::{Contexts, ControlCoding};
use decoder_core::Node;
use decoder_core::{PixelSink, Rect, Tile};
use rayon::prelude::*;
use std::convert::Infallible;

/// One way of coding a node as a leaf.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Index into the node's fits.
    pub fit: u8,
    /// Control quantiser.
    pub cq: u8,
    /// Weight quantiser.
    pub wq: u8,
    /// Control coding.
    pub coding: ControlCoding,
    /// Squared error over the node's in-image pixels.
    pub sse: f64,
    /// Where its quantised control indices, then weight indices (when `wq` is not the
    /// default), start in [`NodeAnalysis::indices`]: kept, as every rate table and the writer
    /// need them again.
    pub at: u32,
}

/// Everything the analysis knows about one node.
#[derive(Debug, Clone)]
pub struct NodeAnalysis {
    /// The node.
    pub node: Node,
    /// One fit per model the node supports.
    pub fits: Vec<Fit>,
    /// Every (fit, quantiser) pair with its distortion.
    pub candidates: Vec<Candidate>,
    /// The candidates' indices, one after the other (one allocation per node).
    pub indices: Vec<i16>,
}

impl NodeAnalysis {
    /// The leaf syntax of candidate `c`.
    pub fn leaf(&self, c: &Candidate) -> LeafSyntax {
        let model = self.fits[usize::from(c.fit)].model;
        let m = MODELS[usize::from(model)];
        let (nc, nw) = (m.control_count(), m.weight_count());
        let mut leaf = LeafSyntax {
            model,
            cquant: c.cq,
            wquant: c.wq,
            coding: c.coding,
            ..LeafSyntax::default()
        };
        let at = c.at as usize;
        leaf.control[..nc].copy_from_slice(&self.indices[at..at + nc]);
        if WEIGHT_QUANTISER_KINDS[usize::from(c.wq)] != WeightQuantiser::Default {
            leaf.weights[..nw].copy_from_slice(&self.indices[at + nc..at + nc + nw]);
        }
        leaf
    }
}

/// The nodes of one quadtree level.
#[derive(Debug, Clone)]
pub struct Level {
    /// Node side, as a power of two.
    pub log2: u8,
    /// Nodes per row.
    pub cols: u32,
    /// Analysed nodes, row-major; `None` outside the image.
    pub nodes: Vec<Option<NodeAnalysis>>,
}

impl Level {
    /// The node at `(x, y)` (its top-left pixel), if analysed.
    pub fn get(&self, x: u32, y: u32) -> Option<&NodeAnalysis> {
        let i = (y >> self.log2) * self.cols + (x >> self.log2);
        self.nodes.get(i as usize).and_then(Option::as_ref)
    }
}

/// The result of the exhaustive analysis of one image: serves any number of targets.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// The image.
    pub plane: Plane,
    /// Header of the streams written from this analysis (with the Lloyd-Max codebooks).
    pub header: Header,
    /// Levels from the smallest leaf (index 0) to the root.
    pub levels: Vec<Level>,
    /// Rates of the kept candidates under the contexts of a trial encode (about 0.2 bpp): the
    /// first pass of every target starts from them.
    pub rates: RateTable,
    /// The trial encode's plan (its multiplier and estimates): where the searches of targets
    /// start.
    pub trial: Anchor,
}

impl Analysis {
    /// The level of nodes of side `2^log2`.
    pub fn level(&self, log2: u8) -> Option<&Level> {
        self.levels
            .get(usize::from(log2.checked_sub(self.header.min_leaf_log2)?))
    }

    /// Analyses `plane`. `progress` is called with the number of nodes analysed so far.
    pub fn run(plane: Plane, config: &EncoderConfig, progress: &(dyn Fn(u64) + Sync)) -> Analysis {
        // Leaf sizes the format allows.
        let min_leaf_log2 = config.min_leaf_log2.clamp(MIN_LEAF_LOG2, MAX_LEAF_LOG2);
        let mut header = Header {
            width: plane.width as u16,
            height: plane.height as u16,
            channels: 1,
            bit_depth: 8,
            min_leaf_log2,
            max_leaf_log2: config.max_leaf_log2.clamp(min_leaf_log2, MAX_LEAF_LOG2),
            codebooks: [Codebook::EMPTY; 2],
            // Set by the writer.
            payload_len: 0,
            checksum: 0,
        };
        let root = header.root_log2();
        let t_fit = std::time::Instant::now();
        super::fit::prepare_projections(header.min_leaf_log2..=header.max_leaf_log2.min(root));
        let done = std::sync::atomic::AtomicU64::new(0);
        let mut levels = Vec::new();
        for log2 in header.min_leaf_log2..=root {
            let cols = (plane.width + (1 << log2) - 1) >> log2;
            let rows = (plane.height + (1 << log2) - 1) >> log2;
            let analyse = log2 <= header.max_leaf_log2;
            let nodes: Vec<Option<NodeAnalysis>> = (0..cols * rows)
                .into_par_iter()
                .map(|i| {
                    let node = Node {
                        x: (i % cols) << log2,
                        y: (i / cols) << log2,
                        log2,
                    };
                    if !analyse {
                        return None;
                    }
                    let (models, count) = models_for_block(log2);
                    // Per model: the default-weight fit, and the joint fit with weights where
                    // there is one (its control values suit its weights, not the default ones,
                    // so both are kept).
                    let mut fits = Vec::with_capacity(2 * count);
                    for &m in &models[..count] {
                        if !config.fit_weights && !searched_with_default_weights(m) {
                            continue;
                        }
                        let plain = fit_default(&plane, &node, m);
                        let weighted = if config.fit_weights {
                            fit_weighted(&plane, &node, &plain)
                        } else {
                            None
                        };
                        fits.push(plain);
                        fits.extend(weighted);
                    }
                    let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    progress(n + 1);
                    Some(NodeAnalysis {
                        node,
                        fits,
                        candidates: Vec::new(),
                        indices: Vec::new(),
                    })
                })
                .collect();
            levels.push(Level { log2, cols, nodes });
        }
        if std::env::var_os("PIFS_TIMING").is_some() {
            eprintln!("fits: {:.2} s", t_fit.elapsed().as_secs_f64());
        }
        header.codebooks = design_codebooks(&levels, config.codebook_levels);
        let mut analysis = Analysis {
            plane,
            header,
            levels,
            rates: RateTable::empty(),
            trial: Anchor {
                lambda: 1.0,
                bits: 1.0,
                sse: 1.0,
            },
        };
        let timing = std::env::var_os("PIFS_TIMING").is_some();
        let t = std::time::Instant::now();
        analysis.measure_candidates();
        if timing {
            eprintln!("closed-loop candidates: {:.2} s", t.elapsed().as_secs_f64());
        }
        let t = std::time::Instant::now();
        analysis.prune_candidates(config.trial_bpp);
        if timing {
            eprintln!("candidate pruning: {:.2} s", t.elapsed().as_secs_f64());
        }
        analysis
    }

    /// Keeps, at every node, only the candidates that are its best leaf for some multiplier of
    /// interest, under rates measured from a trial encode's adapted contexts. Every later
    /// encode then weighs a handful of candidates per node instead of all of them.
    fn prune_candidates(&mut self, trial_bpp: f64) {
        let pixels = self.header.pixel_count() as f64;
        let first = RateTable::new(self, &Contexts::default());
        // The trained contexts change the rates only a little: what is far from the hull under
        // the first rates does not reach it under the trained ones, and need not be rated again.
        let near = first.lambda_optimal(self, 1e-2..=1e6, HULL_LAYERS);
        let first = first.select(&near);
        self.retain_candidates(&near);
        // A rough plan only gathers coding statistics.
        let plan = first.rough_plan_for_bits(self, &self.header, trial_bpp * pixels);
        self.trial = plan.anchor();
        let snapshot = match super::writer::write(self, &self.header, &plan) {
            Ok(w) => w.final_contexts,
            Err(_) => Contexts::default(),
        };
        let rates = RateTable::new(self, &snapshot);
        let keep = rates.lambda_optimal(self, 1e-2..=1e6, 1);
        self.rates = rates.select(&keep);
        self.retain_candidates(&keep);
        // The kept candidates near the trial's multiplier, rounded with other multipliers,
        // join them, rated under the same contexts; the hull then keeps what pays.
        let window = (self.trial.lambda / VARIANT_WINDOW)..=(self.trial.lambda * VARIANT_WINDOW);
        let vary = self.rates.lambda_optimal(self, window, 1);
        self.add_rounding_variants(&vary);
        let rates = RateTable::new(self, &snapshot);
        let keep = rates.lambda_optimal(self, 1e-2..=1e6, 1);
        self.rates = rates.select(&keep);
        self.retain_candidates(&keep);
    }

    /// Adds to every node, for each candidate `vary` lists (indices into its list) that has the
    /// default weights, the same quantisers rounding its control indices with each of
    /// [`ROUNDING_VARIANTS`] (where that changes an index): points between those of its control
    /// steps.
    fn add_rounding_variants(&mut self, vary: &[Vec<Vec<u16>>]) {
        let plane = &self.plane;
        let header = &self.header;
        for (level, vary) in self.levels.iter_mut().zip(vary) {
            level.nodes.par_iter_mut().zip(vary).for_each(|(na, vary)| {
                let Some(na) = na else { return };
                for &k in vary {
                    let c = na.candidates[usize::from(k)];
                    if c.wq != 0 {
                        continue;
                    }
                    let fit = &na.fits[usize::from(c.fit)];
                    let n = MODELS[usize::from(fit.model)].control_count();
                    let targets = ControlTargets::of(fit, na.node.log2).with_edges(
                        &ImagePrediction { plane },
                        &na.node,
                        fit.model,
                    );
                    for lambda in ROUNDING_VARIANTS {
                        let q =
                            quantise(fit, &targets, c.cq, 0, c.coding, &header.codebooks, lambda);
                        let at = na.indices.len();
                        if na.indices[c.at as usize..][..n] == q.leaf.control[..n] {
                            continue;
                        }
                        na.indices.extend_from_slice(&q.leaf.control[..n]);
                        na.candidates.push(Candidate {
                            sse: quantised_sse(plane, header, &na.node, fit, &q),
                            at: at as u32,
                            ..c
                        });
                    }
                }
            });
        }
    }

    /// Keeps at every node the candidates `keep` lists (indices into its list, ascending).
    fn retain_candidates(&mut self, keep: &[Vec<Vec<u16>>]) {
        for (level, keep) in self.levels.iter_mut().zip(keep) {
            for (na, keep) in level.nodes.iter_mut().zip(keep) {
                if let Some(na) = na {
                    let mut all = std::mem::take(&mut na.candidates).into_iter();
                    let mut at = 0;
                    na.candidates = keep
                        .iter()
                        .map(|&ci| {
                            let c = all.nth(usize::from(ci) - at).expect("index in range");
                            at = usize::from(ci) + 1;
                            c
                        })
                        .collect();
                }
            }
        }
    }

    /// Quantises every fit with every quantiser and measures the closed-loop distortion.
    fn measure_candidates(&mut self) {
        let plane = &self.plane;
        let header = &self.header;
        for level in &mut self.levels {
            level.nodes.par_iter_mut().flatten().for_each(|na| {
                let mut out = Vec::new();
                let mut indices = Vec::new();
                for (fi, fit) in na.fits.iter().enumerate() {
                    let model = MODELS[usize::from(fit.model)];
                    let targets = ControlTargets::of(fit, na.node.log2).with_edges(
                        &ImagePrediction { plane },
                        &na.node,
                        fit.model,
                    );
                    let fitted_weights = fit.weighted;
                    for cq in 0..CONTROL_QUANTISERS as u8 {
                        for wq in 0..WEIGHT_QUANTISERS as u8 {
                            let kind = WEIGHT_QUANTISER_KINDS[usize::from(wq)];
                            let usable = match kind {
                                WeightQuantiser::Default => !fitted_weights,
                                WeightQuantiser::Uniform(_) => fitted_weights,
                                WeightQuantiser::Codebook => {
                                    fitted_weights && header.has_codebooks()
                                }
                            };
                            // Weighted variants are tried on every other control step (a
                            // step ratio of 2): they are rarely chosen, and this halves
                            // their cost.
                            if !usable || (wq > 0 && (model.weight_count() == 0 || cq % 2 == 1)) {
                                continue;
                            }
                            // Both control codings where the syntax allows a choice, for the
                            // default weights; weighted variants (rare) with DPCM only.
                            let codings: &[ControlCoding] = if wq == 0 && model.has_coding_choice()
                            {
                                &[ControlCoding::Dpcm, ControlCoding::Transform]
                            } else {
                                &[ControlCoding::Dpcm]
                            };
                            for &coding in codings {
                                let q = quantise(
                                    fit,
                                    &targets,
                                    cq,
                                    wq,
                                    coding,
                                    &header.codebooks,
                                    ROUNDING_LAMBDA,
                                );
                                let sse = quantised_sse(plane, header, &na.node, fit, &q);
                                let leaf = q.leaf;
                                let (nc, nw) = (model.control_count(), model.weight_count());
                                let at = indices.len() as u32;
                                indices.extend_from_slice(&leaf.control[..nc]);
                                if kind != WeightQuantiser::Default {
                                    indices.extend_from_slice(&leaf.weights[..nw]);
                                }
                                out.push(Candidate {
                                    fit: fi as u8,
                                    cq,
                                    wq,
                                    coding,
                                    sse,
                                    at,
                                });
                            }
                        }
                    }
                }
                na.candidates = out;
                na.indices = indices;
            });
        }
    }
}

/// Prediction from earlier leaves, estimated before the stream exists: earlier leaves are taken
/// to have drawn the image's own pixels, under the decoder's availability rule
/// ([`decoder_core::internal::prediction::Frontier`]).
pub struct ImagePrediction<'a> {
    /// The image.
    pub plane: &'a Plane,
}

impl ImagePrediction<'_> {
    fn sample(&self, x: u32, y: u32) -> i32 {
        i32::from(self.plane.get(x, y)) * SAMPLE_ONE
    }
}

impl SamplePrediction for ImagePrediction<'_> {
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
        let (width, height) = (self.plane.width, self.plane.height);
        let known = if above {
            inside_tile(y, height) && x < width
        } else {
            inside_tile(x, width) && y < height
        };
        known.then(|| {
            let (x, y) = if above { (x, y - 1) } else { (x - 1, y) };
            self.sample(x, y)
        })
    }
}

/// Whether the analysis fits model `m` when weights are not fitted. The 5x5/4x4 model's default
/// scheme makes nearly the same surface as the 5x5/2x2 model's, so searching it too costs
/// analysis time for hardly any gain (see docs/decisions.md).
fn searched_with_default_weights(m: u8) -> bool {
    m != 3
}

/// Layers of the lower convex hull (rate, error) that are kept from the first, untrained rates
/// for rating again under trained contexts.
const HULL_LAYERS: usize = 2;

/// Rounding variants are made of the candidates on a node's hull for multipliers within this
/// factor of the trial's: the targets an analysis serves lie around its trial rate, and
/// varying candidates far from it costs time for no gain (see docs/decisions.md).
const VARIANT_WINDOW: f64 = 16.0;

/// Below this mean squared error per pixel, a candidate's error is measured in the closed loop
/// rather than estimated ([`quantised_sse`]).
const MIN_ESTIMATED_MSE: f64 = 2.0;

/// Squared error of a quantised leaf: by the quadratic form of an exact fit where there is one
/// (the error quantisation added, which error feedback computed, or else [`Fit::error_of`]: the
/// reconstructed control values, or coefficients, exactly and the synthesis in real arithmetic,
/// so it differs from the closed loop only by the integer synthesis's rounding and clamping),
/// else by [`closed_loop_sse`].
fn quantised_sse(plane: &Plane, header: &Header, node: &Node, fit: &Fit, q: &Quantised) -> f64 {
    if let Some(residual) = fit.residual {
        let estimate = q.added_error.map(|added| residual + added).or_else(|| {
            let n = MODELS[usize::from(fit.model)].control_count();
            let mut control = [0.0f64; decoder_core::internal::model::MAX_CONTROL];
            for (c, &v) in control.iter_mut().zip(&q.values[..n]) {
                *c = f64::from(v) / f64::from(SAMPLE_ONE);
            }
            fit.error_of(node.log2, &control[..n])
        });
        if let Some(sse) = estimate {
            // The integer synthesis's rounding adds about 1/12 per pixel and its clamping can
            // remove error; both matter only when the error itself is that small, where the
            // closed loop decides.
            let pixels = f64::from(node.size()) * f64::from(node.size());
            if sse > MIN_ESTIMATED_MSE * pixels {
                return sse;
            }
        }
    }
    closed_loop_sse(plane, header, node, &q.leaf)
}

/// Squared error of a quantised leaf, reconstructed by decoder-core, over its in-image pixels.
pub fn closed_loop_sse(
    plane: &Plane,
    header: &Header,
    node: &Node,
    leaf: &decoder_core::internal::syntax::LeafSyntax,
) -> f64 {
    let Ok(patch) = decoder_core::internal::syntax::reconstruct(header, leaf, node.log2) else {
        return f64::INFINITY;
    };
    struct Sse<'a> {
        plane: &'a Plane,
        total: u64,
    }
    impl PixelSink for Sse<'_> {
        type Error = Infallible;

        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
            let Rect { x, y, w, h } = tile.area;
            let mut k = 0;
            for py in y..y + h {
                for px in x..x + w {
                    let d = i64::from(self.plane.get(px, py)) - i64::from(tile.pixels[k]);
                    self.total += (d * d) as u64;
                    k += 1;
                }
            }
            Ok(())
        }
    }
    let mut sink = Sse { plane, total: 0 };
    let image = Rect::of_size(plane.width, plane.height);
    let Ok(()) = patch.render(node, image, &mut sink);
    sink.total as f64
}

/// Lloyd-Max codebooks for the line and cell weights, from every fitted weight.
fn design_codebooks(levels: &[Level], size: usize) -> [Codebook; 2] {
    if size < 2 {
        return [Codebook::EMPTY; 2];
    }
    let mut samples = [Vec::new(), Vec::new()];
    for na in levels.iter().flat_map(|l| l.nodes.iter().flatten()) {
        for fit in &na.fits {
            if fit.weights.iter().all(|&w| w == 0.0) {
                continue;
            }
            for (w, class) in fit.weights.iter().zip(weight_classes(fit.model)) {
                samples[usize::from(class == WeightClass::Cell)].push(*w);
            }
        }
    }
    let line = lloyd_max(&mut samples[0], size);
    let cell = lloyd_max(&mut samples[1], size);
    if line.len == 0 || cell.len == 0 {
        [Codebook::EMPTY; 2]
    } else {
        [line, cell]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured test image: a smooth pattern plus noise.
    fn textured_plane(w: u32, h: u32) -> Plane {
        let mut seed = 7u32;
        let data = (0..w * h)
            .map(|i| {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let (x, y) = (f64::from(i % w), f64::from(i / w));
                let smooth = 128.0 + 60.0 * (x / 9.0).sin() * (y / 13.0).cos();
                (smooth + f64::from(seed >> 28)).clamp(0.0, 255.0) as u8
            })
            .collect();
        Plane::new(w, h, data)
    }

    /// Rounding with a smaller multiplier keeps more nonzero indices for less added error, a
    /// larger one fewer for more (summed over many leaves: one leaf's greedy rounding need not
    /// be monotonic), and the analysis keeps such variants where they are on a node's hull.
    #[test]
    fn rounding_variants_trade_bits_for_error() {
        let plane = textured_plane(64, 64);
        let codebooks = [Codebook::EMPTY; 2];
        let multipliers = [ROUNDING_VARIANTS[0], ROUNDING_LAMBDA, ROUNDING_VARIANTS[3]];
        // Per multiplier: nonzero indices and added error, summed.
        let mut totals = [(0usize, 0.0f64); 3];
        for log2 in 2..=4u8 {
            for (x, y) in [(0, 0), (16, 16), (32, 0)] {
                let node = Node { x, y, log2 };
                let (models, count) = models_for_block(log2);
                for &m in &models[..count] {
                    let fit = fit_default(&plane, &node, m);
                    let targets = ControlTargets::of(&fit, log2);
                    let n = MODELS[usize::from(m)].control_count();
                    for cq in [4u8, 7, 10] {
                        for coding in [ControlCoding::Dpcm, ControlCoding::Transform] {
                            for (t, &lambda) in totals.iter_mut().zip(&multipliers) {
                                let q = quantise(&fit, &targets, cq, 0, coding, &codebooks, lambda);
                                let Some(added) = q.added_error else { continue };
                                t.0 += q.leaf.control[..n].iter().filter(|&&i| i != 0).count();
                                t.1 += added;
                            }
                        }
                    }
                }
            }
        }
        assert!(
            totals[0].0 > totals[1].0 && totals[1].0 > totals[2].0,
            "{totals:?}"
        );
        assert!(
            totals[0].1 < totals[1].1 && totals[1].1 < totals[2].1,
            "{totals:?}"
        );

        let analysis = Analysis::run(plane, &EncoderConfig::default(), &|_| {});
        let kept_variants = analysis
            .levels
            .iter()
            .flat_map(|l| l.nodes.iter().flatten())
            .filter(|na| {
                na.candidates.iter().enumerate().any(|(i, a)| {
                    na.candidates[..i]
                        .iter()
                        .any(|b| (a.fit, a.cq, a.wq, a.coding) == (b.fit, b.cq, b.wq, b.coding))
                })
            })
            .count();
        assert!(kept_variants > 0, "no node kept a rounding variant");
    }

    /// The quadratic form of an exact fit ([`Fit::error_of`]) predicts the closed-loop error of
    /// every quantised leaf to within the integer synthesis's rounding: with `e` the real
    /// error and `r` the rounding (|r| <= 1/2) at a pixel, `|(e + r)^2 - e^2| <= |e| + 1/4`,
    /// and the sum of `|e|` is at most `sqrt(pixels * estimate)`.
    #[test]
    fn estimated_error_follows_the_closed_loop() {
        let (w, h) = (64u32, 64u32);
        let plane = textured_plane(w, h);
        let header = Header {
            width: w as u16,
            height: h as u16,
            channels: 1,
            bit_depth: 8,
            min_leaf_log2: 2,
            max_leaf_log2: 6,
            codebooks: [Codebook::EMPTY; 2],
            payload_len: 0,
            checksum: 0,
        };
        let mut checked = 0;
        for log2 in 2..=5u8 {
            let node = Node { x: 16, y: 0, log2 };
            let (models, count) = models_for_block(log2);
            for &m in &models[..count] {
                let fit = fit_default(&plane, &node, m);
                let targets = ControlTargets::of(&fit, log2);
                let codings = [ControlCoding::Dpcm, ControlCoding::Transform];
                for (cq, coding) in [0u8, 5, 11]
                    .into_iter()
                    .flat_map(|c| codings.map(|d| (c, d)))
                {
                    let q = quantise(
                        &fit,
                        &targets,
                        cq,
                        0,
                        coding,
                        &header.codebooks,
                        ROUNDING_LAMBDA,
                    );
                    let n = MODELS[usize::from(m)].control_count();
                    let control: Vec<f64> = q.values[..n]
                        .iter()
                        .map(|&v| f64::from(v) / f64::from(SAMPLE_ONE))
                        .collect();
                    let estimate = fit.error_of(log2, &control).expect("an interior exact fit");
                    // Error feedback's own figure agrees with the form of the values.
                    let residual = fit.residual.expect("an interior exact fit");
                    let fed_back = residual + q.added_error.expect("error feedback");
                    assert!(
                        (fed_back - estimate).abs() <= 0.02 * estimate + 1.0,
                        "model {m} at {log2}, cq {cq}, {coding:?}: feedback {fed_back}, form {estimate}"
                    );
                    let closed = closed_loop_sse(&plane, &header, &node, &q.leaf);
                    let pixels = f64::from(node.size() * node.size());
                    let bound = (pixels * estimate).sqrt() + 0.25 * pixels;
                    assert!(
                        (estimate - closed).abs() <= bound,
                        "model {m} at {log2}, cq {cq}, {coding:?}: estimate {estimate}, closed loop {closed}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked >= 60, "only {checked} leaves checked");
    }

    /// Detail finer than the smallest leaf's subdividing grids: a checkerboard of 2 px squares
    /// on 4 px leaves (whose 3 x 3 grid has points 2 px apart: its samples all land on
    /// squares of one colour) is coded by pixel grids, and the stream decodes to the
    /// encoder's reconstruction.
    #[test]
    fn pixel_grids_code_detail_finer_than_their_leaves() {
        let (w, h) = (32u32, 16u32);
        // Left half flat, right half the checkerboard.
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if x < 16 {
                    100
                } else if ((x / 2) + (y / 2)) % 2 == 0 {
                    40
                } else {
                    220
                }
            })
            .collect();
        let plane = Plane::new(w, h, data);
        let config = EncoderConfig {
            max_leaf_log2: 4,
            ..EncoderConfig::default()
        };
        assert_eq!(config.min_leaf_log2, 2, "4 px leaves");
        let analysis = Analysis::run(plane.clone(), &config, &|_| {});
        let encoded = analysis
            .encode(super::super::Target::Bpp(4.0))
            .expect("an encode");
        let mut pixels = vec![0u8; plane.data.len()];
        decoder_core::Decoder::new(&encoded.bytes)
            .and_then(|d| d.decode_into(&mut pixels))
            .expect("a valid stream");
        assert_eq!(pixels, encoded.reconstruction);
        assert!(encoded.psnr > 40.0, "PSNR {}", encoded.psnr);
    }
}
