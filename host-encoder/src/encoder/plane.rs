//! The image the encoder works on, its error measure, and the prediction every stage assumes
//! before a stream exists (earlier leaves drew the image's own pixels).
//!
//! Bottom layer of the encoder: uses nothing else of it.

use decoder_core::internal::model::{SAMPLE_BITS, SAMPLE_ONE};
use decoder_core::internal::prediction::{beside_known, SamplePrediction};

/// An 8-bit grayscale image, and for a 16-bit surface its samples finer than grey.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Plane {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major samples.
    pub data: Vec<u8>,
    /// For a 16-bit surface: row-major samples in 1/16 of a grey level (`0..=4080`, the
    /// resolution of the decoder's patches), which the analysis fits instead of `data` (their
    /// rounding to grey).
    pub fine: Option<Vec<u16>>,
    /// For a plane cut from a larger image ([`Plane::crop`]): the samples of the image's row
    /// just above it, which prediction at its top edge sees as the whole image's would.
    above: Option<Vec<i32>>,
    /// The analysis's bound on each pixel's error, in whole samples
    /// ([`super::EncoderConfig::error_bound`]), which a leaf's distortion sees.
    pub(super) bound: Option<u32>,
}

impl Plane {
    /// Wraps row-major samples (`data.len() == width * height`).
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Self {
        assert_eq!(
            data.len(),
            width as usize * height as usize,
            "plane size mismatch"
        );
        Plane {
            width,
            height,
            data,
            fine: None,
            above: None,
            bound: None,
        }
    }

    /// Wraps row-major samples in 1/16 of a grey level (`0..=4080`; larger ones are taken as
    /// 4080): a 16-bit surface mapped onto grey, finer than grey.
    pub fn with_samples(width: u32, height: u32, samples: Vec<u16>) -> Self {
        let top = (255 * SAMPLE_ONE) as u16;
        let samples: Vec<u16> = samples.into_iter().map(|s| s.min(top)).collect();
        let data = samples
            .iter()
            .map(|&s| ((s + (SAMPLE_ONE / 2) as u16) >> SAMPLE_BITS) as u8)
            .collect();
        Plane {
            fine: Some(samples),
            ..Plane::new(width, height, data)
        }
    }

    /// The plane with `pixels` (row-major, 8-bit, of its size) in place of its own, and the
    /// row above it kept: what a reconstruction of it predicts from.
    pub fn redrawn(&self, pixels: Vec<u8>) -> Plane {
        Plane {
            above: self.above.clone(),
            ..Plane::new(self.width, self.height, pixels)
        }
    }

    /// The pixel at `(x, y)`, rounded to grey.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> u8 {
        self.data[y as usize * self.width as usize + x as usize]
    }

    /// The target at `(x, y)` in grey levels: the fine sample's, or the pixel's.
    #[inline]
    pub fn value(&self, x: u32, y: u32) -> f64 {
        f64::from(self.sample(x, y)) / f64::from(SAMPLE_ONE)
    }

    /// The targets of the `out.len()` pixels from `(x, y)` rightwards, in grey levels (as
    /// [`Plane::value`]).
    pub fn row_values(&self, x: u32, y: u32, out: &mut [f64]) {
        let start = y as usize * self.width as usize + x as usize;
        let at = start..start + out.len();
        match &self.fine {
            Some(fine) => {
                let one = f64::from(SAMPLE_ONE);
                for (o, &s) in out.iter_mut().zip(&fine[at]) {
                    *o = f64::from(s) / one;
                }
            }
            None => {
                for (o, &p) in out.iter_mut().zip(&self.data[at]) {
                    *o = f64::from(p);
                }
            }
        }
    }

    /// The rectangle `width` x `height` at `(x, y)` (inside this plane) as a plane of its own,
    /// keeping the samples of the row above it: the analysis of a part of an image
    /// predicts its top edge from that row as the whole image's analysis would.
    pub(crate) fn crop(&self, (x, y): (u32, u32), (width, height): (u32, u32)) -> Plane {
        let rows = |row_len: usize| {
            let stride = self.width as usize;
            (y as usize..(y + height) as usize).map(move |r| {
                let start = r * stride + x as usize;
                start..start + row_len
            })
        };
        let data = rows(width as usize)
            .flat_map(|at| self.data[at].iter().copied())
            .collect();
        let fine = self.fine.as_ref().map(|fine| {
            rows(width as usize)
                .flat_map(|at| fine[at].iter().copied())
                .collect()
        });
        let above = (y > 0).then(|| (x..x + width).map(|c| self.sample(c, y - 1)).collect());
        Plane {
            width,
            height,
            data,
            fine,
            above,
            bound: self.bound,
        }
    }

    /// This plane as an image of its own: without the row above it that [`Plane::crop`] kept.
    pub(crate) fn alone(self) -> Plane {
        Plane {
            above: None,
            ..self
        }
    }

    /// The target at `(x, y)` in 1/16 of a grey level.
    #[inline]
    pub fn sample(&self, x: u32, y: u32) -> i32 {
        let at = y as usize * self.width as usize + x as usize;
        match &self.fine {
            Some(fine) => i32::from(fine[at]),
            None => i32::from(self.data[at]) * SAMPLE_ONE,
        }
    }
}

