//! The analysis (thesis Alg. 1), the driver that runs the stages below it on one image: every
//! model that a block can support is fitted at every quadtree node down to the smallest leaf
//! ([`super::fit`]), then quantised ([`super::quantise`]) with every quantiser (or, for an
//! analysis that serves rate targets, with the coarse control steps, then the finer ones only
//! while they pay near the multiplier of a plan at the trial rate), each candidate's
//! distortion measured (by an exact fit's quadratic form, or through decoder-core's own
//! reconstruction); then the candidates are pruned to those rate control can choose
//! ([`super::rate`]), under the contexts of a trial encode ([`super::writer`]). For a colour
//! image, every node also gets what its chroma costs as a leaf ([`super::chroma`]), and a node
//! is settled only where its chroma is smooth too.
//!
//! Above every stage; below the public API (`super`), which encodes targets from its result.

use super::candidates::{
    targets_of, Candidate, CandidateTree, ChromaCost, Level, NodeAnalysis, RoundingId,
    WithCandidates,
};
use super::chroma::{self, ChromaCache, ChromaSteps, ColourPlanes};
use super::config::{EncoderConfig, BOUND_PENALTY};
use super::error::EncodeError;
use super::fit::{fit_default, prepare_projections, Fit};
use super::ids::{ControlQuantiserId, ModelId};
use super::masking::{ContrastScale, Masking};
use super::plane::{ImagePrediction, Plane};
use super::quantise::{
    quantise, ControlTargets, Quantised, ResidualPrices, Rounding, ROUNDING_LAMBDA,
};
use super::rate::{
    leaf_bits, node_hull, prune_node, rate_node, Anchor, GrowingHull, LocalContexts, RateTable,
};
use super::writer;
use decoder_core::internal::colour::rgb_to_luma;
use decoder_core::internal::format::{MAX_LEAF_LOG2, MIN_LEAF_LOG2};
use decoder_core::internal::model::{MAX_CONTROL, SAMPLE_ONE};
use decoder_core::internal::syntax::LeafSyntax;
use decoder_core::internal::syntax::{reconstruct, Contexts, ControlCoding, Header, MAX_DEBLOCK};
use decoder_core::internal::synthesis::{Depth, Patch, Stop, TileMut, TileOut};
use decoder_core::{Node, PixelSink, Rect, Tile};
use rayon::prelude::*;
use std::convert::Infallible;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// The result of the analysis of one image: serves any number of targets
/// ([`Analysis::encode`]). Made by [`crate::analyse`].
#[derive(Debug, Clone)]
pub struct Analysis {
    /// The image.
    pub(super) plane: Plane,
    /// Header of the streams written from this analysis.
    pub(super) header: Header,
    /// Every node's candidates, pruned to those rate control can choose.
    pub(super) tree: CandidateTree,
    /// Rates of the kept candidates under the contexts of a trial encode: the first pass of
    /// every target starts from them.
    pub(super) rates: RateTable,
    /// The trial encode's plan (its multiplier and estimates): where the searches of targets
    /// start.
    pub(super) trial: Anchor,
    /// The pixels the trial encode drew (its luma), which the candidates the final pruning
    /// rounds were predicted from ([`RoundingId::prediction`]); `None` for a 16-bit surface.
    pub(super) drawn: Option<Plane>,
    /// The edge-smoothing strength every stream gets, or `None` to choose it per stream
    /// ([`EncoderConfig::deblock`]).
    pub(super) deblock: Option<u8>,
    /// How long each stage took.
    timing: AnalysisTiming,
    /// The chroma of a colour image (the analysis itself sees `plane`, its luma): streams
    /// are then colour streams.
    pub(super) colour: Option<ColourPlanes>,
    /// Chroma options the writes of colour streams reconstructed, for the next writes.
    pub(super) chroma_cache: ChromaCache,
}

/// How long each stage of an analysis took (wall time), for a caller that reports it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct AnalysisTiming {
    /// Fitting every model at every node.
    pub fits: Duration,
    /// Quantising the fits and measuring each candidate's error.
    pub candidates: Duration,
    /// Pruning the candidates, the trial encode included.
    pub pruning: Duration,
}

impl Analysis {
    /// The image analysed.
    pub fn plane(&self) -> &Plane {
        &self.plane
    }

    /// Width of the image, pixels.
    pub fn width(&self) -> u32 {
        u32::from(self.header.width)
    }

    /// Height of the image, pixels.
    pub fn height(&self) -> u32 {
        u32::from(self.header.height)
    }

    /// Side of the smallest leaf, as a power of two ([`EncoderConfig::min_leaf_log2`] as the
    /// format allows it).
    pub fn min_leaf_log2(&self) -> u8 {
        self.header.min_leaf_log2
    }

    /// Side of the largest leaf, as a power of two ([`EncoderConfig::max_leaf_log2`] as the
    /// format allows it).
    pub fn max_leaf_log2(&self) -> u8 {
        self.header.max_leaf_log2
    }

    /// How long each stage took.
    pub fn timing(&self) -> AnalysisTiming {
        self.timing
    }

    /// Channels of the streams this analysis writes: 1 (grayscale) or 3 (colour).
    pub fn channels(&self) -> u8 {
        self.header.channels
    }

