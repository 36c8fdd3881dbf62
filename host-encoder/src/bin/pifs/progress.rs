//! The analysis's progress on a terminal: a spinner (time and nodes so far) until enough work is
//! done for an estimate of the time left to mean something, then a bar whose estimate comes from
//! the work done so far (fitting nodes, making their candidates, refining them, in the order
//! the analysis reports them), then a spinner again for the closing steps (the trial encode and
//! the pruning), which report no progress and so get no estimate.

use host_encoder::packets::RegionsDone;
use host_encoder::{AnalysisStage, AnalysisSteps};
use indicatif::{ProgressBar, ProgressStyle};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Whether analyses draw no progress of their own (a batch draws one bar for all).
static HIDDEN: AtomicBool = AtomicBool::new(false);

/// From now on, analyses draw no progress display ([`Progress::on_terminal`] gives `None`).
pub fn hide_analysis_progress() {
    HIDDEN.store(true, Ordering::Relaxed);
}

/// Share of the fitting work after which the bar replaces the spinner.
const BAR_AFTER_SHARE: f64 = 0.10;

/// Steps of the bar (it shows the share of the work done).
const BAR_STEPS: u64 = 1000;

/// Time after which the bar replaces the spinner, whatever the share done.
const BAR_AFTER: Duration = Duration::from_secs(2);

/// Work of fitting a node, beside its pixels (one unit each): a fixed cost, as measured
/// (per-node times grow as this plus the pixels).
const NODE_OVERHEAD: f64 = 96.0;

/// Work of making a node's candidates (quantising its fits with every quantiser and rating
/// them) per pixel of the node, up to 64 pixels (the largest model's grid: quantisation grows
/// with the control values, not the pixels), in the units of [`NODE_OVERHEAD`]. Measured
/// (`examples/stage_times.rs` with each level timed, kodim05 and kodim23): about 70 µs a node
/// of 4 px and 270 to 420 µs a larger one, where fitting takes about 0.02 µs a unit.
const CANDIDATE_WORK: f64 = 235.0;

/// Share of [`CANDIDATE_WORK`] in the fine pass when there is one: the profile of kodim13 at
/// 0.25 bpp (docs/results.md) spent 0.30 s there against 1.30 s in the coarse pass.
const FINE_SHARE: f64 = 0.2;

/// Share of an analysis's time after the passes that report progress: the trial encode and the
/// pruning, 24 to 34% on seven Kodak images (`examples/stage_times.rs`: 1.1 to 2.2 s of 4.7
/// to 6.5 s). The bar stops short of it, and its estimate includes it.
const CLOSING_SHARE: f64 = 0.28;

/// The work of an analysis, stretch by stretch in the order it is done
/// ([`host_encoder::analysis_steps`]). The analysis reports node steps, but a node's fitting
/// grows with its pixels and its candidates with its control values. Nodes inside a settled
/// node are reported too, at once, so the share done jumps ahead on easy content.
#[derive(Debug, Clone, PartialEq)]
pub struct Work {
    /// Per stretch: nodes, and work per node.
    levels: Vec<(u64, f64)>,
}

impl Work {
    /// The work of the analysis whose node steps are `steps`.
    pub fn new(steps: &[AnalysisSteps]) -> Work {
        let fine = steps.iter().any(|s| s.stage == AnalysisStage::Fine);
        let per_node = |s: &AnalysisSteps| {
            let pixels = 4f64.powi(i32::from(s.log2));
            let candidates = CANDIDATE_WORK * pixels.min(64.0);
            match s.stage {
                AnalysisStage::Fitting => NODE_OVERHEAD + pixels,
                AnalysisStage::Coarse if fine => candidates * (1.0 - FINE_SHARE),
                AnalysisStage::Fine => candidates * FINE_SHARE,
                _ => candidates,
            }
        };
        Work {
            levels: steps.iter().map(|s| (s.nodes, per_node(s))).collect(),
        }
    }

    /// Work of `steps` steps of equal work.
    pub fn even(steps: u64) -> Work {
        Work {
            levels: vec![(steps, 1.0)],
        }
    }

    /// Nodes in all.
    pub fn nodes(&self) -> u64 {
        self.levels.iter().map(|l| l.0).sum()
    }

    /// The share of the work done once `done` nodes are (levels are done one after the other).
    pub fn share(&self, done: u64) -> f64 {
        let total: f64 = self.levels.iter().map(|&(n, w)| n as f64 * w).sum();
        let mut left = done;
        let mut work = 0.0;
        for &(n, w) in &self.levels {
            let here = left.min(n);
            work += here as f64 * w;
            left -= here;
        }
        if total > 0.0 {
            (work / total).min(1.0)
        } else {
            1.0
        }
    }
}