/// PSNR (peak 255) of a squared error over `pixels` pixels.
pub fn psnr(sse: f64, pixels: usize) -> f64 {
    if sse <= 0.0 {
        return f64::INFINITY;
    }
    10.0 * (255.0f64 * 255.0 * pixels as f64 / sse).log10()
}

/// Prediction from earlier leaves, estimated before the stream exists: earlier leaves are taken
/// to have drawn the image's own pixels, or those a trial encode drew, under the decoder's
/// availability rule ([`decoder_core::internal::prediction::Frontier`]).
#[derive(Debug, Clone, Copy)]
pub struct ImagePrediction<'a> {
    /// The image (what leaves are fitted to).
    pub plane: &'a Plane,
    /// The pixels a trial encode drew, of the plane's size, once one has been made: nearer
    /// than the image's own to those a stream's leaves will be predicted from.
    drawn: Option<&'a Plane>,
    /// The pixels this prediction reads: the plane's own, or `drawn`.
    beside: &'a Plane,
    /// Width of the stripes the image is coded in, pixels.
    pub stripe: u32,
}

impl<'a> ImagePrediction<'a> {
    /// Prediction from the image's own pixels, coded in stripes of `stripe` pixels.
    pub fn new(plane: &'a Plane, stripe: u32) -> Self {
        ImagePrediction {
            plane,
            drawn: None,
            beside: plane,
            stripe,
        }
    }

    /// The same prediction, knowing the pixels a trial encode drew (of the plane's size),
    /// which [`ImagePrediction::drawn`] predicts from.
    pub fn with_drawn(self, drawn: Option<&'a Plane>) -> Self {
        debug_assert!(
            drawn.is_none_or(|d| (d.width, d.height) == (self.plane.width, self.plane.height))
        );
        ImagePrediction { drawn, ..self }
    }

    /// Prediction from the pixels the trial encode drew where they are known, else from the
    /// image's own.
    pub fn drawn(self) -> Self {
        ImagePrediction {
            beside: self.drawn.unwrap_or(self.plane),
            ..self
        }
    }

    /// Prediction from the image's own pixels.
    pub fn own(self) -> Self {
        ImagePrediction {
            beside: self.plane,
            ..self
        }
    }

    fn sample(&self, x: u32, y: u32) -> i32 {
        self.beside.sample(x, y)
    }
}

impl SamplePrediction for ImagePrediction<'_> {
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
        let (width, height) = (self.beside.width, self.beside.height);
        if above && y == 0 {
            // The row above a plane cut from a larger image.
            let row = self.beside.above.as_ref()?;
            return (y < height).then(|| row.get(x as usize).copied()).flatten();
        }
        beside_known(above, x, y, width, height, self.stripe).then(|| {
            let (x, y) = if above { (x, y - 1) } else { (x - 1, y) };
            self.sample(x, y)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane cut from a larger one predicts its top edge from the row above it, as the whole
    /// plane does there, and nothing beyond its own width; alone, from nothing.
    #[test]
    fn a_cut_plane_predicts_from_the_row_above_it() {
        let data: Vec<u8> = (0..64 * 40).map(|i| (i * 7 % 251) as u8).collect();
        let whole = Plane::new(64, 40, data);
        let cut = whole.crop((32, 16), (32, 24));
        assert_eq!(cut.get(3, 2), whole.get(35, 18));
        let (full, part) = (
            ImagePrediction::new(&whole, 32),
            ImagePrediction::new(&cut, 32),
        );
        for x in 0..32 {
            assert_eq!(part.beside(true, x, 0), full.beside(true, x + 32, 16));
            assert_eq!(part.beside(true, x, 5), full.beside(true, x + 32, 21));
            assert_eq!(part.beside(false, x, 5), full.beside(false, x + 32, 21));
        }
        assert_eq!(part.beside(true, 32, 0), None);
        let alone = cut.alone();
        let alone = ImagePrediction::new(&alone, 32);
        assert_eq!(alone.beside(true, 3, 0), None);
    }

    /// A plane of samples keeps them as its targets (`value`, `row_values`, `sample`) and
    /// their rounding to grey as its pixels; a plane of pixels targets the pixels.
    #[test]
    fn fine_samples_are_the_targets_and_round_to_the_pixels() {
        let plane = Plane::with_samples(3, 1, vec![0, 24, 5000]);
        assert_eq!(plane.data, vec![0, 2, 255]);
        assert_eq!(plane.sample(1, 0), 24);
        assert_eq!(plane.value(1, 0), 1.5);
        assert_eq!(plane.value(2, 0), 255.0);
        let mut row = [0.0; 3];
        plane.row_values(0, 0, &mut row);
        assert_eq!(row, [0.0, 1.5, 255.0]);
        let pixels = Plane::new(2, 1, vec![7, 9]);
        assert_eq!(
            (pixels.value(1, 0), pixels.sample(0, 0)),
            (9.0, 7 * SAMPLE_ONE)
        );
    }
}