    /// Analyses `plane`, an image's luma, and with `colour` its chroma for colour streams.
    /// `progress` is called with the number of nodes done so far: every node of a leaf size
    /// once fitted, then once its candidates are made.
    pub(super) fn run(
        plane: Plane,
        colour: Option<ColourPlanes>,
        config: &EncoderConfig,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Analysis, EncodeError> {
        let scale = ContrastScale::of(&plane, config.tune);
        Analysis::run_in_bands(plane, colour, config, (BAND_PIXELS, scale), progress)
    }

    /// [`Analysis::run`] of a part of an image (`plane`, cut by [`Plane::crop`], and its
    /// chroma), its errors weighed by the whole image's contrast `scale`: the analysis the
    /// whole image's would make there, but at the part's top edge (its trial encode, which
    /// trains its rates, sees no pixel above it).
    pub(super) fn run_part(
        plane: Plane,
        colour: Option<ColourPlanes>,
        config: &EncoderConfig,
        scale: Option<ContrastScale>,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Analysis, EncodeError> {
        Analysis::run_in_bands(plane, colour, config, (BAND_PIXELS, scale), progress)
    }

    /// [`Analysis::run`], fitting and quantising bands of about `band_pixels` pixels one after
    /// the other ([`band_height`]), errors weighed by `scale` ([`Masking::scaled`]).
    fn run_in_bands(
        mut plane: Plane,
        colour: Option<ColourPlanes>,
        config: &EncoderConfig,
        (band_pixels, scale): (u32, Option<ContrastScale>),
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Analysis, EncodeError> {
        let mut header = header_for(&plane, config)?;
        plane.bound = config.bound_in_samples();
        if colour.is_some() {
            header.channels = 3;
        }
        let mut analysis = Analysis {
            tree: CandidateTree::new(
                empty_levels(&plane, &header),
                header.min_leaf_log2,
                Masking::scaled(&plane, scale),
            ),
            plane,
            header,
            rates: RateTable::empty(),
            trial: Anchor {
                lambda: 1.0,
                bits: 1.0,
                sse: 1.0,
            },
            drawn: None,
            // A 16-bit stream is not smoothed (its samples are the leaves').
            deblock: match config.range {
                Some(_) => Some(0),
                None => config.deblock.map(|d| d.min(MAX_DEBLOCK)),
            },
            timing: AnalysisTiming::default(),
            colour,
            chroma_cache: ChromaCache::default(),
        };
        let started = Instant::now();
        let (first, fit_time) = analysis.measure_candidates(config, band_pixels, progress);
        let candidates = started.elapsed().saturating_sub(fit_time);
        let started = Instant::now();
        analysis.prune_candidates(config.trial_bpp, first);
        analysis.timing = AnalysisTiming {
            fits: fit_time,
            candidates,
            pruning: started.elapsed(),
        };
        Ok(analysis)
    }

    /// Keeps, at every node, only the candidates that are its best leaf for some multiplier of
    /// interest, under rates measured from a trial encode's adapted contexts. Every later
    /// encode then weighs a handful of candidates per node instead of all of them.
    /// `first` rates the candidates from the contexts every stream starts from.
    fn prune_candidates(&mut self, trial_bpp: f64, first: RateTable) {
        let pixels = self.header.pixel_count() as f64;
        // A rough plan only gathers coding statistics.
        let plan = first.rough_plan_for_bits(&self.tree, &self.header, trial_bpp * pixels);
        drop(first);
        self.trial = plan.anchor();
        // The split flags are priced from the contexts the trial ended with.
        let (snapshot, local) = match writer::write_trial(
            (&self.tree, &prediction_of(&self.plane, &self.header)),
            &self.header,
            &plan,
            &self.chroma_cache,
        ) {
            Ok(t) => {
                self.drawn = trial_reconstruction(&t.written.bytes, &self.plane);
                (t.written.final_contexts, t.local)
            }
            Err(_) => (Contexts::default(), LocalContexts::default()),
        };
        let trial = Trial {
            prediction: prediction_of(&self.plane, &self.header).with_drawn(self.drawn.as_ref()),
            local: &local,
            window: (self.trial.lambda / VARIANT_WINDOW)..=(self.trial.lambda * VARIANT_WINDOW),
        };
        let plane = &self.plane;
        let (levels, masking) = self.tree.levels_and_masking_mut();
        for level in levels {
            level.nodes.par_iter_mut().flatten().for_each(|na| {
                let weight = masking.weight(&na.node);
                final_candidates(plane, (na, weight), &trial);
            });
        }
        self.rates = RateTable::of_contexts(&snapshot);
    }

    /// Fits every model at every node and quantises every fit with every quantiser (with
    /// [`EncoderConfig::fine_steps`], the coarse steps, a plan at the trial rate from them,
    /// then the finer steps that pay) and measures each candidate's distortion; keeps at each
    /// node, as soon as it is done, only the candidates on its hull under the rates every
    /// stream starts from (the trained contexts change the rates only a little, so what is off
    /// the hull under the first rates seldom reaches it under the trained ones; see
    /// docs/decisions.md): the rest is never stored.
    /// Returns the rates of the kept candidates and the time the fitting took. `progress` is called
    /// with the number of node steps done so far (in the order [`analysis_steps`] gives).
    fn measure_candidates(
        &mut self,
        config: &EncoderConfig,
        band_pixels: u32,
        progress: &(dyn Fn(u64) + Sync),
    ) -> (RateTable, Duration) {
        let start = Contexts::default();
        let first = if config.fine_steps.is_some() {
            FIRST_COARSE
        } else {
            0
        };
        let done = AtomicU64::new(0);
        let report = || progress(done.fetch_add(1, Ordering::Relaxed) + 1);
        let (ends, fit_time) = self.fit_and_coarse(band_pixels, (&start, first), &report);
        let rates = RateTable::of_contexts(&start);
        let Some(margin) = config.fine_steps else {
            return (rates, fit_time);
        };
        // The multiplier of a plan at the trial rate from the coarse steps alone: a plan
        // with finer steps too reaches that rate at about the same multiplier or above.
        // The plan is dropped before the fine pass adds its candidates.
        let trial_lambda = {
            let pixels = self.header.pixel_count() as f64;
            let plan =
                rates.rough_plan_for_bits(&self.tree, &self.header, config.trial_bpp * pixels);
            plan.anchor().lambda
        };
        let search = FineSearch {
            start: &start,
            first,
            floor: trial_lambda / margin,
        };
        let (plane, header) = (&self.plane, &self.header);
        let colour = self.colour.as_ref();
        let stripe = header.stripe_width();
        let chroma_steps = ChromaSteps::Fine {
            first,
            floor: search.floor,
        };
        let (levels, masking) = self.tree.levels_and_masking_mut();
        // Each node's chain ends are dropped once its fine pass is done.
        for (level, ends) in levels.iter_mut().zip(ends) {
            if level.log2 > header.max_leaf_log2 {
                continue;
            }
            level.nodes.par_iter_mut().zip(ends).for_each(|(na, ends)| {
                if let Some(na) = na {
                    let weight = masking.weight(&na.node);
                    fine_candidates(plane, header, (na, weight), &ends, &search);
                    prune_node(na, &ALL_LAMBDAS);
                    if let Some(colour) = colour {
                        let node = na.node;
                        let cost = &na.chroma;
                        na.chroma =
                            chroma::leaf_cost(colour, &node, (stripe, weight), chroma_steps, cost);
                    }
                }
                report();
            });
        }
        (rates, fit_time)
    }

    /// The fitting and the coarse pass of [`Analysis::measure_candidates`], band by band
    /// ([`band_height`]): a band's nodes are fitted, then get their candidates from control
    /// step `first` up, rated from `start`, pruned (a candidate off the hull stays off it when
    /// finer steps join), and the band's fits are dropped, so that the fits of the whole image
    /// never live at once.
    /// Returns the chains' ends, per level and node, and the time the fitting took.
    fn fit_and_coarse(
        &mut self,
        band_pixels: u32,
        (start, first): (&Contexts, u8),
        report: &(dyn Fn() + Sync),
    ) -> (PerNode<Vec<ChainEnd>>, Duration) {
        let top = largest_leaf_log2(&self.header);
        prepare_projections(self.header.min_leaf_log2..=top);
        let mut ends: PerNode<Vec<ChainEnd>> = vec![Vec::new(); self.tree.levels().len()];
        let band = band_height(&self.header, top, band_pixels);
        let mut fit_time = Duration::ZERO;
        for y in (0..self.plane.height).step_by(band as usize) {
            let started = Instant::now();
            let fits = self.fit_band(y..y + band, report);
            fit_time += started.elapsed();
            self.coarse_band(y..y + band, fits, start, first, report, &mut ends);
        }
        // Levels above the largest leaf have no candidates, but an empty list per node.
        for (level, ends) in self.tree.levels().iter().zip(&mut ends) {
            if level.log2 > top {
                ends.resize(level.nodes.len(), Vec::new());
            }
        }
        (ends, fit_time)
    }

    /// Fits every node of a leaf size whose rows lie in `rows` (pixels; the band's), from the
    /// largest down; a node inside a settled one ([`settles`]) is not analysed: its parent is a
    /// leaf as good as any cut below it, so easy content (flat or smooth areas) costs only its
    /// largest nodes. Returns the fits of the band's nodes, per level (smallest first) and
    /// node, for the coarse pass (where the nodes keep only their models).
    fn fit_band(&mut self, rows: Range<u32>, report: &(dyn Fn() + Sync)) -> PerNode<Vec<Fit>> {
        // The first band's nodes hold their candidates' indices (all of an image of one band);
        // the others' are made again when needed, so that the memory stops growing with them.
        let holds = rows.start == 0;
        let (plane, colour) = (&self.plane, self.colour.as_ref());
        let min = self.header.min_leaf_log2;
        let top = largest_leaf_log2(&self.header);
        let mut all_fits = vec![Vec::new(); self.tree.levels().len()];
        // Whether each node of the band in the level above (the last one fitted) is settled,
        // from the node of index `above_first` on.
        let (mut settled_above, mut above_first, mut cols_above) = (Vec::new(), 0, 0);
        for log2 in (min..=top).rev() {
            let level = &mut self.tree.levels_mut()[usize::from(log2 - min)];
            let nodes = band_nodes(level, &rows);
            let cols = level.cols;
            let fitted: Vec<_> = nodes
                .clone()
                .into_par_iter()
                .map(|i| {
                    let (cx, cy) = (i as u32 % cols, i as u32 / cols);
                    let node = Node {
                        x: cx << log2,
                        y: cy << log2,
                        log2,
                    };
                    let parent = ((cy / 2) * cols_above + cx / 2) as usize;
                    let inside_settled = parent
                        .checked_sub(above_first)
                        .and_then(|p| settled_above.get(p).copied())
                        .unwrap_or(false);
                    if inside_settled {
                        report();
                        return (None, Vec::new(), true);
                    }
                    let fits = fit_node(plane, &node);
                    report();
                    let settled = settles(plane, &node, &fits)
                        && colour.is_none_or(|c| chroma::smooth_within(c, &node, SETTLED_MSE));
                    (Some(NodeAnalysis::new(node, holds)), fits, settled)
                })
                .collect();
            // Collected whole, then split: unzipping in parallel grew chunks while the fits'
            // large temporaries came and went, and the allocator kept the holes (see
            // docs/decisions.md).
            let mut fits = Vec::with_capacity(fitted.len());
            settled_above = Vec::with_capacity(fitted.len());
            for ((na, node_fits, settled), slot) in
                fitted.into_iter().zip(&mut level.nodes[nodes.clone()])
            {
                *slot = na;
                fits.push(node_fits);
                settled_above.push(settled);
            }
            (above_first, cols_above) = (nodes.start, cols);
            all_fits[usize::from(log2 - min)] = fits;
        }
        all_fits
    }

    /// The coarse pass over the nodes whose rows lie in `rows` (pixels; the band's), with
    /// their `fits`: each node keeps what it needs of its fits and its candidates from control
    /// step `first` up, pruned; appends its chains' ends to `out`.
    fn coarse_band(
        &mut self,
        rows: Range<u32>,
        fits: PerNode<Vec<Fit>>,
        start: &Contexts,
        first: u8,
        report: &(dyn Fn() + Sync),
        out: &mut PerNode<Vec<ChainEnd>>,
    ) {
        let (plane, header) = (&self.plane, &self.header);
        let colour = self.colour.as_ref();
        let stripe = header.stripe_width();
        let (levels, masking) = self.tree.levels_and_masking_mut();
        for ((level, fits), ends) in levels.iter_mut().zip(fits).zip(out) {
            if level.log2 > header.max_leaf_log2 {
                continue;
            }
            let nodes = band_nodes(level, &rows);
            let band_ends: Vec<Vec<ChainEnd>> = level.nodes[nodes]
                .par_iter_mut()
                .zip(fits)
                .map(|(na, fits)| {
                    let out = match na {
                        Some(na) => {
                            let weight = masking.weight(&na.node);
                            if let Some(colour) = colour {
                                let steps = match first {
                                    0 => ChromaSteps::All,
                                    first => ChromaSteps::Coarse { first },
                                };
                                na.chroma = chroma::leaf_cost(
                                    colour,
                                    &na.node,
                                    (stripe, weight),
                                    steps,
                                    &ChromaCost::default(),
                                );
                            }
                            na.fits = fits.iter().map(|f| f.model).collect();
                            let ends =
                                coarse_candidates(plane, header, (na, weight), &fits, start, first);
                            prune_node(na, &ALL_LAMBDAS);
                            ends
                        }
                        None => Vec::new(),
                    };
                    report();
                    out
                })
                .collect();
            ends.extend(band_ends);
        }
    }
}

impl WithCandidates for Analysis {
    fn candidates(&self) -> &CandidateTree {
        &self.tree
    }
}

/// The header of the streams of `plane` under `config` (its payload yet unknown), or
/// [`EncodeError::BadDimensions`] if the format cannot hold the image.
pub(super) fn header_for(plane: &Plane, config: &EncoderConfig) -> Result<Header, EncodeError> {
    header_of_size(plane.width, plane.height, config)
}

/// [`header_for`] an image of `width x height` pixels.
pub(super) fn header_of_size(
    width: u32,
    height: u32,
    config: &EncoderConfig,
) -> Result<Header, EncodeError> {
    let bad = || EncodeError::BadDimensions { width, height };
    let width = u16::try_from(width).map_err(|_| bad())?;
    let height = u16::try_from(height).map_err(|_| bad())?;
    if width == 0 || height == 0 {
        return Err(bad());
    }
    // Leaf sizes the format allows.
    let min_leaf_log2 = config.min_leaf_log2.clamp(MIN_LEAF_LOG2, MAX_LEAF_LOG2);
    Ok(Header {
        width,
        height,
        channels: 1,
        bit_depth: if config.range.is_some() { 16 } else { 8 },
        min_leaf_log2,
        max_leaf_log2: config.max_leaf_log2.clamp(min_leaf_log2, MAX_LEAF_LOG2),
        stripe: config.stripe,
        deblock: 0,
        // Set by the writer.
        payload_len: 0,
        checksum: 0,
        range: config.range,
    })
}

/// Every level of the quadtree of `header`, from the smallest leaf to the root, with no node
/// analysed yet.
fn empty_levels(plane: &Plane, header: &Header) -> Vec<Level> {
    (header.min_leaf_log2..=header.root_log2())
        .map(|log2| {
            let cols = plane.width.div_ceil(1 << log2);
            let rows = plane.height.div_ceil(1 << log2);
            Level {
                log2,
                cols,
                nodes: vec![None; (cols * rows) as usize],
            }
        })
        .collect()
}

/// Side of the largest nodes analysed under `header`, as a power of two: the largest leaf, or
/// the root when the image is smaller.
fn largest_leaf_log2(header: &Header) -> u8 {
    header.max_leaf_log2.min(header.root_log2())
}

/// Pixels a band of the analysis holds at least (unless the image is smaller): its fits live
/// until its coarse pass, about 75 bytes a pixel, so an image of any size is analysed in a
/// bounded memory, in bands large enough to keep both cores busy.
const BAND_PIXELS: u32 = 1 << 20;

/// Height of the bands the analysis fits and quantises one after the other (pixels): whole
/// rows of the largest nodes (of side `2^top`), `band_pixels` or more, at most the image.
fn band_height(header: &Header, top: u8, band_pixels: u32) -> u32 {
    let node_rows = u32::from(header.height).div_ceil(1 << top);
    let row_pixels = u32::from(header.width) << top;
    band_pixels.div_ceil(row_pixels).clamp(1, node_rows) << top
}

/// What an analysis does in one stretch of the node steps it reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum AnalysisStage {
    /// Fitting every model to a node.
    Fitting,
    /// Quantising a node's fits at the coarse control steps (at every step when there is no
    /// fine pass) and rating them.
    Coarse,
    /// Quantising a node's fits at the finer control steps that pay near the trial's
    /// multiplier ([`EncoderConfig::fine_steps`]).
    Fine,
}

/// A stretch of the node steps an analysis reports: `nodes` steps of one stage at nodes of
/// side `2^log2`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AnalysisSteps {
    /// What is done.
    pub stage: AnalysisStage,
    /// Side of the nodes, as a power of two.
    pub log2: u8,
    /// Node steps.
    pub nodes: u64,
}

/// The node steps [`crate::analyse`] (or [`crate::analyse_colour`]) reports on a `width x
/// height` image under `config`, in the order it does them (band by band, each band fitted
/// from its largest nodes down, then quantised from its smallest up; the fine pass over the
/// whole image at the end), so that a progress display can weigh each step by its work.
/// Empty for an image the format cannot hold.
pub fn analysis_steps(width: u32, height: u32, config: &EncoderConfig) -> Vec<AnalysisSteps> {
    steps_in_bands(width, height, config, BAND_PIXELS)
}

/// [`analysis_steps`] of an analysis in bands of about `band_pixels` pixels.
fn steps_in_bands(
    width: u32,
    height: u32,
    config: &EncoderConfig,
    band_pixels: u32,
) -> Vec<AnalysisSteps> {
    let Ok(header) = header_of_size(width, height, config) else {
        return Vec::new();
    };
    let (min, top) = (header.min_leaf_log2, largest_leaf_log2(&header));
    let band = band_height(&header, top, band_pixels);
    let stretch = |stage, log2: u8, rows: Range<u32>| {
        let nodes = |y: u32| u64::from(y.min(height).div_ceil(1 << log2));
        AnalysisSteps {
            stage,
            log2,
            nodes: u64::from(width.div_ceil(1 << log2)) * (nodes(rows.end) - nodes(rows.start)),
        }
    };
    let mut steps = Vec::new();
    for y in (0..height).step_by(band as usize) {
        let rows = y..y + band;
        steps.extend(
            (min..=top)
                .rev()
                .map(|l| stretch(AnalysisStage::Fitting, l, rows.clone())),
        );
        steps.extend((min..=top).map(|l| stretch(AnalysisStage::Coarse, l, rows.clone())));
    }
    if config.fine_steps.is_some() {
        steps.extend((min..=top).map(|l| stretch(AnalysisStage::Fine, l, 0..height)));
    }
    steps
}

/// The indices in `level`'s nodes of those whose rows lie in `rows` (pixels, from and up to
/// multiples of the level's node side or the image's bottom).
fn band_nodes(level: &Level, rows: &Range<u32>) -> Range<usize> {
    let cols = level.cols as usize;
    let last = level.nodes.len() / cols;
    let row = |y: u32| ((y >> level.log2) as usize).min(last);
    row(rows.start) * cols..row(rows.end) * cols
}

/// Mean squared error per pixel (grey levels squared) within which a node's best fit
/// reproduces its block for the node to be settled: nothing below it is analysed (see
/// docs/decisions.md).
const SETTLED_MSE: f64 = 0.5;

/// Coded values four children need at least (a bilinear patch each): a fit settles a node
/// only with fewer, so that a cut below cannot be cheaper; a richer fit (a pixel grid is
/// exact) settles nothing.
const CHILDREN_VALUES: usize = 4 * 4;

/// Whether the block of `node` is reproduced by one of its `fits` of fewer than
/// [`CHILDREN_VALUES`] values (by an exact fit's residual), or by its mean (for a block at the
/// image's edge), within [`SETTLED_MSE`] per pixel.
fn settles(plane: &Plane, node: &Node, fits: &[Fit]) -> bool {
    let x1 = (node.x + node.size()).min(plane.width);
    let y1 = (node.y + node.size()).min(plane.height);
    let pixels = f64::from((x1 - node.x) * (y1 - node.y));
    let best = fits
        .iter()
        .filter(|f| f.model.model().coded_side(node.log2).pow(2) < CHILDREN_VALUES)
        .filter_map(|f| f.residual)
        .fold(f64::INFINITY, f64::min);
    let sse = if best.is_finite() {
        best
    } else {
        let (mut sum, mut sum2) = (0.0, 0.0);
        for y in node.y..y1 {
            for x in node.x..x1 {
                let v = plane.value(x, y);
                sum += v;
                sum2 += v * v;
            }
        }
        sum2 - sum * sum / pixels
    };
    sse <= SETTLED_MSE * pixels
}

/// The fits of `node`: one per model it supports (the least-squares control values).
fn fit_node(plane: &Plane, node: &Node) -> Vec<Fit> {
    ModelId::for_block(node.log2)
        .map(|m| fit_default(plane, node, m))
        .collect()
}

/// One way of quantising a fit at successive control steps: the fit (an index into the node's
/// fits) and its control coding.
#[derive(Debug, Clone, Copy)]
struct Chain {
    fit: u8,
    coding: ControlCoding,
}

/// The chains of fit `fit` (the node's fit number `fi`): both control codings where the
/// syntax allows a choice.
fn chains_of(fi: usize, fit: &Fit) -> Vec<Chain> {
    let codings: &[ControlCoding] = if fit.model.model().has_coding_choice() {
        &[ControlCoding::Dpcm, ControlCoding::Transform]
    } else {
        &[ControlCoding::Dpcm]
    };
    codings
        .iter()
        .map(|&coding| Chain {
            fit: fi as u8,
            coding,
        })
        .collect()
}

/// The pixels a trial `stream` of `plane` decodes to, as a plane predictions can be made from
/// (its luma: for a colour stream, that of its RGB by the encoder's rule, within a level of the
/// decoder's own). `None` for a 16-bit surface, which is predicted from its own samples.
fn trial_reconstruction(stream: &[u8], plane: &Plane) -> Option<Plane> {
    /// Keeps the luma of the tiles it is given.
    struct Luma {
        width: u32,
        pixels: Vec<u8>,
    }
    impl PixelSink for Luma {
        type Error = Infallible;

        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
            let Rect { x, y, w, h } = tile.area;
            let channels = usize::from(tile.channels);
            let mut k = 0;
            for py in y..y + h {
                let row = (py * self.width) as usize;
                for px in x..x + w {
                    let p = &tile.pixels[k * channels..][..channels];
                    self.pixels[row + px as usize] = match p {
                        &[r, g, b] => rgb_to_luma(r, g, b),
                        _ => p[0],
                    };
                    k += 1;
                }
            }
            Ok(())
        }
    }
    if plane.fine.is_some() {
        return None;
    }
    let decoder = decoder_core::Decoder::new(stream)
        .ok()?
        .stripe_capacity::<{ 1 << 16 }>();
    let (width, height) = decoder.output_size();
    if (width, height) != (plane.width, plane.height) {
        return None;
    }
    let mut luma = Luma {
        width,
        pixels: vec![0; plane.data.len()],
    };
    decoder.decode(&mut luma).ok()?;
    Some(plane.redrawn(luma.pixels))
}