/// The time left when `share` of the work took `elapsed`, at the same pace; `None` while
/// nothing is done.
pub fn time_left(share: f64, elapsed: Duration) -> Option<Duration> {
    (share > 0.0).then(|| elapsed.mul_f64((1.0 - share).max(0.0) / share))
}

/// Whether an estimate made now means something: enough work done, or enough time passed.
pub fn estimate_is_meaningful(share: f64, elapsed: Duration) -> bool {
    share >= BAR_AFTER_SHARE || elapsed >= BAR_AFTER
}

/// "1 min 05 s", "12 s".
pub fn duration_text(d: Duration) -> String {
    let s = d.as_secs_f64().round() as u64;
    if s >= 60 {
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        format!("{s} s")
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Starting,
    Running,
    Closing,
}

/// The progress display of one analysis (drawn on stderr, and only on a terminal).
#[derive(Debug)]
pub struct Progress {
    bar: ProgressBar,
    work: Work,
    start: Instant,
    phase: Mutex<Phase>,
}

impl Progress {
    /// A display for `work`, or `None` when stderr is not a terminal or displays are hidden.
    pub fn on_terminal(work: Work) -> Option<Progress> {
        use std::io::IsTerminal;
        if !std::io::stderr().is_terminal() || HIDDEN.load(Ordering::Relaxed) {
            return None;
        }
        let bar = ProgressBar::new(BAR_STEPS);
        bar.set_style(style("{spinner} analysing: {msg}, {elapsed}"));
        bar.set_message(format!("0/{} node steps", work.nodes()));
        bar.enable_steady_tick(Duration::from_millis(120));
        Some(Progress {
            bar,
            work,
            start: Instant::now(),
            phase: Mutex::new(Phase::Starting),
        })
    }

    /// Called by the analysis with the number of node steps (a fit, a node's candidates) done
    /// so far (from any thread, not necessarily in order).
    pub fn nodes_done(&self, done: u64) {
        let mut phase = match self.phase.lock() {
            Ok(p) => p,
            Err(poisoned) => poisoned.into_inner(),
        };
        let total = self.work.nodes();
        if *phase == Phase::Closing {
            return;
        }
        let elapsed = self.start.elapsed();
        if done >= total {
            *phase = Phase::Closing;
            // The closing steps report nothing: their time is estimated once, from the passes'.
            let left = time_left(1.0 - CLOSING_SHARE, elapsed).unwrap_or_default();
            self.bar.set_style(style(
                "{spinner} analysing: candidates made; pruning them with a trial encode (about {msg}), {elapsed} so far",
            ));
            self.bar.set_message(duration_text(left));
            return;
        }
        let share = (1.0 - CLOSING_SHARE) * self.work.share(done);
        if *phase == Phase::Starting && estimate_is_meaningful(share, elapsed) {
            *phase = Phase::Running;
            self.bar.set_style(style(
                "analysing {bar:40} {percent}%, {elapsed} so far{msg}",
            ));
        }
        match *phase {
            Phase::Starting => self.bar.set_message(format!("{done}/{total} node steps")),
            _ => {
                // The bar shows work, not nodes: a large node is more work than a small one.
                self.bar.set_position((share * BAR_STEPS as f64) as u64);
                if let Some(left) = time_left(share, elapsed) {
                    self.bar
                        .set_message(format!(", about {} left", duration_text(left)));
                }
            }
        }
    }

    /// Removes the display.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// The progress display of the region packets' encoding (drawn on stderr, and only on a
/// terminal): the regions made, and the time left from the share of the pixels done.
#[derive(Debug)]
pub struct RegionsProgress {
    bar: ProgressBar,
    start: Instant,
    /// The largest share reported so far (reports may come out of order); `None` before the
    /// first.
    furthest: Mutex<Option<f64>>,
}

impl RegionsProgress {
    /// A display, or `None` when stderr is not a terminal or displays are hidden.
    pub fn on_terminal() -> Option<RegionsProgress> {
        use std::io::IsTerminal;
        if !std::io::stderr().is_terminal() || HIDDEN.load(Ordering::Relaxed) {
            return None;
        }
        let bar = ProgressBar::new(1);
        bar.set_style(style(
            "{spinner} packets: cutting the image into regions, {elapsed}",
        ));
        bar.enable_steady_tick(Duration::from_millis(120));
        Some(RegionsProgress {
            bar,
            start: Instant::now(),
            furthest: Mutex::new(None),
        })
    }

    /// Called with each region made (from any thread, not necessarily in order).
    pub fn made(&self, done: RegionsDone) {
        let mut furthest = match self.furthest.lock() {
            Ok(f) => f,
            Err(poisoned) => poisoned.into_inner(),
        };
        match *furthest {
            Some(share) if done.share < share => return,
            Some(_) => {}
            None => self.bar.set_style(style(
                "packets {bar:40} {pos}/{len} regions, {elapsed} so far{msg}",
            )),
        }
        *furthest = Some(done.share);
        self.bar.set_length(done.regions as u64);
        self.bar.set_position(done.done as u64);
        let elapsed = self.start.elapsed();
        if estimate_is_meaningful(done.share, elapsed) {
            if let Some(left) = time_left(done.share, elapsed) {
                self.bar
                    .set_message(format!(", about {} left", duration_text(left)));
            }
        }
    }

    /// Removes the display.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

fn style(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_spinner())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The work of an analysis of a `width x height` image for rate targets with leaves of
    /// `2^min_log2` to `2^max_log2` pixels.
    fn work(width: u32, height: u32, min_log2: u8, max_log2: u8) -> Work {
        let config = host_encoder::EncoderConfig {
            min_leaf_log2: min_log2,
            max_leaf_log2: max_log2,
            fine_steps: Some(host_encoder::FINE_STEP_MARGIN),
            ..Default::default()
        };
        Work::new(&host_encoder::analysis_steps(width, height, &config))
    }

    #[test]
    fn work_weighs_nodes_by_their_pixels() {
        // 64x64, nodes of 32 and 4 px: 4 large nodes of 96 + 1024 units first, then 256 small
        // ones of 96 + 16.
        let work = work(64, 64, 2, 5);
        let work = Work {
            levels: vec![work.levels[0], work.levels[3]],
        };
        assert_eq!(work.nodes(), 260);
        let total = 256.0 * 112.0 + 4.0 * 1120.0;
        assert_eq!(work.share(0), 0.0);
        assert!((work.share(2) - 2.0 * 1120.0 / total).abs() < 1e-12);
        assert!((work.share(132) - (4.0 * 1120.0 + 128.0 * 112.0) / total).abs() < 1e-12);
        assert_eq!(work.share(260), 1.0);
        assert_eq!(work.share(999), 1.0);
        // A large node weighs more than a small one, less than its share of pixels.
        assert!(work.share(1) - work.share(0) > 5.0 * (work.share(5) - work.share(4)));
    }

    #[test]
    fn work_is_fitting_then_candidates_then_refining() {
        let work = work(64, 64, 2, 5);
        let nodes = 256 + 64 + 16 + 4;
        assert_eq!(work.nodes(), 3 * nodes);
        // The fitting pass: largest nodes first; then the candidates, smallest first; then
        // their refinement, smallest first, a fifth of the candidates' work.
        assert_eq!(work.levels[0].0, 4);
        assert_eq!(work.levels[4].0, 256);
        assert_eq!(work.levels[8].0, 256);
        let fitting: f64 = work.levels[..4].iter().map(|&(n, w)| n as f64 * w).sum();
        let total: f64 = work.levels.iter().map(|&(n, w)| n as f64 * w).sum();
        assert!((work.share(nodes) - fitting / total).abs() < 1e-12);
        assert!((work.levels[8].1 / work.levels[4].1 - 0.25).abs() < 1e-12);
    }

    #[test]
    fn work_of_a_large_image_goes_band_by_band() {
        // 6000x4000: bands of whole rows of 128 px nodes, each fitted then quantised.
        let work = work(6000, 4000, 2, 7);
        let fitting_of_128 = NODE_OVERHEAD + 16384.0;
        let bands = work.levels.iter().filter(|l| l.1 == fitting_of_128).count();
        assert!(bands > 10, "{bands} bands");
        let whole =
            |l: u8| u64::from(6000u32.div_ceil(1 << l)) * u64::from(4000u32.div_ceil(1 << l));
        let all: u64 = (2..=7).map(whole).sum();
        assert_eq!(work.nodes(), 3 * all);
    }

    #[test]
    fn the_estimate_follows_the_pace_so_far() {
        assert_eq!(time_left(0.0, Duration::from_secs(1)), None);
        let left = time_left(0.25, Duration::from_secs(3)).unwrap();
        assert!((left.as_secs_f64() - 9.0).abs() < 1e-9);
        assert_eq!(
            time_left(1.0, Duration::from_secs(3)).unwrap(),
            Duration::ZERO
        );
        // Not shown while a wild guess: little work done, little time passed.
        assert!(!estimate_is_meaningful(0.01, Duration::from_millis(300)));
        assert!(estimate_is_meaningful(0.10, Duration::from_millis(300)));
        assert!(estimate_is_meaningful(0.01, Duration::from_secs(2)));
    }

    #[test]
    fn durations_read_naturally() {
        assert_eq!(duration_text(Duration::from_millis(11_600)), "12 s");
        assert_eq!(duration_text(Duration::from_secs(65)), "1 min 05 s");
    }
}
