//! The image the encoder works on, its error measure, and the prediction every stage assumes
//! before a stream exists (earlier leaves drew the image's own pixels).
//!
//! Bottom layer of the encoder: uses nothing else of it.

use decoder_core::internal::model::SAMPLE_ONE;
use decoder_core::internal::prediction::{beside_known, SamplePrediction};

/// An 8-bit grayscale image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Plane {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major samples.
    pub data: Vec<u8>,
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
        }
    }

    /// The sample at `(x, y)`.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> u8 {
        self.data[y as usize * self.width as usize + x as usize]
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
/// to have drawn the image's own pixels, under the decoder's availability rule
/// ([`decoder_core::internal::prediction::Frontier`]).
#[derive(Debug, Clone, Copy)]
pub struct ImagePrediction<'a> {
    /// The image.
    pub plane: &'a Plane,
    /// Width of the stripes the image is coded in, pixels.
    pub stripe: u32,
}

impl ImagePrediction<'_> {
    fn sample(&self, x: u32, y: u32) -> i32 {
        i32::from(self.plane.get(x, y)) * SAMPLE_ONE
    }
}

impl SamplePrediction for ImagePrediction<'_> {
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
        let (width, height) = (self.plane.width, self.plane.height);
        beside_known(above, x, y, width, height, self.stripe).then(|| {
            let (x, y) = if above { (x, y - 1) } else { (x - 1, y) };
            self.sample(x, y)
        })
    }
}