/// Prediction from the pixels of `plane`, coded under `header`, as the analysis estimates it.
pub(super) fn prediction_of<'a>(plane: &'a Plane, header: &Header) -> ImagePrediction<'a> {
    ImagePrediction::new(plane, header.stripe_width())
}

/// Quantises `fit` (the node's fit of chain `chain`, whose targets are `targets`) with control
/// quantiser `cq`, measures its error (times the node's `weight`, [`Masking`]) and its bits
/// (coded from `ctx`, left as it is) and adds it to `na`'s candidates. Returns it.
fn add_candidate(
    plane: &Plane,
    (na, weight): (&mut NodeAnalysis, f64),
    (fit, targets): (&Fit, &ControlTargets),
    (chain, cq): (Chain, ControlQuantiserId),
    (prediction, ctx): (&ImagePrediction, &mut Contexts),
) -> Candidate {
    let q = quantise(
        fit,
        targets,
        cq,
        chain.coding,
        Rounding::from_start(ROUNDING_LAMBDA),
    );
    let c = Candidate {
        fit: chain.fit,
        cq,
        coding: chain.coding,
        rounding: RoundingId::default(),
        sse: quantised_sse(plane, &na.node, fit, &q) * weight,
        bits: leaf_bits(&na.node, &q.leaf, prediction, ctx),
    };
    na.push(c, &q.leaf);
    c
}

/// What the final pruning of every node needs from the trial encode.
struct Trial<'a> {
    /// Prediction from the image, knowing the pixels the trial encode drew.
    prediction: ImagePrediction<'a>,
    /// The trial encode's contexts at the end of each block: a candidate is rated from those
    /// of the block around its node, and its variants rounded with their prices.
    local: &'a LocalContexts,
    /// The multipliers near the trial's, whose candidates get rounding variants.
    window: std::ops::RangeInclusive<f64>,
}

/// The final pruning of node `na`, under the trial encode's contexts: rates its candidates
/// from those of the block around it, keeps those that are its best leaf for some multiplier,
/// adds the rounding variants of those best near the trial's multiplier
/// ([`add_rounding_variants`], some priced under the block's contexts), and keeps again what
/// pays. Node by node, so that no node's variants wait for the others'.
/// `weight`: the node's error weight ([`Masking`]).
fn final_candidates(plane: &Plane, (na, weight): (&mut NodeAnalysis, f64), trial: &Trial) {
    let prediction = &trial.prediction;
    let around = trial.local.around(&na.node);
    rate_node(na, prediction, &around.contexts);
    prune_node(na, &ALL_LAMBDAS);
    let vary = node_hull(na, &trial.window);
    let known = na.candidates.len();
    let prices = around.prices();
    let varied = add_rounding_variants(plane, prediction, (na, weight), &vary, &prices);
    na.prices = Some(prices);
    let node = na.node;
    let mut ctx = around.contexts.clone();
    for (c, leaf) in na.candidates[known..].iter_mut().zip(&varied) {
        c.bits = leaf_bits(&node, leaf, &prediction.drawn(), &mut ctx);
    }
    prune_node(na, &ALL_LAMBDAS);
}

/// Adds to node `na`, for each of its candidates `vary` lists, the same quantisers rounding
/// its control indices with [`ROUNDING_LAMBDA`] and each of [`ROUNDING_VARIANTS`], the bits
/// priced under `block`, the trial encode's contexts around the node ([`RoundingId::variants`];
/// where that makes indices no other rounding made): points between those of its control
/// steps, rounded knowing what bits cost there. Their errors are weighted by `weight`, as the
/// node's others are. They are rounded predicting from the pixels the trial drew
/// ([`ImagePrediction::drawn`] of `image`). Returns the syntax of the added candidates, in
/// order.
fn add_rounding_variants(
    plane: &Plane,
    image: &ImagePrediction,
    (na, weight): (&mut NodeAnalysis, f64),
    vary: &[u16],
    block: &ResidualPrices,
) -> Vec<LeafSyntax> {
    // Each fit is made again (with its targets) once, for all its candidates.
    let mut made: Vec<Option<(Fit, ControlTargets)>> = (0..na.fits.len()).map(|_| None).collect();
    let roundings: Vec<RoundingId> = RoundingId::variants().collect();
    let mut varied = Vec::with_capacity(vary.len() * roundings.len());
    na.reserve(varied.capacity(), varied.capacity() * MAX_CONTROL);
    let drawn = image.drawn();
    for &k in vary {
        let c = na.candidates[usize::from(k)];
        let own = na.leaf(usize::from(k), image);
        let (fit, targets) =
            made[usize::from(c.fit)].get_or_insert_with(|| na.fit_and_targets(c.fit, &drawn));
        let n = fit.model.model().control_count();
        let mut made_here = vec![own.control];
        for r in &roundings {
            let q = quantise(fit, targets, c.cq, c.coding, r.with(Some(block)));
            if made_here.iter().any(|m| m[..n] == q.leaf.control[..n]) {
                continue;
            }
            made_here.push(q.leaf.control);
            let v = Candidate {
                sse: quantised_sse(plane, &na.node, fit, &q) * weight,
                rounding: *r,
                ..c
            };
            na.push(v, &q.leaf);
            varied.push(q.leaf);
        }
    }
    varied
}

/// Something per analysed node, level by level (smallest nodes first) and node by node.
type PerNode<T> = Vec<Vec<T>>;

/// Where a chain's coarse pass ended: the chain, and the bits and error of its finest step.
#[derive(Debug, Clone, Copy)]
struct ChainEnd {
    chain: Chain,
    bits: f32,
    sse: f64,
}

/// The coarse pass at node `na`: every chain of every fit at the control steps from `first`
/// up, coarsest first, rated from `start`, until the node's candidates so far make a step
/// pointless: once their hull covers a step's bits at the fit's own residual, every finer
/// step of the chain (more bits, and never less error than the residual) is off the hull too.
/// The richest fits go first, so that their candidates end the poorer fits' chains early.
/// Replaces the node's candidates; returns where each chain that reached step `first` ended.
fn coarse_candidates(
    plane: &Plane,
    header: &Header,
    (na, weight): (&mut NodeAnalysis, f64),
    fits: &[Fit],
    start: &Contexts,
    first: u8,
) -> Vec<ChainEnd> {
    na.clear();
    let chains: Vec<Vec<Chain>> = (fits.iter().enumerate())
        .map(|(fi, fit)| chains_of(fi, fit))
        .collect();
    // Room for every candidate the pass can make, so that pushing never moves them.
    let steps = ControlQuantiserId::all()
        .filter(|cq| cq.rank() >= first)
        .count();
    for (fit, chains) in fits.iter().zip(&chains) {
        let n = chains.len() * steps;
        na.reserve(n, n * fit.model.model().control_count());
    }
    let prediction = prediction_of(plane, header);
    let mut ctx = start.clone();
    let mut hull = GrowingHull::default();
    let mut ends = Vec::new();
    for (fit, chains) in fits.iter().zip(chains).rev() {
        let targets = targets_of(&prediction, &na.node, fit);
        let residual = error_floor(&na.node, fit) * weight;
        for chain in chains {
            let mut end = None;
            let tried = ControlQuantiserId::all().filter(|cq| cq.rank() >= first);
            for cq in tried.rev() {
                let rating = (&prediction, &mut ctx);
                let c = add_candidate(plane, (na, weight), (fit, &targets), (chain, cq), rating);
                hull.add((f64::from(c.bits), c.sse));
                if hull.covers((f64::from(c.bits), residual)) {
                    end = None;
                    break;
                }
                end = Some(ChainEnd {
                    chain,
                    bits: c.bits,
                    sse: c.sse,
                });
            }
            ends.extend(end);
        }
    }
    ends
}

/// The least squared error any candidate of `fit` on `node` can have: the residual of an exact
/// fit, unless errors that small are measured in the closed loop ([`quantised_sse`]), whose
/// integer synthesis may clamp some error away; else zero.
fn error_floor(node: &Node, fit: &Fit) -> f64 {
    let pixels = f64::from(node.size()) * f64::from(node.size());
    fit.residual
        .filter(|&r| r > MIN_ESTIMATED_MSE * pixels)
        .unwrap_or(0.0)
}

/// What the fine pass searches: steps finer than control quantiser `first`, rated from
/// `start`, while they lower a node's error by at least `floor` per bit.
struct FineSearch<'a> {
    start: &'a Contexts,
    first: u8,
    floor: f64,
}

/// The fine pass at node `na`, after the coarse one ended at `ends` (`bits`: the bits of the
/// node's candidates, to which it adds those it makes): each chain goes on to finer steps
/// while a step lowers the error by at least the floor per bit it adds; a step that buys
/// less only pays for multipliers below the floor, and a finer one still, less again.
fn fine_candidates(
    plane: &Plane,
    header: &Header,
    (na, weight): (&mut NodeAnalysis, f64),
    ends: &[ChainEnd],
    search: &FineSearch,
) {
    let prediction = prediction_of(plane, header);
    let mut ctx = search.start.clone();
    let mut hull = GrowingHull::default();
    for c in &na.candidates {
        hull.add((f64::from(c.bits), c.sse));
    }
    let steps = ControlQuantiserId::all()
        .filter(|cq| cq.rank() < search.first)
        .count();
    na.reserve(ends.len() * steps, ends.len() * steps * MAX_CONTROL);
    // The chains of one fit are consecutive: its targets are made once.
    for same_fit in ends.chunk_by(|a, b| a.chain.fit == b.chain.fit) {
        let fit = fit_default(plane, &na.node, na.fits[usize::from(same_fit[0].chain.fit)]);
        let targets = targets_of(&prediction, &na.node, &fit);
        let residual = error_floor(&na.node, &fit) * weight;
        for end in same_fit {
            // The hull may have come to cover the chain's coarse end since (with the finer
            // steps of other chains): its finer steps could not be on it either.
            if hull.covers((f64::from(end.bits), residual)) {
                continue;
            }
            let chain = end.chain;
            let (mut last_bits, mut last_sse) = (end.bits, end.sse);
            for cq in ControlQuantiserId::all()
                .filter(|cq| cq.rank() < search.first)
                .rev()
            {
                let rating = (&prediction, &mut ctx);
                let c = add_candidate(plane, (na, weight), (&fit, &targets), (chain, cq), rating);
                let b = c.bits;
                hull.add((f64::from(b), c.sse));
                let added = f64::from(b) - f64::from(last_bits);
                let stalls = added > 0.0 && last_sse - c.sse < search.floor * added;
                if stalls || hull.covers((f64::from(b), residual)) {
                    break;
                }
                (last_bits, last_sse) = (b, c.sse);
            }
        }
    }
}

/// With [`EncoderConfig::fine_steps`], control quantisers from this one up (steps of 128 and
/// coarser, 1/16 grey) are tried at every node, finer ones only while they pay.
const FIRST_COARSE: u8 = 7;

/// The multipliers the analysis keeps candidates for: every target's.
const ALL_LAMBDAS: std::ops::RangeInclusive<f64> = 1e-2..=1e6;

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
/// else by [`closed_loop_sse`]. Under a bound on each pixel's error, always by the closed loop:
/// the form knows no single pixel's error.
fn quantised_sse(plane: &Plane, node: &Node, fit: &Fit, q: &Quantised) -> f64 {
    if plane.bound.is_some() {
        return closed_loop_sse(plane, node, &q.leaf);
    }
    if let Some(residual) = fit.residual {
        let estimate = q.added_error.map(|added| residual + added).or_else(|| {
            let n = fit.model.model().control_count();
            let mut control = [0.0f64; MAX_CONTROL];
            for (c, &v) in control.iter_mut().zip(&q.control_values(node.log2)[..n]) {
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
    closed_loop_sse(plane, node, &q.leaf)
}

/// Squared error of a quantised leaf, reconstructed by decoder-core, over its in-image pixels
/// (a 16-bit surface's: its samples against the fine targets, in grey levels squared), plus
/// [`BOUND_PENALTY`] times each pixel's squared excess over the plane's bound, if any.
fn closed_loop_sse(plane: &Plane, node: &Node, leaf: &LeafSyntax) -> f64 {
    let Ok(patch) = reconstruct(leaf, node.log2) else {
        return f64::INFINITY;
    };
    if plane.fine.is_some() {
        return fine_sse(plane, node, &patch);
    }
    /// Adds up the errors of the tiles it is given.
    struct Sse<'a> {
        plane: &'a Plane,
        sum: ErrorSum,
    }
    impl PixelSink for Sse<'_> {
        type Error = Infallible;

        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
            let Rect { x, y, w, h } = tile.area;
            let mut k = 0;
            for py in y..y + h {
                for px in x..x + w {
                    let d = i64::from(self.plane.get(px, py)) - i64::from(tile.pixels[k]);
                    self.sum.add(d * i64::from(SAMPLE_ONE));
                    k += 1;
                }
            }
            Ok(())
        }
    }
    let mut sink = Sse {
        plane,
        sum: ErrorSum::new(plane.bound),
    };
    let image = Rect::of_size(plane.width, plane.height);
    let Ok(()) = patch.render(node, image, &mut sink);
    sink.sum.distortion()
}

/// Errors in samples: the sum of their squares, and of their squared excess over a bound.
struct ErrorSum {
    squares: u64,
    excess: u64,
    bound: Option<u32>,
}

impl ErrorSum {
    fn new(bound: Option<u32>) -> ErrorSum {
        ErrorSum {
            squares: 0,
            excess: 0,
            bound,
        }
    }

    #[inline]
    fn add(&mut self, d: i64) {
        self.squares += (d * d) as u64;
        if let Some(b) = self.bound {
            let over = d.unsigned_abs().saturating_sub(u64::from(b));
            self.excess += over * over;
        }
    }

    /// The squared error plus [`BOUND_PENALTY`] times the squared excess, in grey levels
    /// squared.
    fn distortion(&self) -> f64 {
        let one = f64::from(SAMPLE_ONE);
        (self.squares as f64 + BOUND_PENALTY * self.excess as f64) / (one * one)
    }
}

/// [`closed_loop_sse`] of a 16-bit surface: the patch's samples, clamped to grey 0..255 as a
/// decoder clamps them, against the plane's fine targets.
fn fine_sse(plane: &Plane, node: &Node, patch: &Patch) -> f64 {
    /// Adds up the errors of the tiles' samples.
    struct Sse<'a> {
        plane: &'a Plane,
        sum: ErrorSum,
    }
    impl TileOut for Sse<'_> {
        fn put(&mut self, _tile: TileMut<'_>) -> Result<(), Stop> {
            // Every tile comes with its samples (`depth`).
            Err(Stop)
        }

        fn put_samples(&mut self, tile: TileMut<'_>, samples: &mut [i16]) -> Result<(), Stop> {
            let Rect { x, y, w, h } = tile.area;
            let top = 255 * SAMPLE_ONE;
            let points = (y..y + h).flat_map(|py| (x..x + w).map(move |px| (px, py)));
            for ((px, py), &s) in points.zip(samples.iter()) {
                let d = i64::from(self.plane.sample(px, py) - i32::from(s).clamp(0, top));
                self.sum.add(d);
            }
            Ok(())
        }

        fn depth(&self) -> Depth {
            Depth::Samples
        }
    }
    let mut sink = Sse {
        plane,
        sum: ErrorSum::new(plane.bound),
    };
    let image = Rect::of_size(plane.width, plane.height);
    if patch.render_to(node, image, &mut sink).is_err() {
        return f64::INFINITY;
    }
    sink.sum.distortion()
}

#[cfg(test)]
mod tests {
    use super::super::config::{
        Target, Tune, FINE_STEP_MARGIN, LOW_RATE_BPP, LOW_RATE_MIN_LEAF_LOG2,
    };
    use super::super::ids::leaf_syntax;
    use super::super::quantise::ROUNDING_VARIANTS;
    use super::*;
    use decoder_core::internal::syntax::code_leaf;

    /// The trial encode's contexts block by block follow its coder: after its last leaf they
    /// price a leaf as the contexts the stream ended with do; and on an image smooth on the left
    /// and noisy on the right, the smooth tile's own contexts price its leaves for fewer bits
    /// than the contexts the stream ended with (the noisy tile's).
    #[test]
    fn local_contexts_follow_the_trial_encode() {
        let (w, h) = (256u32, 128u32);
        let mut seed = 11u32;
        let data = (0..w * h)
            .map(|i| {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let (x, y) = (f64::from(i % w), f64::from(i / w));
                let smooth = 128.0 + 50.0 * (x / 21.0).sin() * (y / 17.0).cos();
                let noise = if x < 128.0 {
                    0.0
                } else {
                    f64::from(seed >> 26) - 32.0
                };
                (smooth + noise).clamp(0.0, 255.0) as u8
            })
            .collect();
        let analysis = Analysis::run(
            Plane::new(w, h, data),
            None,
            &EncoderConfig::default(),
            &|_| {},
        )
        .expect("an analysis");
        let (tree, header) = (&analysis.tree, &analysis.header);
        let image = analysis.image();
        let bits = 2.0 * f64::from(w * h);
        let plan = analysis.rates.rough_plan_for_bits(tree, header, bits);
        let trial = writer::write_trial((tree, &image), header, &plan, &analysis.chroma_cache)
            .expect("a trial stream");
        let leaves = writer::leaf_bits((tree, &image), header, &plan, None, &analysis.chroma_cache)
            .expect("the leaves");
        // Every candidate of `node`, priced from `contexts`.
        let price = |node: &Node, contexts: &Contexts| -> f64 {
            let na = tree.node(node).expect("an analysed node");
            (na.leaves(&image).iter())
                .map(|leaf| f64::from(leaf_bits(node, leaf, &image, &mut contexts.clone())))
                .sum()
        };
        let local = |node: &Node| &trial.local.around(node).contexts;
        let last = leaves.last().expect("a leaf").node;
        let end = &trial.written.final_contexts;
        assert_eq!(price(&last, local(&last)), price(&last, end));
        let smooth: Vec<Node> = leaves
            .iter()
            .map(|l| l.node)
            .filter(|n| n.x < 128)
            .collect();
        let (own, ended): (f64, f64) = smooth
            .iter()
            .map(|n| (price(n, local(n)), price(n, end)))
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        assert!(
            own < 0.95 * ended,
            "{own} bits from their own contexts, {ended} from the end's"
        );
    }

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
        let multipliers = [ROUNDING_VARIANTS[0], ROUNDING_LAMBDA, ROUNDING_VARIANTS[3]];
        // Per multiplier: nonzero indices and added error, summed.
        let mut totals = [(0usize, 0.0f64); 3];
        for log2 in 2..=4u8 {
            for (x, y) in [(0, 0), (16, 16), (32, 0)] {
                let node = Node { x, y, log2 };
                for m in ModelId::for_block(log2) {
                    let fit = fit_default(&plane, &node, m);
                    let targets = ControlTargets::of(&fit, log2);
                    let n = m.model().control_count();
                    for cq in [6, 9, 12].map(ControlQuantiserId::new) {
                        for coding in [ControlCoding::Dpcm, ControlCoding::Transform] {
                            for (t, &lambda) in totals.iter_mut().zip(&multipliers) {
                                let rounding = Rounding::from_start(lambda);
                                let q = quantise(&fit, &targets, cq, coding, rounding);
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

        let analysis =
            Analysis::run(plane, None, &EncoderConfig::default(), &|_| {}).expect("an analysis");
        let kept_variants = analysis
            .tree
            .levels()
            .iter()
            .flat_map(|l| l.nodes.iter().flatten())
            .filter(|na| {
                na.candidates.iter().enumerate().any(|(i, a)| {
                    na.candidates[..i]
                        .iter()
                        .any(|b| (a.fit, a.cq, a.coding) == (b.fit, b.cq, b.coding))
                })
            })
            .count();
        assert!(kept_variants > 0, "no node kept a rounding variant");
    }

    /// Choosing each leaf in the walk, under the contexts and beside the pixels it is coded
    /// with, among the candidates that cost no more than the plan's, never makes a plan's
    /// stream larger than its leaves written as planned, and makes it smaller over a range of
    /// rates: rate control can rely on a plan's size ([`writer::write`]).
    #[test]
    fn leaves_chosen_in_the_walk_cost_no_more_than_planned() {
        let analysis = Analysis::run(
            textured_plane(128, 128),
            None,
            &EncoderConfig::default(),
            &|_| {},
        )
        .expect("an analysis");
        let (tree, header) = (&analysis.tree, &analysis.header);
        let image = analysis.image();
        let pixels = f64::from(128 * 128);
        let cache = &analysis.chroma_cache;
        let (mut chosen_sum, mut planned_sum) = (0.0, 0.0);
        for bpp in [0.05, 0.1, 0.25, 0.5, 1.0, 2.0] {
            let plan = analysis
                .rates
                .rough_plan_for_bits(tree, header, bpp * pixels);
            let chosen = writer::write((tree, &image), header, &plan, None, cache);
            let planned = writer::write_as_planned((tree, &image), header, &plan, cache);
            let (chosen, planned) = (chosen.unwrap().payload_bits, planned.unwrap().payload_bits);
            assert!(
                chosen <= planned,
                "{bpp} bpp: {chosen} bits chosen, {planned} planned"
            );
            chosen_sum += chosen;
            planned_sum += planned;
        }
        assert!(
            chosen_sum < planned_sum,
            "{chosen_sum} bits chosen, {planned_sum} planned"
        );
    }

    /// Rounding under the prices of contexts that have coded only zero residuals keeps fewer
    /// nonzero indices than under the contexts every stream starts from or contexts that have
    /// coded residuals of one: a block's prices move the rounding ([`add_rounding_variants`]).
    #[test]
    fn block_prices_move_the_rounding() {
        let plane = textured_plane(64, 64);
        let header = header_for(&plane, &EncoderConfig::default()).expect("a header");
        let image = prediction_of(&plane, &header);
        let cq = ControlQuantiserId::new(8);
        let at = Node {
            x: 16,
            y: 16,
            log2: 4,
        };
        let model = ModelId::for_block(4).last().expect("a model");
        let n = model.model().control_count();
        // Contexts that have coded `count` leaves whose residuals are all `residual` (signs
        // alternating).
        let adapted = |residual: i16| {
            let mut contexts = Contexts::default();
            let mut leaf = leaf_syntax(model, cq, ControlCoding::Dpcm);
            for (i, index) in leaf.control[1..n].iter_mut().enumerate() {
                *index = if i % 2 == 0 { residual } else { -residual };
            }
            for _ in 0..300 {
                let mut coded = leaf;
                let mut counter = crate::entropy::BitCounter::default();
                code_leaf(&mut counter, &mut contexts, &at, &image, &mut coded).expect("codable");
            }
            ResidualPrices::under(&contexts)
        };
        let (quiet, busy) = (adapted(0), adapted(1));
        let prices = [&quiet, ResidualPrices::at_start(), &busy];
        let mut nonzero = [0usize; 3];
        for log2 in 2..=4u8 {
            for (x, y) in [(0, 0), (16, 16), (32, 0), (48, 32)] {
                let node = Node { x, y, log2 };
                for m in ModelId::for_block(log2) {
                    let fit = fit_default(&plane, &node, m);
                    let targets = ControlTargets::of(&fit, log2);
                    for (count, prices) in nonzero.iter_mut().zip(prices) {
                        let rounding = Rounding {
                            lambda: ROUNDING_LAMBDA,
                            prices,
                        };
                        let q = quantise(&fit, &targets, cq, ControlCoding::Dpcm, rounding);
                        let k = m.model().control_count();
                        *count += q.leaf.control[1..k].iter().filter(|&&i| i != 0).count();
                    }
                }
            }
        }
        assert!(
            nonzero[0] < nonzero[1] && nonzero[0] < nonzero[2],
            "nonzero indices under quiet / starting / busy prices: {nonzero:?}"
        );
    }

    /// The fine pass takes each chain on from its coarse end one step at a time, and stops a
    /// chain at the first step that lowers the error by less than the floor per bit added:
    /// with an infinite floor at the first step that adds bits, with none at no step, which
    /// then gives the candidates of the exhaustive search.
    #[test]
    fn fine_steps_go_on_while_they_pay() {
        let plane = textured_plane(64, 64);
        let header = header_for(&plane, &EncoderConfig::default()).expect("a header");
        let start = Contexts::default();
        let node = Node {
            x: 16,
            y: 16,
            log2: 4,
        };
        let fits = fit_node(&plane, &node);
        let fresh = || NodeAnalysis {
            fits: fits.iter().map(|f| f.model).collect(),
            ..NodeAnalysis::new(node, true)
        };
        let key = |c: &Candidate| (c.fit, c.coding == ControlCoding::Transform);
        let steps = |na: &NodeAnalysis| {
            let mut s: Vec<_> = na.candidates.iter().map(|c| (key(c), c.cq)).collect();
            s.sort_unstable();
            s
        };
        let mut all = fresh();
        coarse_candidates(&plane, &header, (&mut all, 1.0), &fits, &start, 0);
        for floor in [f64::INFINITY, f64::NEG_INFINITY] {
            let mut na = fresh();
            let ends =
                coarse_candidates(&plane, &header, (&mut na, 1.0), &fits, &start, FIRST_COARSE);
            assert!(na.candidates.iter().all(|c| c.cq.rank() >= FIRST_COARSE));
            let coarse = na.candidates.len();
            let search = FineSearch {
                start: &start,
                first: FIRST_COARSE,
                floor,
            };
            fine_candidates(&plane, &header, (&mut na, 1.0), &ends, &search);
            let bits: Vec<f32> = na.candidates.iter().map(|c| c.bits).collect();
            if floor == f64::NEG_INFINITY {
                assert_eq!(steps(&na), steps(&all));
                continue;
            }
            // Each chain's finer steps, in the order made: every one but the last adds no
            // bits to the one before; the last adds some, or is the finest step. A chain
            // without any is one whose coarse end the hull had come to cover.
            let mut hull = GrowingHull::default();
            for c in &na.candidates {
                hull.add((f64::from(c.bits), c.sse));
            }
            for end in &ends {
                let c = end.chain;
                let of_chain = (c.fit, c.coding == ControlCoding::Transform);
                let chain: Vec<usize> = (coarse..na.candidates.len())
                    .filter(|&k| key(&na.candidates[k]) == of_chain)
                    .collect();
                if chain.is_empty() {
                    let fit = fit_default(&plane, &node, na.fits[usize::from(c.fit)]);
                    let floor = error_floor(&node, &fit);
                    assert!(hull.covers((f64::from(end.bits), floor)), "{of_chain:?}");
                    continue;
                }
                let mut last = end.bits;
                for (j, &k) in chain.iter().enumerate() {
                    let adds = bits[k] > last;
                    let finest = na.candidates[k].cq.rank() == 0;
                    assert_eq!(adds || finest, j + 1 == chain.len(), "{chain:?}");
                    last = bits[k];
                }
            }
        }
    }

    /// Only an analysis whose every target is a rate below the raw size searches fine steps
    /// near its trial: a quality target's rate is not known before the analysis, and at the
    /// unlimited budget every step pays.
    #[test]
    fn fine_steps_only_for_rate_targets() {
        let of = |targets: &[Target]| EncoderConfig::for_targets(targets, 1000).fine_steps;
        assert_eq!(
            of(&[Target::Bpp(0.1), Target::Bytes(300)]),
            Some(FINE_STEP_MARGIN)
        );
        assert_eq!(of(&[Target::Bytes(300), Target::Psnr(30.0)]), None);
        assert_eq!(of(&[Target::Psnr(30.0)]), None);
        assert_eq!(of(&[Target::Bytes(usize::MAX)]), None);
        assert_eq!(of(&[Target::Bpp(8.0)]), None);
        assert_eq!(of(&[]), None);
        assert_eq!(EncoderConfig::default().fine_steps, None);
    }

    /// Leaves start at 8 px only when every target is a rate of at most 0.1 bpp: a target
    /// above it, or one whose rate is not known (a quality), keeps 4 px leaves.
    #[test]
    fn low_rates_only_analyse_from_8_px_leaves() {
        let of = |targets: &[Target]| EncoderConfig::for_targets(targets, 1000).min_leaf_log2;
        let (low, usual) = (
            LOW_RATE_MIN_LEAF_LOG2,
            EncoderConfig::default().min_leaf_log2,
        );
        assert_eq!((low, usual), (3, 2));
        assert_eq!(of(&[Target::Bpp(0.05), Target::Bytes(12)]), low);
        assert_eq!(of(&[Target::Bpp(LOW_RATE_BPP)]), low);
        assert_eq!(of(&[Target::Bytes(13)]), usual);
        assert_eq!(of(&[Target::Bpp(0.05), Target::Bpp(0.25)]), usual);
        assert_eq!(of(&[Target::Bpp(0.05), Target::Psnr(30.0)]), usual);
        assert_eq!(of(&[]), usual);
    }

    /// Searching the fine steps only where they pay near the trial's multiplier keeps the
    /// quality of the exhaustive search at the trial rate.
    #[test]
    fn fine_steps_near_the_trial_keep_its_quality() {
        let plane = textured_plane(96, 64);
        let target = Target::Bpp(0.5);
        let config = EncoderConfig::for_targets(&[target], 96 * 64);
        assert_eq!(config.fine_steps, Some(FINE_STEP_MARGIN));
        let exhaustive = EncoderConfig {
            fine_steps: None,
            ..config.clone()
        };
        let psnr_of = |config: &EncoderConfig| {
            let analysis = Analysis::run(plane.clone(), None, config, &|_| {}).expect("analysis");
            analysis.encode(target).expect("an encode").psnr
        };
        let (fine, all) = (psnr_of(&config), psnr_of(&exhaustive));
        assert!(fine > all - 0.05, "{fine} dB against {all} dB");
    }

    /// Mean SSIM (Wang et al. 2004: an 11 x 11 Gaussian window of deviation 1.5, `K1` 0.01,
    /// `K2` 0.03, over the windows inside the image) of `b` against `a`, both `w` wide.
    fn mean_ssim(a: &[u8], b: &[u8], w: usize) -> f64 {
        let h = a.len() / w;
        let g: Vec<f64> = (0..11)
            .map(|i| (-((i as f64 - 5.0).powi(2)) / 4.5).exp())
            .collect();
        let norm: f64 = g.iter().sum::<f64>().powi(2);
        let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
        let mut total = 0.0;
        for y in 0..h - 10 {
            for x in 0..w - 10 {
                let mut m = [0.0f64; 5];
                for j in 0..11 {
                    for i in 0..11 {
                        let k = g[i] * g[j] / norm;
                        let (p, q) = (
                            f64::from(a[(y + j) * w + x + i]),
                            f64::from(b[(y + j) * w + x + i]),
                        );
                        m[0] += k * p;
                        m[1] += k * q;
                        m[2] += k * p * p;
                        m[3] += k * q * q;
                        m[4] += k * p * q;
                    }
                }
                let (va, vb, cov) = (m[2] - m[0] * m[0], m[3] - m[1] * m[1], m[4] - m[0] * m[1]);
                total += (2.0 * m[0] * m[1] + c1) * (2.0 * cov + c2)
                    / ((m[0] * m[0] + m[1] * m[1] + c1) * (va + vb + c2));
            }
        }
        total / ((w - 10) * (h - 10)) as f64
    }

    /// Contrast masking buys SSIM: at the same budget, six crops of the bundled sample (256 x
    /// 128 each: its blurred background and the parrots) have a higher mean SSIM with
    /// [`Tune::Ssim`] than with [`Tune::Psnr`] (summed over the crops). (Their squared error
    /// need not be higher: the rate control's choices are not exactly optimal for either.)
    #[test]
    fn ssim_tuning_buys_ssim() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../samples/kodim23.png");
        let sample = crate::io::load_luma(std::path::Path::new(path)).expect("the bundled sample");
        let (w, h) = (256u32, 128u32);
        let target = Target::Bpp(0.25);
        // Per tuning: the summed SSIM.
        let mut sums = [0.0f64; 2];
        for (x0, y0) in [
            (0, 64),
            (256, 64),
            (512, 64),
            (0, 320),
            (256, 320),
            (512, 320),
        ] {
            let data = (0..w * h)
                .map(|i| sample.data[((y0 + i / w) * sample.width + x0 + i % w) as usize])
                .collect();
            let plane = Plane::new(w, h, data);
            for (tune, ssim) in [Tune::Psnr, Tune::Ssim].into_iter().zip(&mut sums) {
                let config = EncoderConfig {
                    tune,
                    ..EncoderConfig::for_targets(&[target], (w * h) as usize)
                };
                let analysis =
                    Analysis::run(plane.clone(), None, &config, &|_| {}).expect("analysis");
                let encoded = analysis.encode(target).expect("an encode");
                *ssim += mean_ssim(&plane.data, &encoded.reconstruction, w as usize);
            }
        }
        let [psnr, ssim] = sums;
        assert!(ssim > psnr, "SSIM {ssim} (ssim) against {psnr} (psnr)");
    }

    /// A node that a bilinear patch reproduces ends the analysis below it: the flat half of an
    /// image costs only its largest nodes, the textured half is analysed down to the smallest
    /// leaf, and the flat half still decodes exactly.
    #[test]
    fn settled_nodes_end_the_analysis_below_them() {
        let (w, h) = (128u32, 128u32);
        let textured = textured_plane(w, h);
        let data = (0..w * h)
            .map(|i| {
                if i % w < 64 {
                    textured.data[i as usize]
                } else {
                    90
                }
            })
            .collect();
        let plane = Plane::new(w, h, data);
        let analysis = Analysis::run(plane.clone(), None, &EncoderConfig::default(), &|_| {})
            .expect("an analysis");
        let mut seen = 0;
        for level in analysis.tree.levels() {
            for (i, na) in level.nodes.iter().enumerate() {
                let x = (i as u32 % level.cols) << level.log2;
                if level.log2 >= 6 || x < 64 {
                    assert!(na.is_some(), "node at x {x}, level {} skipped", level.log2);
                } else {
                    assert!(na.is_none(), "node at x {x}, level {} analysed", level.log2);
                    seen += 1;
                }
            }
        }
        // Below each of the flat half's two 64-px nodes: 4 + 16 + 64 + 256 nodes of 32 to 4 px.
        assert_eq!(seen, 2 * 340);
        let encoded = analysis
            .encode(super::super::config::Target::Bpp(1.0))
            .expect("an encode");
        for y in 0..h {
            for x in 64..w {
                assert_eq!(
                    encoded.reconstruction[(y * w + x) as usize],
                    90,
                    "({x}, {y})"
                );
            }
        }
    }

    /// A candidate's syntax, held by its node or made again ([`NodeAnalysis::leaf`]), is the
    /// syntax the passes made and rated, for the coarse pass's candidates, the rounding
    /// variants (rounded against other pixels drawn beside the node than the image's) and
    /// those a node keeps; a node that holds indices keeps only its candidates'.
    #[test]
    fn candidates_are_made_again_unchanged() {
        let plane = textured_plane(64, 64);
        let header = header_for(&plane, &EncoderConfig::default()).expect("a header");
        // What a trial encode might have drawn: the image, blurred into steps of 8 px.
        let drawn = Plane::new(
            64,
            64,
            (0..64 * 64)
                .map(|i| plane.get(i % 64 / 8 * 8, i / 64 / 8 * 8))
                .collect(),
        );
        let own = prediction_of(&plane, &header);
        let image = own.with_drawn(Some(&drawn));
        let node = Node {
            x: 16,
            y: 16,
            log2: 4,
        };
        let fits = fit_node(&plane, &node);
        let start = Contexts::default();
        let mut nodes = [true, false].map(|holds| NodeAnalysis {
            fits: fits.iter().map(|f| f.model).collect(),
            ..NodeAnalysis::new(node, holds)
        });
        let mut kept = Vec::new();
        for na in &mut nodes {
            coarse_candidates(&plane, &header, (na, 1.0), &fits, &start, 0);
            assert!(na.candidates.len() > 8);
            let rated = na.candidates.clone();
            rate_node(na, &own, &start);
            assert_eq!(na.candidates, rated);
            let vary: Vec<u16> = (0..na.candidates.len() as u16).step_by(2).collect();
            let known = na.candidates.len();
            let block = ResidualPrices::under(&start);
            // Rounded against the image's own pixels beside the node, some variants differ.
            let mut alone = na.clone();
            let varied_alone =
                add_rounding_variants(&plane, &own, (&mut alone, 1.0), &vary, &block);
            let varied = add_rounding_variants(&plane, &image, (na, 1.0), &vary, &block);
            assert!(!varied.is_empty());
            assert_ne!(varied, varied_alone);
            assert_eq!(na.candidates.len(), known + varied.len());
            for (k, leaf) in (known..).zip(&varied) {
                let c = na.candidates[k];
                assert_ne!(c.rounding, RoundingId::default());
                assert_eq!(&na.leaf(k, &image), leaf);
            }
            let keep: Vec<u16> = (0..na.candidates.len() as u16).step_by(3).collect();
            let all = na.leaves(&image);
            let before: Vec<LeafSyntax> = keep.iter().map(|&k| all[usize::from(k)]).collect();
            na.retain(&keep);
            assert_eq!(na.leaves(&image), before);
            kept.push(before);
        }
        // Held or made again, the same syntax.
        assert_eq!(kept[0], kept[1]);
        let held = nodes[0].indices.as_ref().map_or(0, |held| held.len());
        let count: usize = (nodes[0].candidates.iter())
            .map(|c| nodes[0].fits[usize::from(c.fit)].model().control_count())
            .sum();
        assert_eq!(held, count);
        assert!(nodes[1].indices.is_none());
    }

    /// A node keeps a fit by its model only: made again, it is the same fit, inside the image
    /// and at its edge (where it is fitted iteratively).
    #[test]
    fn kept_fits_are_made_again_unchanged() {
        let plane = textured_plane(40, 40);
        for (x, y) in [(8, 8), (32, 32)] {
            let node = Node { x, y, log2: 4 };
            for fit in fit_node(&plane, &node) {
                assert_eq!(
                    fit_default(&plane, &node, fit.model),
                    fit,
                    "node ({x}, {y})"
                );
            }
        }
    }

    /// The quadratic form of an exact fit ([`Fit::error_of`]) predicts the closed-loop error of
    /// every quantised leaf to within the integer synthesis's rounding: with `e` the real
    /// error and `r` the rounding (|r| <= 1/2) at a pixel, `|(e + r)^2 - e^2| <= |e| + 1/4`,
    /// and the sum of `|e|` is at most `sqrt(pixels * estimate)`.
    #[test]
    fn estimated_error_follows_the_closed_loop() {
        let (w, h) = (64u32, 64u32);
        let plane = textured_plane(w, h);
        let mut checked = 0;
        for log2 in 2..=5u8 {
            let node = Node { x: 16, y: 0, log2 };
            for m in ModelId::for_block(log2) {
                let fit = fit_default(&plane, &node, m);
                let targets = ControlTargets::of(&fit, log2);
                let codings = [ControlCoding::Dpcm, ControlCoding::Transform];
                for (cq, coding) in [2, 7, 13]
                    .map(ControlQuantiserId::new)
                    .into_iter()
                    .flat_map(|c| codings.map(|d| (c, d)))
                {
                    let rounding = Rounding::from_start(ROUNDING_LAMBDA);
                    let q = quantise(&fit, &targets, cq, coding, rounding);
                    let n = m.model().control_count();
                    let control: Vec<f64> = q.control_values(log2)[..n]
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
                    let closed = closed_loop_sse(&plane, &node, &q.leaf);
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

    /// With a bound on each pixel's error, a leaf's distortion is its squared error plus
    /// [`BOUND_PENALTY`] times each pixel's squared excess over the bound, measured in the
    /// closed loop even where an error this large is otherwise estimated.
    #[test]
    fn a_bound_adds_the_squared_excess() {
        let plain = textured_plane(64, 64);
        let node = Node {
            x: 16,
            y: 16,
            log2: 4,
        };
        let model = ModelId::for_block(node.log2).next().unwrap();
        let fit = fit_default(&plain, &node, model);
        let targets = ControlTargets::of(&fit, node.log2);
        let cq = ControlQuantiserId::new(13);
        let rounding = Rounding::from_start(ROUNDING_LAMBDA);
        let q = quantise(&fit, &targets, cq, ControlCoding::Dpcm, rounding);
        let patch = reconstruct(&q.leaf, node.log2).unwrap();
        let mut errors = Vec::new();
        let mut collect = |tile: Tile<'_>| {
            let Rect { x, y, w, h } = tile.area;
            let points = (y..y + h).flat_map(|py| (x..x + w).map(move |px| (px, py)));
            for ((px, py), &p) in points.zip(tile.pixels) {
                errors.push(i64::from(plain.get(px, py)) - i64::from(p));
            }
        };
        struct Each<'a, F: FnMut(Tile<'_>)>(&'a mut F);
        impl<F: FnMut(Tile<'_>)> PixelSink for Each<'_, F> {
            type Error = Infallible;
            fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
                (self.0)(tile);
                Ok(())
            }
        }
        let Ok(()) = patch.render(&node, Rect::of_size(64, 64), &mut Each(&mut collect));
        let squares: i64 = errors.iter().map(|d| d * d).sum();
        assert_eq!(closed_loop_sse(&plain, &node, &q.leaf), squares as f64);
        let largest = errors.iter().map(|d| d.abs()).max().unwrap();
        assert!(largest >= 2, "a coarse step errs by {largest}");
        for bound in [0, 1, largest - 1, largest] {
            let mut bounded = plain.clone();
            bounded.bound = Some((bound * i64::from(SAMPLE_ONE)) as u32);
            let excess: i64 = errors.iter().map(|d| (d.abs() - bound).max(0).pow(2)).sum();
            let expected = squares as f64 + BOUND_PENALTY * excess as f64;
            assert_eq!(
                quantised_sse(&bounded, &node, &fit, &q),
                expected,
                "{bound}"
            );
        }
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
        let analysis = Analysis::run(plane.clone(), None, &config, &|_| {}).expect("an analysis");
        let encoded = analysis
            .encode(super::super::config::Target::Bpp(4.0))
            .expect("an encode");
        assert_decodes_to(&encoded.bytes, &encoded.reconstruction);
        assert!(encoded.psnr > 40.0, "PSNR {}", encoded.psnr);
    }

    /// An analysis in bands (here, one per row of its largest nodes) keeps what one band over
    /// the whole image keeps (the candidates of nodes past the first band made again from the
    /// image instead of held), and reports the node steps [`analysis_steps`] lists.
    #[test]
    fn bands_change_nothing_but_the_memory() {
        let config = EncoderConfig {
            max_leaf_log2: 5,
            fine_steps: Some(FINE_STEP_MARGIN),
            ..EncoderConfig::default()
        };
        let plane = textured_plane(256, 200);
        let scale = ContrastScale::of(&plane, config.tune);
        let reported = AtomicU64::new(0);
        let progress = |n: u64| {
            reported.fetch_max(n, Ordering::Relaxed);
        };
        let banded = Analysis::run_in_bands(plane.clone(), None, &config, (1, scale), &progress)
            .expect("an analysis");
        let listed = steps_in_bands(256, 200, &config, 1);
        assert_eq!(listed.iter().filter(|s| s.log2 == 5).count(), 7 * 2 + 1);
        let steps: u64 = listed.iter().map(|s| s.nodes).sum();
        assert_eq!(reported.load(Ordering::Relaxed), steps);
        let whole = Analysis::run_in_bands(plane, None, &config, (u32::MAX, scale), &|_| {})
            .expect("an analysis");
        // The first band's nodes hold their indices, the others make them again.
        let image = banded.image();
        let unplaced = |na: &NodeAnalysis| (na.candidates.clone(), na.leaves(&image));
        let mut made_again = 0;
        for (a, b) in banded.tree.levels().iter().zip(whole.tree.levels()) {
            for (a, b) in a.nodes.iter().zip(&b.nodes) {
                let (a, b) = (a.as_ref(), b.as_ref());
                assert_eq!(a.map(unplaced), b.map(unplaced));
                made_again += usize::from(a.is_some_and(|a| a.indices.is_none()));
                assert!(b.is_none_or(|b| b.indices.is_some()));
            }
        }
        assert!(made_again > 0);
        for bpp in [0.25, 1.0] {
            let target = Target::Bpp(bpp);
            let (a, b) = (banded.encode(target), whole.encode(target));
            assert_eq!(a.expect("a stream").bytes, b.expect("a stream").bytes);
        }
    }

    /// The analysis, with the default settings, of the 64 x 64 colour image whose pixel
    /// `(x, y)` has the YCbCr values `ycbcr(x, y)`.
    fn colour_analysis(ycbcr: impl Fn(u32, u32) -> [u8; 3]) -> Analysis {
        let (w, h) = (64u32, 64u32);
        let rgb: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let [l, cb, cr] = ycbcr(i % w, i / w);
                decoder_core::internal::colour::ycbcr_to_rgb(l, cb, cr)
            })
            .collect();
        let (y, colour) = ColourPlanes::from_rgb(w, h, rgb);
        Analysis::run(y, Some(colour), &EncoderConfig::default(), &|_| {}).expect("an analysis")
    }

    /// The pixels the trial encode drew, which the final pruning predicts from, are a picture
    /// of the image's luma at about the trial's rate, for a grayscale and a colour image
    /// alike (a colour image's trial is coded in grayscale: its luma, not its RGB's).
    #[test]
    fn the_trial_draws_the_images_luma() {
        let surface = |x: u32, y: u32| {
            128.0 + 60.0 * (f64::from(x) / 9.0).sin() * (f64::from(y) / 13.0).cos()
        };
        let colour = colour_analysis(|x, y| [surface(x, y) as u8, 80, 180]);
        let gray = Analysis::run(
            Plane::new(
                64,
                64,
                (0..64 * 64)
                    .map(|i| surface(i % 64, i / 64) as u8)
                    .collect(),
            ),
            None,
            &EncoderConfig::default(),
            &|_| {},
        )
        .expect("an analysis");
        for analysis in [&gray, &colour] {
            let drawn = analysis.drawn.as_ref().expect("the trial's pixels");
            assert_eq!((drawn.width, drawn.height), (64, 64));
            let sse: f64 = (drawn.data.iter().zip(&analysis.plane.data))
                .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
                .sum();
            let psnr = super::super::plane::psnr(sse, drawn.data.len());
            assert!(psnr > 30.0, "the trial's luma at {psnr} dB");
            assert_ne!(drawn.data, analysis.plane.data, "a trial at its own rate");
        }
    }

    /// The quadtree's cut weighs each leaf's chroma with its luma: on an image whose colour
    /// changes where its luma's texture does not, the cut that sees chroma codes the same
    /// bytes with less RGB error than the cut chosen for luma alone (the same analysis with
    /// its chroma costs cleared).
    #[test]
    fn the_cut_sees_chroma() {
        // Smooth luma, and two colours meeting on a line that no large leaf's edge follows.
        let seeing = colour_analysis(|x, y| {
            let luma = 128.0 + 50.0 * (f64::from(x) / 9.0).sin() * (f64::from(y) / 13.0).cos();
            let (cb, cr) = if x + y / 3 < 27 { (70, 190) } else { (190, 80) };
            [luma as u8, cb, cr]
        });
        let mut blind = seeing.clone();
        for level in blind.tree.levels_mut() {
            for na in level.nodes.iter_mut().flatten() {
                na.chroma = super::super::candidates::ChromaCost::default();
            }
        }
        const BYTES: usize = 300;
        let target = super::super::config::Target::Bytes(BYTES);
        let seen = seeing.encode(target).expect("an encode");
        let unseen = blind.encode(target).expect("an encode");
        assert!(seen.bytes.len() <= BYTES && unseen.bytes.len() <= BYTES);
        assert!(
            seen.psnr > unseen.psnr + 0.2,
            "PSNR-RGB {} seeing chroma, {} blind to it",
            seen.psnr,
            unseen.psnr
        );
    }

    /// Fine luma under a smooth colour: the cut splits for luma, and split nodes code the
    /// chroma of their whole subtree once instead of a chroma leaf pair per leaf; the stream
    /// decodes to the encoder's reconstruction.
    #[test]
    fn split_nodes_code_a_smooth_colour_once() {
        use super::super::rate::Decision;
        let analysis = colour_analysis(|x, y| {
            let luma = 128.0 + 60.0 * (f64::from(x) / 1.7).sin() * (f64::from(y) / 2.3).cos();
            [luma as u8, (90 + x) as u8, (170 - y / 2) as u8]
        });
        let plan = analysis
            .rates
            .plan_for_bits(&analysis, &analysis.header, 8.0 * 1500.0, None);
        let count = |decisions: &[Vec<Decision>], d: Decision| {
            decisions.iter().flatten().filter(|&&x| x == d).count()
        };
        assert!(
            count(&plan.decisions, Decision::SplitWithChroma) > 0,
            "{plan:?}"
        );
        assert_eq!(count(&plan.subtree_decisions, Decision::SplitWithChroma), 0);
        let encoded = analysis
            .encode(super::super::config::Target::Bytes(1500))
            .expect("an encode");
        assert_decodes_to(&encoded.bytes, &encoded.reconstruction);
    }

    /// decoder-core decodes `stream` to the encoder's `reconstruction`.
    fn assert_decodes_to(stream: &[u8], reconstruction: &[u8]) {
        let mut pixels = vec![0u8; reconstruction.len()];
        decoder_core::Decoder::new(stream)
            .and_then(|d| d.decode_into(&mut pixels))
            .expect("a valid stream");
        assert_eq!(pixels, reconstruction);
    }
}
